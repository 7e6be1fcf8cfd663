"""The critical time step a scenario is checked against before it runs."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from revdem_cli.config import load_scenario
from revdem_cli.timestep import guard

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
SPHERE_MASS = 4.0 / 3.0 * math.pi * 0.005**3 * 1000.0  # the shipped spheres, kg


def scenario(name: str, *overrides: str):
    return load_scenario(CONFIGS / f"{name}.toml", list(overrides))[0]


@pytest.mark.parametrize("name", ["collision", "collision_shear", "drop_A"])
def test_shipped_configs_are_far_below_critical(name):
    case = scenario(name)
    critical, why = guard.critical_time_step(case)
    assert case.integrator.dt < 1e-3 * critical
    assert "Rayleigh" in why


def test_a_huge_time_step_is_flagged():
    case = scenario("collision", "integrator.dt=1e-3")
    critical, _ = guard.critical_time_step(case)
    assert case.integrator.dt > critical


def test_hertz_collision_is_bounded_by_the_rayleigh_step_and_the_impact():
    critical, why = guard.critical_time_step(scenario("collision"))
    rayleigh = math.pi * 0.005 * math.sqrt(1000.0 / 2e6) / (0.1631 * 0.2 + 0.8766)
    assert critical == pytest.approx(rayleigh, rel=1e-12)  # 386 µs
    (pair,) = guard.contact_kinds(scenario("collision"))
    assert pair.speed == pytest.approx(math.hypot(0.9, 0.1) + 0.1)  # |v_A| + |v_B|
    impact = guard.contact_dt(scenario("collision"), pair)
    assert 0.5 < impact / 325e-6 < 2.0  # Hanley 2020 §3.2.1 quotes 325 µs (Burns et al. 2019)
    # undamped, 2/ω at the largest Hertz overlap is 2√(8/15) δ_max/v, about half the
    # collision time 2.94 δ_max/v (Johnson 1985 §11.4)
    hertz = 4.0 / 3.0 * pair.estar * math.sqrt(pair.rstar)
    overlap = (5.0 * pair.speed**2 / (4.0 * pair.inverse_mass * hertz)) ** 0.4
    assert impact == pytest.approx(2 * math.sqrt(8 / 15) * overlap / pair.speed, rel=1e-12)


def test_mindlin_shear_springs_lower_the_hertz_estimate():
    plain = guard.contact_dt(scenario("collision"), *guard.contact_kinds(scenario("collision")))
    shear_case = scenario("collision_shear")
    shear = guard.contact_dt(shear_case, *guard.contact_kinds(shear_case))
    # k_s/k_n = 8 G*/(2 E*) = 2(1-ν)/(2-ν) for equal materials (Hanley 2020 Eq 6, 10); A_t = 7/2 A_n
    ratio = 8 * (2e6 / (2 * 1.8)) / (2 * 2e6 / 0.8)
    assert shear / plain == pytest.approx(1 / math.sqrt(3.5 * ratio), rel=1e-12)


def test_a_dropped_sphere_meets_the_plane_at_its_free_fall_speed():
    speeds = guard.particle_speeds(scenario("drop_A"))
    assert speeds[0] == pytest.approx(math.sqrt(2 * 9.81 * 20e-6), rel=1e-9)


@pytest.mark.parametrize(
    ("name", "shear", "alpha"),
    [
        ("collision", [], math.sqrt(2.0)),  # two spheres, normal only
        (
            "collision",
            ["contact.tangential=linear", "contact.ks=1e5", "contact.friction=0.5"],
            2.0 / math.sqrt(7.0),
        ),  # Peng 2020 Eq 49
        ("drop_A", [], 2.0),  # a sphere on a wall: its own mass
        (
            "drop_A",
            ["contact.tangential=linear", "contact.ks=1e5", "contact.friction=0.5"],
            2.0 / math.sqrt(3.5),
        ),
    ],
)
def test_linear_contacts_take_the_verified_two_body_limit(name, shear, alpha):
    case = scenario(name, "contact.model=linear", "contact.kn=1e5", *shear)
    critical, why = guard.critical_time_step(case)
    assert critical == pytest.approx(alpha * math.sqrt(SPHERE_MASS / 1e5), rel=1e-12)
    assert why.startswith("linear contact")


def test_damping_lowers_the_linear_limit_as_velocity_verlet_does():
    case = scenario(
        "collision", "contact.model=linear", "contact.kn=1e5", "contact.normal_damping=0.5"
    )
    critical, _ = guard.critical_time_step(case)
    undamped = math.sqrt(2.0) * math.sqrt(SPHERE_MASS / 1e5)
    assert critical == pytest.approx(undamped * (math.sqrt(1 + 0.25) - 0.5), rel=1e-12)


def test_heavy_damping_gives_a_positive_limit():
    """β = 1e8 of critical: (2/ω)/(√(1 + β²) + β), about 1/(β ω), not the 0 s that the
    difference √(1 + β²) − β rounds to (Peng 2020 Eq 30 by velocity Verlet)."""
    case = scenario(
        "collision", "contact.model=linear", "contact.kn=1e5", "contact.normal_damping=1e8"
    )
    critical, _ = guard.critical_time_step(case)
    undamped = math.sqrt(2.0) * math.sqrt(SPHERE_MASS / 1e5)
    assert critical == pytest.approx(undamped / (math.sqrt(1 + 1e16) + 1e8), rel=1e-12, abs=0.0)


def test_a_stage_of_its_own_damping_bounds_the_limit_by_the_largest():
    """[contact] damped 0.1 and a stage damped 0.5 of critical: the guard holds every stage
    to the limit at 0.5, sqrt(2) sqrt(m / k_n) (sqrt(1 + 0.25) - 0.5) (Peng 2020 Eq 30)."""
    sets = ["contact.model=linear", "contact.kn=1e5", "contact.normal_damping=0.1"]
    alone = guard.critical_time_step(scenario("collision", *sets))[0]
    staged = scenario("collision", *sets, "stages.0.contact.normal_damping=0.5")
    critical, _ = guard.critical_time_step(staged)
    undamped = math.sqrt(2.0) * math.sqrt(SPHERE_MASS / 1e5)
    assert critical == pytest.approx(undamped * (math.sqrt(1 + 0.25) - 0.5), rel=1e-12)
    assert critical < alone
