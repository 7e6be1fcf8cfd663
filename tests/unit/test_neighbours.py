import numpy as np
import pytest

from benchmarks.fcc_hertz import scenario_data
from revdem_cli.config import Scenario
from revdem_cli.io.tape import no_tape
from revdem_cli.kernels.integrate import needs_rebuild
from revdem_cli.kernels.neighbours import (
    build_pairs,
    carry_history,
    index_by_particle,
    largest_reach,
)
from revdem_cli.stage import Model, stepping_bundles
from revdem_cli.state import initial_state
from tests.conftest import crossovers

OPEN = (np.zeros(3, np.int64), np.ones(3))


def brute_force_pairs(x, radius, skin, box=None):
    """Pairs within reach, the nearest image across a periodic box if one is given."""
    n = len(x)
    found = []
    for i in range(n):
        for j in range(i + 1, n):
            d = x[j] - x[i]
            if box is not None:
                d -= box * np.floor(d / box + 0.5)
            if np.linalg.norm(d) < radius[i] + radius[j] + skin:
                found.append((i, j))
    return found


def random_packing(n, seed, size=0.05):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, size, (n, 3)), rng.uniform(0.004, 0.006, n)


def listed(x, radius, skin, periodic, length):
    cap = 20000
    pi, pj = np.zeros(cap, np.int32), np.zeros(cap, np.int32)
    n = build_pairs(x, radius, skin, periodic, length, pi, pj)
    return n, list(zip(pi[:n].tolist(), pj[:n].tolist(), strict=True))


@pytest.mark.parametrize("count", [200, 400])  # serial, parallel: on either side of 256
def test_cell_list_pairs_equal_brute_force_and_are_sorted(count):
    x, radius = random_packing(count, 1)
    with crossovers(256, 256):  # on any threading layer
        n, pairs = listed(x, radius, 0.001, *OPEN)
    expected = brute_force_pairs(x, radius, 0.001)
    assert n == len(expected) > 0
    assert pairs == expected


@pytest.mark.parametrize("size", [0.05, 0.035])  # 3 and 2 cells an edge: each cell once
def test_periodic_pairs_reach_across_faces_to_the_nearest_image(size):
    x, radius = random_packing(300, 3, size)
    box = np.full(3, size)
    n, pairs = listed(x, radius, 0.001, np.ones(3, np.int64), box)
    expected = brute_force_pairs(x, radius, 0.001, box)
    assert pairs == expected
    across = [(i, j) for i, j in expected if np.abs(x[j] - x[i]).max() > size / 2]
    assert across, "some pairs touch only through a face"


