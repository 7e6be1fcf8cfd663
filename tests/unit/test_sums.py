"""System-wide sums by blocks of particles: every particle and pair counted once, the same
numbers whatever the thread count."""

import os
import subprocess
import sys

import numpy as np
import pytest

from revdem_cli.config import Scenario
from revdem_cli.kernels.health import HEALTHY, NOT_FINITE, TOO_DEEP, examine
from revdem_cli.kernels.sums import SPAN
from revdem_cli.stage import Model
from revdem_cli.state import initial_state
from tests.conftest import periodic_fcc

CELLS = 11
"""4 x 11^3 = 5324 spheres: two blocks of the sums."""


def shaken_lattice() -> Scenario:
    """A periodic fcc lattice pressed 1e-5 m into each other (12 contacts a sphere), with
    random velocities and Mindlin contacts."""
    spacing = 0.999 * 0.01 * 2**0.5
    return Scenario.model_validate(
        {
            "name": "lattice",
            **periodic_fcc(CELLS, spacing, random_velocity=0.01, seed=5),
            "integrator": {"dt": 1e-6},
            "stages": [{"name": "run", "steps": 1}],
        }
    )


def observed(scenario: Scenario) -> tuple:
    model = Model.of(scenario)
    state = initial_state(scenario)
    return model, state, model.observe(state, model.dynamics)


def test_the_lattice_spans_more_than_one_block():
    assert 4 * CELLS**3 > SPAN


def test_blocked_observables_count_every_particle_and_contact_once():
    model, state, row = observed(shaken_lattice())
    p, pairs = state.particles, state.pairs
    count = int(pairs.count[0])
    kinetic = 0.5 * (p.mass * (p.v**2).sum(1) + p.inertia * (p.omega**2).sum(1)).sum()
    assert row[model.layout.column("kinetic_energy")] == pytest.approx(kinetic, rel=1e-12)
    assert row[model.layout.column("coordination_number")] == 12.0  # 2 x 6 N contacts / N
    normal = np.linalg.norm(pairs.force[:count], axis=1)  # no shear force yet
    assert row[model.layout.column("max_normal_force")] == pytest.approx(normal.max(), rel=1e-12)
    length = state.cell.length
    d = p.x[pairs.j[:count]] - p.x[pairs.i[:count]]
    d -= length * np.floor(d / length + 0.5)
    stress = -np.einsum("ka,kb->ab", d, pairs.force[:count]) / length.prod()
    column = model.layout.column("stress")
    assert row[column : column + 9].reshape(3, 3) == pytest.approx(stress, rel=1e-12)
    assert np.trace(stress) > 0  # compressed: something was summed


@pytest.mark.parametrize("block", [0, 1])
def test_examine_finds_a_fault_in_any_block(block):
    scenario = shaken_lattice()
    state = initial_state(scenario)
    p, pairs, walls, cell = state.particles, state.pairs, state.walls, state.cell
    assert examine(p, pairs, walls, cell, 0.5).what == HEALTHY
    q = block * SPAN + 7
    k = int(pairs.first[q])  # the first pair listed under q
    j = int(pairs.j[k])
    saved = p.x[j].copy()
    p.x[j] = p.x[q] + 0.2 * (p.x[j] - p.x[q])  # 80 % of the way into q
    finding = examine(p, pairs, walls, cell, 0.5)
    assert finding.what == TOO_DEEP
    assert (finding.particle, finding.partner) == (q, j)
    p.x[j] = saved
    p.omega[q + 1, 2] = np.nan
    finding = examine(p, pairs, walls, cell, 0.5)
    assert finding.what == NOT_FINITE
    assert (finding.particle, finding.value) == (q + 1, 2)


def test_observables_are_bitwise_the_same_with_one_and_two_threads():
    script = (
        "from tests.unit.test_sums import *; import sys;"
        "sys.stdout.write(observed(shaken_lattice())[2].tobytes().hex())"
    )
    rows = []
    for threads in (1, 2):
        env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
        done = subprocess.run(
            [sys.executable, "-c", script], check=True, env=env, capture_output=True, text=True
        )
        rows.append(done.stdout.strip())
    assert rows[0] == rows[1]
    model = Model.of(shaken_lattice())
    column = model.layout.column("stress")
    stress = np.frombuffer(bytes.fromhex(rows[0]))[column : column + 9].reshape(3, 3)
    assert np.trace(stress) > 0  # the blocks' contacts were summed, on each thread count
