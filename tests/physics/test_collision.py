"""Two-sphere collisions: conservation laws, analytic limits and reversal (Hanley 2020 §3.2.1)."""

import json
import math

import h5py
import numpy as np
import pytest

from revdem_cli.engine import run_scenario
from tests.conftest import two_spheres


def forward(scenario, tmp_path):
    return run_scenario(scenario, "", ".toml", tmp_path, reverse=False).forward


def observable(path, name):
    with h5py.File(path) as f:
        return f[f"observables/{name}/step"][:], f[f"observables/{name}/value"][:]


def velocities(path):
    with h5py.File(path) as f:
        return f["particles/all/velocity/value"][:], f["particles/all/mass"][:]


def test_collision_reverses_to_round_off(collision_run):
    verdict = json.loads(collision_run.comparison.read_text())
    assert verdict["frames_compared"] == 301
    assert verdict["max_position_error_rel"] <= 1e-10
    assert verdict["max_velocity_error"] <= 1e-9
    assert verdict["reversible"] and verdict["first_divergence_step"] is None
    energy = verdict["total_energy_back"]  # the energy it started with, to round-off
    assert energy["step"] == 0 and energy["reversed"] == pytest.approx(energy["forward"], 1e-12)
    with h5py.File(collision_run.forward) as f, h5py.File(collision_run.reverse) as r:
        steps = f["particles/all/position/step"][:]
        np.testing.assert_array_equal(steps, r["particles/all/position/step"][:][::-1])
        assert r["parameters/revdem"].attrs["direction"] == "reverse"


def test_collision_transfers_momentum_as_in_figure_1(collision_run):
    v, _ = velocities(collision_run.forward)
    speed = np.linalg.norm(v, axis=2)
    assert speed[0] == pytest.approx([math.hypot(0.9, 0.1), 0.1])
    assert speed[-1, 0] < 0.15 and speed[-1, 1] > 0.85  # most of A's momentum goes to B


def test_energy_is_conserved_through_a_hertz_collision(tmp_path):
    path = forward(two_spheres(), tmp_path)
    _, total = observable(path, "total_energy")
    _, elastic = observable(path, "elastic_energy")
    assert elastic.max() > 0.1 * total[0]  # the spheres really collide
    assert np.ptp(total) / total[0] < 1e-6


def test_momentum_is_conserved_to_round_off(collision_run):
    v, mass = velocities(collision_run.forward)
    momentum = (v * mass[None, :, None]).sum(axis=1)
    assert np.abs(momentum - momentum[0]).max() < 1e-15


@pytest.mark.parametrize("contact", [{"model": "hertz"}, {"model": "linear", "kn": 5e3}])
def test_head_on_collision_of_equal_spheres_exchanges_normal_velocities(tmp_path, contact):
    scenario = two_spheres(contact=contact)
    data = scenario.model_dump()
    data["particles"][0]["velocity"] = (0.3, 0.0, 0.0)
    data["particles"][1]["velocity"] = (-0.1, 0.0, 0.0)
    data["stages"][0]["steps"] = 20000
    path = forward(type(scenario).model_validate(data), tmp_path)
    v, _ = velocities(path)
    np.testing.assert_allclose(v[-1], [[-0.1, 0.0, 0.0], [0.3, 0.0, 0.0]], rtol=0, atol=1e-6)


def test_linear_contact_lasts_half_a_period_of_the_reduced_mass(tmp_path):
    kn = 5e3
    stage = {"name": "collide", "steps": 12000, "output_every": 1000, "observables_every": 1}
    path = forward(two_spheres(contact={"model": "linear", "kn": kn}, stages=[stage]), tmp_path)
    steps, elastic = observable(path, "elastic_energy")
    in_contact = steps[elastic > 0]
    duration = (in_contact[-1] - in_contact[0] + 1) * 1e-7
    mass = 4 / 3 * math.pi * 0.005**3 * 1000
    assert duration == pytest.approx(math.pi * math.sqrt(mass / 2 / kn), abs=2e-7)
    _, total = observable(path, "total_energy")
    assert np.ptp(total) / total[0] < 1e-6


