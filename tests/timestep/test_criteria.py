"""Peng 2020 criteria: the paper's worked cases and the special cases its equations reduce to."""

from __future__ import annotations

import math

import numpy as np
import pytest

from revdem_cli.timestep import criteria, shapes


@pytest.fixture
def ellipsoid_pair(paper):
    case = paper["ellipsoid_pair"]
    body = shapes.ellipsoid(*case["semi_axes"], case["density"])
    return case, body


def test_ellipsoid_pair_mass_a_max_and_undamped_time_step(ellipsoid_pair):
    case, body = ellipsoid_pair
    assert body.mass == pytest.approx(case["mass_over_pi"] * math.pi, rel=1e-12)
    inverse_mass = criteria.a_max(body, body)
    assert inverse_mass * body.mass == pytest.approx(case["a_max_times_mass"], rel=1e-12)
    dt = criteria.dt_amplification(case["kn"], 0.0, inverse_mass)
    assert dt == pytest.approx(case["dt_undamped"], rel=case["dt_rtol"])
    assert dt == pytest.approx(2.0 / math.sqrt(case["kn"] * inverse_mass), rel=1e-12)


def test_sphere_pair_gives_eq49(paper):
    body = shapes.sphere(0.01, 2650.0)
    inverse_mass = criteria.a_max(body, body)
    assert inverse_mass * body.mass == pytest.approx(paper["sphere"]["a_max_times_mass"])
    kn = 1e6
    dt = criteria.dt_amplification(kn, 0.0, inverse_mass)
    assert dt == pytest.approx(paper["sphere"]["eq49_alpha"] * math.sqrt(body.mass / kn))


def test_a_max_of_unequal_particles_adds_both_sides():
    small, large = shapes.sphere(1.0, 1000.0), shapes.ellipsoid(3, 2, 1, 2000.0)
    expected = 1.0 / small.mass + 1.0 / small.moments[0] + 1.0 / large.mass + 9.0 / large.moments[0]
    assert criteria.a_max(small, large) == pytest.approx(expected)
    assert criteria.a_max(large, small) == criteria.a_max(small, large)


@pytest.mark.parametrize("beta", [0.0, 0.3, 0.7, 1.5, 2.5])
def test_normalised_sphere_forms_are_eq58_to_60(beta):
    forms = criteria.sphere_normalised(beta)
    eq58 = 4.0 / math.sqrt(28.0 - 49.0 * beta**2) if 28.0 > 49.0 * beta**2 else None
    eq59 = math.pi / math.sqrt(2.0 - beta**2 / 4.0) if beta**2 < 8.0 else None
    eq60 = beta + math.sqrt(beta**2 + 4.0 / 7.0)
    assert forms["belytschko"] == pytest.approx(eq58)
    assert forms["collision"] == pytest.approx(eq59)
    assert forms["amplification"] == pytest.approx(eq60)


def test_figure3_asymptotes_sit_at_critical_damping(paper):
    asymptotes = paper["figure3"]
    below, above = 1.0 - 1e-6, 1.0 + 1e-6
    assert criteria.sphere_normalised(asymptotes["eq58_asymptote"] * below)["belytschko"] > 100
    assert criteria.sphere_normalised(asymptotes["eq58_asymptote"] * above)["belytschko"] is None
    assert criteria.sphere_normalised(asymptotes["eq59_asymptote"] * below)["collision"] > 100
    assert criteria.sphere_normalised(asymptotes["eq59_asymptote"] * above)["collision"] is None


def test_damping_number_two_is_critical_damping():
    kn, inverse_mass = 1e10, 7.9e-4
    assert criteria.damping_from_number(2.0, kn, inverse_mass) == pytest.approx(
        criteria.critical_damping(kn, inverse_mass)
    )