def test_too_small_arrays_report_the_size_needed_and_stay_as_they_were():
    x, radius = random_packing(200, 2)
    needed = len(brute_force_pairs(x, radius, 0.001))
    pi, pj = np.full(needed // 2, 7, np.int32), np.full(needed // 2, 7, np.int32)
    assert build_pairs(x, radius, 0.001, *OPEN, pi, pj) == needed
    assert (pi == 7).all() and (pj == 7).all()


def test_history_follows_its_pair_across_rebuilds_in_place():
    rng = np.random.default_rng(5)
    for _ in range(200):
        universe = [(i, j) for i in range(12) for j in range(i + 1, 12)]
        old = sorted(rng.choice(len(universe), rng.integers(0, 30), replace=False))
        new = sorted(rng.choice(len(universe), rng.integers(0, 30), replace=False))
        old_pairs = [universe[k] for k in old]
        new_pairs = [universe[k] for k in new]
        capacity = 40
        history = rng.normal(size=(capacity, 3))
        before = {pair: history[k].copy() for k, pair in enumerate(old_pairs)}
        old_i, old_j = (np.array([p[a] for p in old_pairs] + [0], np.int32) for a in (0, 1))
        new_i, new_j = (np.array([p[a] for p in new_pairs] + [0], np.int32) for a in (0, 1))
        carry_history(old_i, old_j, len(old), new_i, new_j, len(new), history)
        for m, pair in enumerate(new_pairs):
            np.testing.assert_array_equal(history[m], before.get(pair, np.zeros(3)))


def test_the_reach_allows_for_the_single_precision_of_the_positions_at_the_build():
    """A sphere built at 1 + 3 2^-26 m, which single precision rounds to 1 m, has moved
    3 2^-26 m when it reaches 1 m: the reach says at least that, not the 0 of the rounded
    copy, so that the list is rebuilt before a contact can be missed."""
    built_at = np.array([[1.0 + 3 * 2.0**-26, 0.5, 0.5]])
    x_built = built_at.astype(np.float32)
    assert x_built[0, 0] == 1.0  # rounded towards where the sphere goes
    x = np.array([[1.0, 0.5, 0.5]])
    still = np.zeros((1, 3))
    edges = np.ones(3)
    reach = largest_reach(1, x, x_built, still, still, np.ones(1), 0.0, 1, edges, edges)
    assert reach >= built_at[0, 0] - x[0, 0] > 0.0


@pytest.mark.parametrize("direction", [1, -1])
def test_the_reach_bounds_every_particles_distance_after_the_next_drift(direction):
    """In a cell stretched since the build, each particle's distance from its carried build
    position plus its next drift dt |v + direction dt/2 f/m| (Hanley 2020 Eq 1), plus the
    single-precision allowance, is at most the reach; the reach is the sum of the three
    largest, found apart."""
    rng = np.random.default_rng(7)
    n = 300
    length, built = np.array([1.0, 1.1, 0.9]), np.array([1.0, 1.05, 0.95])
    x_built = rng.random((n, 3)).astype(np.float32)
    x = x_built * (length / built) + 1e-4 * rng.normal(size=(n, 3))
    v, f, inv_mass = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.random(n)
    dt = 1e-3
    reach = largest_reach(n, x, x_built, v, f, inv_mass, dt, direction, length, built)
    carried = x_built.astype(np.float64) * (length / built)
    moved = np.linalg.norm(x - carried, axis=1)
    step = dt * np.linalg.norm(v + direction * 0.5 * dt * f * inv_mass[:, None], axis=1)
    allowance = 2.0**-23 * np.abs(carried).sum(axis=1)
    assert np.all(moved + step + allowance <= reach)
    assert reach == pytest.approx(moved.max() + step.max() + allowance.max(), rel=1e-12)


def test_each_particle_lists_its_pairs_in_partner_order():
    pi, pj = np.array([0, 0, 1, 2], np.int32), np.array([1, 3, 2, 3], np.int32)
    first, start, slots = np.zeros(5, np.int32), np.zeros(5, np.int32), np.zeros(4, np.int32)
    index_by_particle(pi, pj, 4, first, start, slots)
    below = [slots[start[p] : start[p + 1]].tolist() for p in range(4)]
    above = [list(range(first[p], first[p + 1])) for p in range(4)]
    per_particle = [b + a for b, a in zip(below, above, strict=True)]
    assert per_particle == [[0, 1], [0, 2], [2, 3], [1, 3]]
    assert [
        [int(pi[k] if pj[k] == p else pj[k]) for k in ks] for p, ks in enumerate(per_particle)
    ] == [
        [1, 3],
        [0, 2],
        [1, 3],
        [0, 2],
    ]


def test_the_list_holds_every_contact_while_spheres_fly_through_many_rebuilds():
    """A periodic gas of 500 spheres at up to 2 m/s, a skin of 0.3 mm: after every few
    steps, each pair of spheres that touch (found by brute force) is in the list."""
    from revdem_cli.config import Scenario
    from revdem_cli.kernels.integrate import OK, PAIR_OVERFLOW, advance
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import empty_events, initial_state
    from tests.conftest import periodic_fcc

    cells, spacing, dt, skin = 5, 0.016, 1e-5, 3e-4
    scenario = Scenario.model_validate(
        {
            "name": "gas",
            **periodic_fcc(cells, spacing, random_velocity=2.0, seed=11),
            "integrator": {"dt": dt},
            "neighbours": {"skin": skin},
            "stages": [{"name": "fly", "steps": 1}],
        }
    )
    model = Model.of(scenario)
    state = initial_state(scenario)
    box = state.cell.length.copy()
    x = state.particles.x
    obs, obs_steps = model.buffers(2)
    stepping = model.stepping(dt, 0, 10**6, 10**6)
    step, rebuilds, contacts = 0, 0, 0
    built = state.pairs.x_built.copy()
    while step < 1500:
        bundles = stepping_bundles(state, model, model.dynamics, model.law)
        status, step, _, _ = advance(
            *bundles, empty_events(), no_tape(), stepping, step, step + 5, step + 5, obs, obs_steps
        )
        if status == PAIR_OVERFLOW:
            state.grow_pairs()
            continue
        assert status == OK
        pairs = state.pairs
        count = int(pairs.count[0])
        listed_pairs = set(zip(pairs.i[:count].tolist(), pairs.j[:count].tolist(), strict=True))
        d = x[None, :, :] - x[:, None, :]
        d -= box * np.floor(d / box + 0.5)
        radius = state.particles.radius
        overlapping = np.linalg.norm(d, axis=2) < radius[:, None] + radius[None, :]
        touching = list(zip(*np.nonzero(np.triu(overlapping, 1)), strict=True))
        assert set(touching) <= listed_pairs, f"step {step}"
        contacts += len(touching)
        rebuilds += not np.array_equal(built, pairs.x_built)
        built = pairs.x_built.copy()
    assert rebuilds >= 30 and contacts >= 100  # the list was tested, and often rebuilt


@pytest.mark.parametrize("shrunk, rebuilt", [(0.04, False), (0.05, True)])
def test_a_shrinking_cell_asks_for_a_rebuild_before_its_gaps_close_half_the_skin(shrunk, rebuilt):
    """Spheres carried with a cell whose edges shrank by `shrunk` since the list was built,
    none moving in it: a gap of r_i + r_j + skin between listed partners' centres closes by
    up to shrunk (2 r_max + skin), 0.42 and 0.525 mm of the 10 mm spheres' 0.5 mm skin; the
    list must be rebuilt once that exceeds half the skin, so at 5 % and not at 4 %."""
    scenario = Scenario.model_validate(scenario_data(2, "frictionless", 1))
    model, state = Model.of(scenario), initial_state(scenario)
    p, pairs, _, cell, *_ = stepping_bundles(state, model, model.dynamics, model.law)
    p.v[:] = 0.0
    p.f[:] = 0.0
    cell.built[:] = cell.length
    cell.length[:] *= 1.0 - shrunk
    p.x[:] = pairs.x_built * (cell.length / cell.built)
    assert needs_rebuild(p, pairs, cell, 1e-6, model.skin, 1) == rebuilt
