"""The integrator judges the formulas: velocity Verlet integrated, and the eigenvalues of Eq 40."""

from __future__ import annotations

import math

import numpy as np
import pytest

from revdem_cli.timestep import criteria, shapes, verify
from revdem_cli.timestep.criteria import Contact

INTEGRATION_RTOL = 1e-3  # slow growth near the limit is resolved to a few 1e-4

K, INVERSE_MASS = 1e10, 20.0 / (8000.0 * math.pi)  # the ellipsoid pair of Peng 2020 Figure 4


def damping(number: float) -> float:
    return criteria.damping_from_number(number, K, INVERSE_MASS)


@pytest.mark.parametrize("number", [0.0, 1.0, 4.0])
def test_integrated_velocity_verlet_limit_matches_its_formula(number):
    integrated = verify.limit_1d(verify.velocity_verlet_is_stable, K, damping(number), INVERSE_MASS)
    formula = criteria.dt_velocity_verlet(K, damping(number), INVERSE_MASS)
    assert integrated == pytest.approx(formula, rel=INTEGRATION_RTOL)


def test_undamped_integration_confirms_eq47():
    integrated = verify.limit_1d(verify.velocity_verlet_is_stable, K, 0.0, INVERSE_MASS)
    assert integrated == pytest.approx(2.0 / math.sqrt(K * INVERSE_MASS), rel=1e-6)


def test_damped_eq46_time_step_blows_up_under_velocity_verlet():
    for number in (0.5, 2.0, 5.0):
        c = damping(number)
        eq46 = criteria.dt_amplification(K, c, INVERSE_MASS)
        limit = criteria.dt_velocity_verlet(K, c, INVERSE_MASS)
        assert not verify.velocity_verlet_is_stable(K, c, INVERSE_MASS, eq46)
        assert verify.velocity_verlet_is_stable(K, c, INVERSE_MASS, 0.99 * limit)
        assert not verify.velocity_verlet_is_stable(K, c, INVERSE_MASS, 1.01 * limit)


def test_two_spheres_normal_only_limit_is_root_two(paper):
    sphere = shapes.sphere(0.002, 2500.0)
    normal_only = 1.0 / sphere.mass + 1.0 / sphere.mass  # Peng 2020 Eq 26 without lever arms
    integrated = verify.limit_1d(verify.velocity_verlet_is_stable, K, 0.0, normal_only)
    alpha = paper["sphere"]["normal_only_alpha"]
    assert integrated == pytest.approx(alpha * math.sqrt(sphere.mass / K), rel=1e-6)


def test_sphere_pair_verifier_gives_eq49(paper):
    sphere = shapes.sphere(0.002, 2500.0)
    kn = 1e5
    limit = verify.velocity_verlet_limit(sphere, sphere, Contact(kn=kn, ks=kn))
    alpha = paper["sphere"]["eq49_alpha"]
    assert limit == pytest.approx(alpha * math.sqrt(sphere.mass / kn), rel=1e-6)


def test_verifier_takes_the_stiffer_direction():
    body = shapes.ellipsoid(3, 2, 1, 1000.0)
    soft_shear = verify.velocity_verlet_limit(body, body, Contact(kn=K, ks=0.25 * K))
    stiff_shear = verify.velocity_verlet_limit(body, body, Contact(kn=0.25 * K, ks=K))
    assert soft_shear == pytest.approx(stiff_shear, rel=1e-6)
    inverse_mass = criteria.a_max(body, body)
    assert soft_shear == pytest.approx(2.0 / math.sqrt(K * inverse_mass), rel=1e-6)


@pytest.mark.parametrize("number", [0.0, 1.0, 3.0, 5.0])
def test_eq46_is_where_the_real_eigenvalue_of_eq40_reaches_minus_one(number):
    c = damping(number)
    eq46 = criteria.dt_amplification(K, c, INVERSE_MASS)
    found = verify.limit_1d(verify.eq40_real_eigenvalues_above_minus_one, K, c, INVERSE_MASS)
    assert found == pytest.approx(eq46, rel=1e-5)
    eigenvalues = np.linalg.eigvals(verify.eq40_matrix(K, c, INVERSE_MASS, eq46))
    assert np.min(np.abs(eigenvalues + 1.0)) < 1e-6


def test_eq40_scheme_is_never_stable_undamped():
    scale = 1.0 / math.sqrt(K * INVERSE_MASS)
    for fraction in (1e-2, 0.3, 1.0, 1.9):
        eigenvalues = np.linalg.eigvals(verify.eq40_matrix(K, 0.0, INVERSE_MASS, fraction * scale))
        assert np.abs(eigenvalues).max() > 1.0
    assert verify.limit_1d(verify.eq40_is_stable, K, 0.0, INVERSE_MASS) == 0.0


@pytest.mark.parametrize("number", [1.0, 5.0])
def test_damped_eq40_scheme_is_stable_only_far_below_eq46(number):
    c = damping(number)
    stable_up_to = verify.limit_1d(verify.eq40_is_stable, K, c, INVERSE_MASS)
    assert 0.0 < stable_up_to < 0.5 * criteria.dt_amplification(K, c, INVERSE_MASS)
    above = np.linalg.eigvals(verify.eq40_matrix(K, c, INVERSE_MASS, 1.01 * stable_up_to))
    assert np.abs(above).max() > 1.0
    assert np.abs(above.imag).max() > 0.0


def test_largest_stable_dt_brackets_from_either_side():
    for guess in (1e-3, 1.0, 100.0):
        assert verify.largest_stable_dt(lambda dt: dt < 0.7, guess) == pytest.approx(0.7, rel=1e-5)
    assert verify.largest_stable_dt(lambda dt: False, 1.0) == 0.0
