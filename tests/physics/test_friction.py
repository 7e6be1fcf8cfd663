"""A sphere on a plane with friction: analytic answers for sliding, rolling and sticking."""

import json
import math

import h5py
import numpy as np
import pytest

from revdem_cli.config import Material, Scenario
from revdem_cli.engine import run_scenario
from revdem_cli.kernels.events import COUNT, KINDS, LAST
from revdem_cli.state import effective_modulus
from tests.conftest import FLOOR, PLANE, SPHERE

R, DENSITY, G = 0.005, SPHERE["density"], 9.81
DT = 1e-5


def resting_overlap(normal_gravity: float) -> float:
    """Hertz overlap that carries the sphere's weight: m g = 4/3 E* sqrt(R) d^1.5."""
    estar = effective_modulus(Material(**SPHERE), Material(**PLANE))
    weight = 4 / 3 * math.pi * R**3 * DENSITY * normal_gravity
    return (weight / (4 / 3 * estar * math.sqrt(R))) ** (2 / 3)


def on_plane(
    tilt=0.0,
    velocity=(0.0, 0.0, 0.0),
    friction=0.3,
    tangential="linear",
    steps=8000,
    reverse=False,
    **contact,
):
    """A sphere resting on the plane z = 0; gravity tilted by `tilt` towards +x (an incline)."""
    gravity = (G * math.sin(tilt), 0.0, -G * math.cos(tilt))
    shear = {"ks": 2000.0} if tangential == "linear" else {}
    return Scenario.model_validate(
        {
            "name": "plane",
            "materials": {"sphere": SPHERE, "plane": PLANE},
            "contact": {
                "model": "hertz",
                "tangential": tangential,
                **({"friction": friction} if tangential != "none" else {}),
                **shear,
                **contact,
            },
            "particles": [
                {
                    "material": "sphere",
                    "radius": R,
                    "position": (0.0, 0.0, R - resting_overlap(-gravity[2])),
                    "velocity": velocity,
                }
            ],
            "walls": [FLOOR],
            "gravity": gravity,
            "integrator": {"dt": DT},
            "stages": [{"name": "roll", "steps": steps, "output_every": 100, "reverse": reverse}],
        }
    )


def trajectory(outputs):
    with h5py.File(outputs.forward) as f:
        g = f["particles/all"]
        return (g["velocity/time"][:], g["velocity/value"][:, 0], g["angular_velocity/value"][:, 0])


@pytest.mark.parametrize("tangential", ["linear", "mindlin"])
def test_a_sliding_sphere_decelerates_at_mu_g_then_rolls_at_five_sevenths(tmp_path, tangential):
    v0, mu = 0.5, 0.3
    outputs = run_scenario(
        on_plane(velocity=(v0, 0, 0), friction=mu, tangential=tangential),
        "",
        ".toml",
        tmp_path,
        reverse=False,
    )
    time, v, w = trajectory(outputs)
    slip_ends = 2 * v0 / (7 * mu * G)  # v0 - mu g t = 5/7 v0
    early = (time > 0.1 * slip_ends) & (time < 0.9 * slip_ends)
    deceleration = -np.polyfit(time[early], v[early, 0], 1)[0]
    assert deceleration == pytest.approx(mu * G, rel=0.01)
    rolling = time > 1.3 * slip_ends
    assert v[rolling, 0] == pytest.approx(5 / 7 * v0, rel=0.01)
    np.testing.assert_allclose(w[rolling, 1] * R, v[rolling, 0], rtol=0.01)  # v = omega r


@pytest.mark.parametrize(("tan_theta", "rolls"), [(0.5, True), (1.0, False)])
def test_on_an_incline_a_sphere_rolls_without_slipping_when_tan_theta_below_7_2_mu(
    tmp_path, tan_theta, rolls
):
    mu = 0.2  # threshold tan(theta) = 7/2 mu = 0.7
    theta = math.atan(tan_theta)
    outputs = run_scenario(
        on_plane(tilt=theta, friction=mu, steps=5000), "", ".toml", tmp_path, reverse=False
    )
    time, v, w = trajectory(outputs)
    late = time > 0.01
    acceleration = np.polyfit(time[late], v[late, 0], 1)[0]
    with h5py.File(outputs.forward) as f:
        log = f["observables/events/value"][-1]
    slips = log[KINDS.index("coulomb_slip")]
    if rolls:
        assert acceleration == pytest.approx(5 / 7 * G * math.sin(theta), rel=0.01)
        # the unloaded shear spring slips while it takes up the load, then never again
        assert slips[LAST] < 500  # 5 ms of the 50 ms run
    else:
        assert slips[COUNT] > 4000  # sliding at (almost) every step
        assert acceleration == pytest.approx(G * (math.sin(theta) - mu * math.cos(theta)), rel=0.01)
        assert (v[late, 0] - w[late, 1] * R).min() > 0.01  # the contact point slips


def test_with_infinite_friction_energy_is_conserved_and_reversal_is_round_off(tmp_path):
    outputs = run_scenario(
        on_plane(velocity=(0.02, 0.01, 0), friction=math.inf, steps=4000, reverse=True),
        "",
        ".toml",
        tmp_path,
    )
    with h5py.File(outputs.forward) as f:
        total = f["observables/total_energy/value"][:]
        kinetic = f["observables/kinetic_energy/value"][:]
        shear = f["observables/max_shear_force/value"][:]
    assert shear.max() > 1e-3  # the tangential spring really works
    assert np.ptp(total) < 1e-4 * kinetic[0]
    verdict = json.loads(outputs.comparison.read_text())
    assert verdict["max_position_error_rel"] < 1e-10 and verdict["reversible"]
    assert verdict["max_angular_velocity_error"] < 1e-8


def test_a_rising_plane_carries_the_sphere_and_the_reversal_brings_both_back(tmp_path):
    lift = 0.02  # m/s
    scenario = on_plane(friction=math.inf, steps=20000, reverse=True)
    data = scenario.model_dump()
    data["walls"][0]["velocity"] = (0.0, 0.0, lift)
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        z = f["particles/all/position/value"][:, 0, 2]
        time = f["particles/all/position/time"][:]
        wall_force = f["observables/wall_force/plane/value"][:]
    carried = z[-1] - z[0]
    # the start-up normal oscillation, amplitude lift sqrt(m/k) ~ 12 um, rides on 4 mm
    assert carried == pytest.approx(lift * time[-1], rel=0.01)
    weight = 4 / 3 * math.pi * R**3 * DENSITY * G
    assert np.mean(wall_force[len(wall_force) // 2 :, 2]) == pytest.approx(-weight, rel=0.05)
    assert outputs.verdict["reversible"] and outputs.verdict["max_position_error_rel"] < 1e-10
