"""The revdem engine itself on one linear sphere contact confirms the two-sphere limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from revdem_cli.state import initial_state
from revdem_cli.timestep import criteria, engine_pair, shapes
from revdem_cli.timestep.assessment import assess
from revdem_cli.timestep.criteria import Contact

KN = 1e6  # N/m
SPHERE = shapes.sphere(0.01, 2500.0)
ENGINE_RTOL = 1e-4  # the bisection resolves the limit to about 1e-6


@pytest.mark.parametrize(
    ("ks", "alpha_key"),
    [(0.0, "normal_only_alpha"), (KN, "eq49_alpha")],
    ids=["frictionless", "shear"],
)
def test_engine_limit_of_two_equal_spheres(paper, ks, alpha_key):
    limit = engine_pair.engine_limit(SPHERE, SPHERE, Contact(kn=KN, ks=ks))
    expected = paper["sphere"][alpha_key] * math.sqrt(SPHERE.mass / KN)  # √2 or 2/√7 (Eq 49)
    assert limit == pytest.approx(expected, rel=ENGINE_RTOL)


def test_shear_springs_make_the_tangential_mode_critical():
    """Just above 2/√7 √(m/k) the engine blows up with shear springs and not without."""
    dt = 1.01 * 2.0 / math.sqrt(7.0) * math.sqrt(SPHERE.mass / KN)
    assert not engine_pair.engine_is_stable(
        engine_pair.resting_pair(SPHERE, SPHERE, Contact(KN, KN)), dt
    )
    assert engine_pair.engine_is_stable(
        engine_pair.resting_pair(SPHERE, SPHERE, Contact(KN, 0.0)), dt
    )


def test_the_engine_pair_has_the_inverse_masses_of_the_given_spheres():
    other = shapes.sphere(0.02, 1000.0)
    scenario = engine_pair.resting_pair(SPHERE, other, Contact(kn=KN, ks=KN))
    particles = initial_state(scenario).particles
    heavy, light = particles.mass
    assert 1 / heavy + 1 / light == pytest.approx(1 / SPHERE.mass + 1 / other.mass, rel=1e-12)
    assert heavy == pytest.approx(engine_pair.HEAVY * light, rel=1e-2)
    # at rest: the contact carries the light sphere's weight, the plane both
    weight = light * -scenario.gravity[2]
    np.testing.assert_allclose(particles.f, 0.0, atol=1e-6 * weight)


def test_dt_verify_sets_the_engine_beside_the_formula():
    assessment = assess(SPHERE, SPHERE, KN, KN, check=True)
    checks = {e.key: e.dt for e in assessment.checks}
    assert checks["engine_integrated"] == pytest.approx(assessment.recommended, rel=ENGINE_RTOL)
    ellipsoid = shapes.ellipsoid(3, 2, 1, 1000.0)
    keys = {e.key for e in assess(ellipsoid, SPHERE, KN, KN, check=True).checks}
    assert "engine_integrated" not in keys and "velocity_verlet_integrated" in keys


@pytest.mark.parametrize("beta", [0.0, 0.1, 0.5])
def test_the_velocity_predictor_limit_reduces_to_verlet_and_to_2_over_omega(beta):
    inverse_mass = 2.0 / SPHERE.mass
    c = beta * 2.0 * math.sqrt(KN / inverse_mass)
    verlet = criteria.dt_velocity_verlet(KN, c, inverse_mass)
    assert criteria.dt_velocity_predictor(KN, c, inverse_mass, 0) == pytest.approx(verlet)
    predicted = [criteria.dt_velocity_predictor(KN, c, inverse_mass, k) for k in (1, 2, 4)]
    if beta == 0.0:  # nothing reads the prediction: 2/omega for every order
        assert predicted == pytest.approx([2.0 / math.sqrt(KN * inverse_mass)] * 3)
    else:  # damping read from an extrapolation shrinks the stable range with the order
        assert verlet > predicted[0] > predicted[1] > predicted[2]


def test_engine_limit_with_the_velocity_predictor():
    """The engine with trvp_order = 2 on a contact damped at half of critical is stable up to
    the root of the scheme's characteristic polynomial (`criteria.predictor_is_stable`), a
    limit 0.54 of velocity Verlet's, to the engine's resolution (its 4000-step trials)."""
    inverse_mass = 2.0 / SPHERE.mass
    c = 0.5 * 2.0 * math.sqrt(KN / inverse_mass)
    limit = engine_pair.engine_limit(SPHERE, SPHERE, Contact(kn=KN, ks=0.0, cn=c), order=2)
    expected = criteria.dt_velocity_predictor(KN, c, inverse_mass, 2)
    assert limit == pytest.approx(expected, rel=3e-3)
    assert expected < 0.6 * criteria.dt_velocity_verlet(KN, c, inverse_mass)


def test_dt_recommends_the_predictors_limit_when_damping_reads_it():
    damped = assess(SPHERE, SPHERE, KN, KN, damping_number=0.5)
    predicted = assess(SPHERE, SPHERE, KN, KN, damping_number=0.5, trvp_order=2)
    limits = {e.key: e.dt for e in predicted.criteria}
    assert predicted.recommended == limits["velocity_predictor"]
    assert predicted.recommended < 0.7 * damped.recommended  # 0.685 at N = 0.5, shear mode
    assert "velocity_predictor" not in {e.key for e in damped.criteria}


def test_dt_refuses_an_order_out_of_range():
    from typer.testing import CliRunner

    from revdem_cli.cli import app

    result = CliRunner().invoke(
        app, ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "2500", "--kn", "1e6",
              "--trvp-order", "5"],
    )  # fmt: skip
    assert result.exit_code == 2 and "--trvp-order must be 0" in result.output