def test_undamped_criteria_agree_and_damping_pulls_them_apart():
    k, inverse_mass = 3e9, 2e-3
    undamped = [
        f(k, 0.0, inverse_mass) for f in (criteria.dt_amplification, criteria.dt_belytschko)
    ]
    assert undamped[0] == pytest.approx(undamped[1])
    assert criteria.dt_velocity_verlet(k, 0.0, inverse_mass) == pytest.approx(undamped[0])
    c = 0.5 * criteria.critical_damping(k, inverse_mass)
    assert criteria.dt_amplification(k, c, inverse_mass) > undamped[0]
    assert criteria.dt_velocity_verlet(k, c, inverse_mass) < undamped[0]


def test_velocity_verlet_limit_solves_its_stability_boundary():
    k, c, inverse_mass = 2e8, 4e3, 1e-3
    dt = criteria.dt_velocity_verlet(k, c, inverse_mass)
    assert k * inverse_mass * dt**2 + 2.0 * c * inverse_mass * dt == pytest.approx(4.0)


@pytest.mark.parametrize("xi", [1e2, 1e4, 1e6])
def test_velocity_verlet_limit_keeps_its_digits_under_heavy_damping(xi):
    """ξ = cA/(2ω) far above 1: the limit still solves kAΔt² + 2cAΔt = 4, and is
    (2/ω)/(√(1 + ξ²) + ξ) (Peng 2020 Eq 30 by velocity Verlet), about 1/(cA)."""
    k, inverse_mass = 1e10, 7.9e-4
    omega = math.sqrt(k * inverse_mass)
    c = 2.0 * xi * omega / inverse_mass
    dt = criteria.dt_velocity_verlet(k, c, inverse_mass)
    assert k * inverse_mass * dt**2 + 2.0 * c * inverse_mass * dt == pytest.approx(4.0, rel=1e-12)
    assert dt == pytest.approx(2.0 / omega / (math.sqrt(1.0 + xi**2) + xi), rel=1e-12, abs=0.0)


def test_equal_principal_moments_have_no_rotation_limit():
    """A sphere-like superquadric (semi-axes 1 1 1) and a cube turned at random have three
    equal principal moments up to round-off: B_max = 0 (Peng 2020 Eq 54), Δt ∞ (Eq 56)."""
    from scipy.spatial.transform import Rotation

    corners = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    rounded = shapes.superquadric(1, 1, 1, 0.5, 0.5, 1000.0)
    for seed in range(5):
        turned = Rotation.random(random_state=seed).apply(corners)
        cube = shapes.polyhedron(turned, 1000.0, "cube")
        assert criteria.b_max(cube) == 0.0
    assert criteria.b_max(rounded) == 0.0
    assert math.isinf(criteria.dt_rotation(1.0, criteria.b_max(rounded), 0.0))


def test_b_max_and_the_rotation_dominant_time_step():
    sphere, ellipsoid = shapes.sphere(1.0, 1000.0), shapes.ellipsoid(3, 2, 1, 1000.0)
    assert criteria.b_max(sphere) == pytest.approx(0.0, abs=1e-12)
    assert math.isinf(criteria.dt_rotation(1.0, 0.0, 0.0))
    # I = m (1, 2, 2.6): B_max = max(1/2.6, 1.6/2, 0.6/1) = 0.8 (Eq 54)
    b = criteria.b_max(ellipsoid)
    assert b == pytest.approx(max(1 / 2.6, 1.6 / 2, 0.6 / 1))
    omega = 3.0
    assert criteria.dt_rotation(omega, b, b) == pytest.approx(1.0 / (omega * b))  # Eq 57
    assert criteria.dt_rotation(omega, b, 0.0) == pytest.approx(2.0 / (omega * b))


def test_time_steps_scale_as_root_of_mass_over_stiffness():
    body = shapes.ellipsoid(3, 2, 1, 1000.0)
    heavy = shapes.ellipsoid(3, 2, 1, 4000.0)
    for number in (0.0, 1.5, 4.0):
        steps = []
        for b, kn in ((body, 1e10), (heavy, 1e10), (body, 4e10)):
            inverse_mass = criteria.a_max(b, b)
            c = criteria.damping_from_number(number, kn, inverse_mass)
            steps.append(criteria.dt_amplification(kn, c, inverse_mass))
        assert np.allclose(steps, [steps[0], 2.0 * steps[0], 0.5 * steps[0]])