def test_a_perturbed_reversal_is_caught(tmp_path):
    from revdem_cli.engine import reverse_run
    from revdem_cli.io.restart import read_restart, write_restart

    outputs = run_scenario(two_spheres(), "", ".toml", tmp_path, reverse=False)
    restart = read_restart(outputs.restart)
    restart.state.particles.v[0, 1] += 1e-6
    write_restart(outputs.restart, restart)
    verdict = reverse_run(outputs.restart, tmp_path / "rev").verdict
    assert not verdict["reversible"] and not verdict["bitwise_identical"]
    assert verdict["first_divergence_step"] == 6000  # already at the restart frame
    assert verdict["max_velocity_error"] == pytest.approx(
        1e-6, rel=0.05
    )  # grows a little on the way back


def test_viscous_damping_gives_the_spring_dashpot_restitution_coefficient(tmp_path):
    beta, kn = 0.1, 5e3  # damping c = 2 beta sqrt(m* kn) with the reduced mass m*
    contact = {"model": "linear", "kn": kn, "normal_damping": beta}
    stage = {"name": "collide", "steps": 12000, "output_every": 1000}
    path = forward(two_spheres(contact=contact, stages=[stage]), tmp_path)
    v, _ = velocities(path)
    restitution = (v[-1, 1, 0] - v[-1, 0, 0]) / (v[0, 0, 0] - v[0, 1, 0])
    assert restitution == pytest.approx(
        math.exp(-math.pi * beta / math.sqrt(1 - beta**2)), rel=2e-3
    )


