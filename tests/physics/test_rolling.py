"""Rolling resistance (EPSD, Ai et al. 2011 type C; Hanley 2020 §5.3): a sphere rolling on
a plane and a spinning pair, against the analytic deceleration, the moment limit, the
conservation laws, and reversal."""

import json
import math

import numpy as np
import pytest

from revdem_cli.config import load_scenario
from revdem_cli.engine import run_scenario
from tests.conftest import stepped, two_spheres

CONFIG = "configs/rolling_resistance.toml"


def rolling(*overrides):
    return load_scenario(CONFIG, list(overrides))


def run(tmp_path, *overrides, reverse=True):
    scenario, text = rolling(*overrides)
    return scenario, run_scenario(scenario, text, ".toml", tmp_path, reverse=reverse)


def test_the_limit_decelerates_a_rolling_sphere_at_five_sevenths_mu_r_g(tmp_path):
    """Rolling without slipping against a moment mu_r r m g: (m + I / r^2) a = -M / r, so
    a = -5/7 mu_r g; then the undamped spring leaves only a rocking of M^2 / (2 k_r)."""
    import h5py

    scenario, outputs = run(tmp_path, reverse=False)
    with h5py.File(outputs.forward) as f:
        t = f["particles/all/velocity/time"][:]
        v = f["particles/all/velocity/value"][:, 0, 0]
    contact = scenario.contact
    g = -scenario.gravity[2]
    rolling_phase = (t > 0.01) & (t < 0.06)  # after the spring wound up, before it stops
    deceleration = -np.polyfit(t[rolling_phase], v[rolling_phase], 1)[0]
    assert deceleration == pytest.approx(5 / 7 * contact.rolling_friction * g, rel=2e-3)
    stop = v[0] / deceleration
    sphere = scenario.particles[0]
    mass = 4 / 3 * math.pi * sphere.radius**3 * scenario.materials["sphere"].density
    moment = contact.rolling_friction * sphere.radius * mass * g
    rocking = moment / math.sqrt(contact.rolling_stiffness * 7 / 5 * mass)  # M / sqrt(k_r I_c)
    assert np.abs(v[t > stop + 0.005]).max() < 1.5 * rocking / sphere.radius
    assert np.abs(v[t > stop + 0.005]).max() < 0.01 * v[0]  # brought to rest


def test_the_rolling_moment_never_exceeds_its_limit_and_reaches_it():
    scenario, _ = rolling()
    mu_r, r = scenario.contact.rolling_friction, scenario.particles[0].radius
    ratios = []
    for state in stepped(scenario, 8000, 5):
        moment = np.linalg.norm(state.walls.rolling[0, 0])
        normal = state.walls.force[0, 0, 2]  # the plane's normal is z
        ratios.append(moment / (mu_r * r * normal))
    assert max(ratios) <= 1 + 1e-12
    assert max(ratios) > 0.999  # the limit acts: this test can fail


def test_the_moment_limit_destroys_information_and_compare_names_it(tmp_path):
    _, outputs = run(tmp_path)
    verdict = json.loads(outputs.comparison.read_text())
    assert not verdict["reversible"]
    # the limit alone: the motions rounded away at rest (a move of 1e-20 m) are rounded
    # away the same in reverse, and a run with no rolling law reverses with as many of them
    assert [cause["mechanism"] for cause in verdict["divergence_causes"]] == ["rolling_limit"]
    (limit,) = verdict["divergence_causes"]  # at the sphere's contact with the plane, wall 0
    assert (limit["particle"], limit["particle_id"]) == (0, 1)
    assert (limit["partner"], limit["partner_id"], limit["partner_wall"]) == (-1, None, "plane")
    assert "the contact of particle 0 (id 1) and wall plane rolled" in limit["message"]


def test_an_elastic_rolling_spring_conserves_energy_and_reverses_to_round_off(tmp_path):
    """With the limit never reached (a very large mu_r) the rolling spring is elastic: the
    sphere rocks back and forth (without sliding: mu = inf), and the run reverses as a
    conservative one does."""
    import h5py

    elastic = ("contact.rolling_friction=1e6", "contact.friction=inf", "stages.0.steps=3000")
    scenario, outputs = run(tmp_path, *elastic)
    verdict = json.loads(outputs.comparison.read_text())
    assert verdict["reversible"], verdict["divergence_causes"]
    assert verdict["max_position_error_rel"] < 1e-10
    with h5py.File(outputs.forward) as f:
        energy = f["observables/total_energy/value"][:]
        kinds = [str(kind) for kind in f["parameters/revdem"].attrs["event_kinds"]]
        log = f["observables/events/value"][-1]
    assert log[kinds.index("rolling_limit"), 0] == 0  # count: never capped
    kinetic = 0.5 * (7 / 5) * 5.236e-4 * 0.05**2
    assert np.ptp(energy) < 1e-3 * kinetic  # the spring's energy is counted: O(dt^2) only


def test_a_spinning_pair_keeps_its_angular_momentum():
    """Two spheres meet head on, one spinning across the line of centres: the rolling moment
    (the pair loop's) winds to its limit, equal and opposite on the two, and the total
    angular momentum, 3e-7 kg m^2/s, stays as it was."""
    contact = {
        "model": "hertz",
        "tangential": "mindlin",
        "friction": float("inf"),
        "rolling": "epsd",
        "rolling_stiffness": 1e-2,
        "rolling_friction": 0.05,
    }
    scenario = two_spheres(contact=contact)
    first = dict(scenario.particles[0]) | {"angular_velocity": (30.0, 0.0, 20.0)}
    scenario = two_spheres(contact=contact, particles=[first, dict(scenario.particles[1])])

    def angular_momentum(state):
        p = state.particles
        return (p.inertia[:, None] * p.omega + p.mass[:, None] * np.cross(p.x, p.v)).sum(0)

    start = None
    largest = 0.0
    for state in stepped(scenario, 6000, 20):
        if start is None:
            start = angular_momentum(state)
        np.testing.assert_allclose(angular_momentum(state), start, rtol=0, atol=1e-9 * 3e-7)
        pairs = state.pairs
        if pairs.count[0] and pairs.overlap[0] > 0:
            x = state.particles.x
            n = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
            limit = 0.05 * 0.0025 * -np.dot(pairs.force[0], n)  # mu_r R* |f_n|
            moment = np.linalg.norm(pairs.rolling[0])
            assert moment <= limit * (1 + 1e-12)
            largest = max(largest, moment / limit)
    assert largest > 0.999  # the pair's rolling spring wound up to its limit