def test_local_damping_stops_a_bouncing_sphere_and_is_named_when_reversal_fails(tmp_path):
    scenario = two_spheres(
        particles=[{"material": "sphere", "radius": 0.005, "position": [0, 0, 0.0051]}],
        walls=[
            {
                "name": "floor",
                "type": "plane",
                "material": "sphere",
                "point": [0, 0, 0],
                "normal": [0, 0, 1],
            }
        ],
        gravity=[0, 0, -9.81],
        damping={"local": 0.7},
        integrator={"dt": 1e-6},
        stages=[{"name": "settle", "steps": 40000, "output_every": 1000, "reverse": True}],
    )
    outputs = run_scenario(scenario, "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        kinetic = f["observables/kinetic_energy/value"][:]
    assert kinetic[-1] < 1e-6 * kinetic.max()  # undamped, it would keep bouncing at the peak
    verdict = outputs.verdict
    assert not verdict["reversible"]
    causes = {cause["mechanism"]: cause for cause in verdict["divergence_causes"]}
    damping = causes["local_damping"]  # no contact: no partner, where -1 named wall 0
    assert damping["partner"] is damping["partner_id"] is damping["partner_wall"] is None
    # the total energy of each run at step 0, where the reversal returns
    energy = verdict["total_energy_back"]
    with h5py.File(outputs.forward) as f, h5py.File(outputs.reverse) as r:
        assert energy["forward"] == f["observables/total_energy/value"][0]
        assert energy["reversed"] == r["observables/total_energy/value"][-1]
        assert r["observables/total_energy/step"][-1] == energy["step"] == 0


def test_a_reversal_run_above_the_critical_time_step_is_blamed_on_it_not_on_round_off(tmp_path):
    """The smoke collision let go on at dt = 1.55 times its critical step (0.386 ms) parts at
    once with no mechanism acting: the verdict names the time step, where it had said
    round-off growth, and below the limit (0.26 ms) nothing is blamed on it."""
    from revdem_cli.config import load_scenario
    from tests.conftest import CONFIGS

    def verdict(dt):
        sets = [f"integrator.dt={dt}", "stages.0.steps=100", "stages.0.output_every=10"]
        scenario, text = load_scenario(CONFIGS / "smoke" / "collision.yaml", sets)
        out = tmp_path / str(dt)
        return run_scenario(scenario, text, ".yaml", out, allow_unstable_dt=True).verdict

    above = verdict(6e-4)
    assert not above["reversible"]
    (cause,) = above["divergence_causes"]
    assert cause["mechanism"] == "time_step_above_limit"
    assert cause["amount"] == pytest.approx(6e-4 / 3.86e-4, rel=2e-3)
    assert "1.55 times the critical time step" in cause["message"]
    assert "amplifies round-off" in cause["message"]
    below = verdict(2.6e-4)
    assert below["reversible"] and below["divergence_causes"] == []


def test_viscous_damping_is_logged_at_the_contacts_it_acts_on(tmp_path):
    """Viscous damping was logged at every step of a run with beta > 0, contact or none: the
    damped collision counted its 3000 steps, and a sphere falling under drag that never
    touched anything, with normal_damping set, was blamed on the dashpot, not on drag's
    amplification of round-off (Hanley 2020 Eq 28). Now the force loops log it at the contacts
    touching: one a step of the collision's contact, and none in the fall."""
    from revdem_cli import api as revdem
    from tests.conftest import CONFIGS

    damped = revdem.load(CONFIGS / "trvp" / "collision_damped.toml").changed(
        {"stages.0.observables_every": 1, "output.figures": []}
    )
    result = revdem.run(damped, tmp_path / "collision")
    times, coordination = result.observables()["coordination_number"]
    steps = np.rint(times / 1e-6).astype(int)  # dt = 1 us
    touching = steps[(coordination > 0.0) & (steps > 0)]  # forces found after each step
    (cause,) = result.comparison["divergence_causes"]
    assert cause["mechanism"] == "viscous_damping"
    assert 1500 < cause["occurrences"] == len(touching) < 2000  # a contact of 1.68 ms
    assert cause["step"] == touching[-1] and cause["amount"] == 0.3
    assert (cause["particle_id"], cause["partner_id"]) == (1, 2)
    assert "(beta = 0.3) acted up to step" in cause["message"]

    fall = revdem.load(CONFIGS / "drop_A.toml").changed(
        {
            "damping.drag": 0.999,
            "contact.normal_damping": 0.1,  # acts at no contact: the sphere falls 2 mm of 1 m
            "integrator.dt": 1e-6,
            "particles.0.position": [0.0, 0.0, 1.0],
            "stages.0.steps": 20000,
            "stages.0.output_every": 1000,
            "reversal.velocity_tolerance": 1e-13,
            "reversal.position_tolerance_rel": 1e-15,
            "output.figures": [],
        }
    )
    verdict = revdem.run(fall, tmp_path / "fall").comparison
    assert not verdict["reversible"]
    mechanisms = [cause["mechanism"] for cause in verdict["divergence_causes"]]
    assert mechanisms == ["drag_amplifies_round_off"], mechanisms


def test_a_frictionless_shear_law_destroys_nothing(tmp_path):
    """With mu = 0 a shear law's history is capped to zero each step: the reversed step,
    capping the same way, finds it again (zero), so nothing is destroyed, but every step of
    every contact was logged as a Coulomb slip, and the reversal of the frictionless
    critical-state cell blamed on it. A slip that removes only the step's increment at
    mu = 0 is no longer logged."""
    from revdem_cli import api as revdem
    from revdem_cli.kernels.events import COUNT, KINDS
    from tests.conftest import CONFIGS

    experiment = revdem.load(CONFIGS / "collision_shear.toml").changed(
        {"contact.friction": 0.0, "output.figures": []}
    )
    result = revdem.run(experiment, tmp_path)
    with h5py.File(result.outputs.forward) as f:
        events = f["observables/events/value"][-1]
        sliding = f["observables/sliding_fraction/value"][:]
    assert events[KINDS.index("coulomb_slip"), COUNT] == 0
    assert sliding.max() == 1.0  # every contact at its limit, mu |f_n| = 0: sliding
    mechanisms = [cause["mechanism"] for cause in result.comparison["divergence_causes"]]
    assert "coulomb_slip" not in mechanisms
