"""The pair loop, done in blocks with a vectorised contact stage, gives bit for bit what the
contact law gives pair by pair, including spin corrections too large for its fast path."""

import numba
import numpy as np
import pytest

from benchmarks.fcc_hertz import scenario_data
from revdem_cli.config import Scenario
from revdem_cli.kernels.cell import images
from revdem_cli.kernels.contact import FORWARD, SMALL_ANGLE, contact_force
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.pairs import (
    FIRST,
    LEAST_PART,
    PART,
    TOOK,
    balanced,
    empty_balance,
    pair_geometry,
    pair_velocity,
    separation,
)
from revdem_cli.kernels.vectors import ZERO, put, row
from revdem_cli.stage import Model, stepping_bundles
from revdem_cli.state import empty_events, initial_state

DT = scenario_data(1, "history", 1)["integrator"]["dt"]  # s, the benchmark's


def fcc(cells: int) -> Scenario:
    """The fcc Hertz benchmark with shear history (benchmarks/fcc_hertz.py) at n = cells."""
    return Scenario.model_validate(scenario_data(cells, "history", 1))


@numba.njit
def pair_by_pair(x, v, w, radius, estar, gstar, image, pi, pj, history, law, force, shear):
    """Each pair's force and new history from contact_force, one pair at a time."""
    strain = (0.0, 0.0, 0.0)
    for k in range(force.shape[0]):
        i, j = pi[k], pj[k]
        d = separation(x, i, j, image)
        overlap, n, rstar = pair_geometry(d, radius[i], radius[j])
        if overlap > 0.0:
            v_ij = (v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], v[j, 2] - v[i, 2])
            vrel, spin = pair_velocity(
                d, n, overlap, radius[i], radius[j], v_ij, row(w, i), row(w, j), strain, False
            )
            f, s, _, _, _ = contact_force(
                law, FORWARD, DT, overlap, n, rstar, 0.0, estar[0, 0], gstar[0, 0], vrel, vrel,
                spin, row(history, k), ZERO,
            )  # fmt: skip
            put(force, k, f)
            put(shear, k, s)


def test_a_pair_apart_has_a_zero_normal_and_a_touching_one_its_unit_normal():
    """`pair_geometry` (Eq 6): d / |d| as d (1 / |d|) for a pair in overlap; for a pair apart,
    just (within APART) or certainly (no distance found), and for one just touching, a zero
    normal, so that its spin about n, the normal its history turns from and the one the
    unwinding keeps are zero."""
    r = 0.005
    d = (0.006, 0.0075, 0.0)  # |d| = 0.0096...: an overlap of 0.4 mm
    overlap, n, rstar = pair_geometry(d, r, r)
    distance = np.sqrt(np.dot(d, d))
    assert overlap == 2 * r - distance > 0.0 and rstar == r * r / (2 * r)
    assert n == tuple(np.array(d) * (1.0 / distance))
    for gap in (0.0, 1e-16, 1e-3):  # touching, apart within APART, certainly apart
        overlap, n, _ = pair_geometry((2 * r + gap, 0.0, 0.0), r, r)
        assert overlap <= 0.0 and n == (0.0, 0.0, 0.0), (gap, overlap, n)


@pytest.mark.parametrize(
    "spin, jitter",  # rad/s: spin corrections of 1e-6 and 0.1 rad; m, against overlaps of 10 um
    [(1.0, 0.0), (1e5, 0.0), (1.0, 1e-5)],
)
def test_blocks_match_the_contact_law_pair_by_pair(spin, jitter):
    scenario = fcc(4)  # 256 spheres: the parallel loops, with a block per thread
    model, state = Model.of(scenario), initial_state(scenario)
    p, pairs = state.particles, state.pairs
    rng = np.random.default_rng(2)
    n_pairs = int(pairs.count[0])
    p.x[:] += rng.normal(size=p.x.shape) * jitter  # listed pairs apart, beside ones touching
    pairs.history[:n_pairs] = rng.normal(size=(n_pairs, 3)) * 1e-4
    p.omega[:] = rng.normal(size=p.omega.shape) * spin
    force, shear = np.zeros((n_pairs, 3)), np.zeros((n_pairs, 3))
    pair_by_pair(
        p.x, p.v, p.omega, p.radius, model.moduli.estar, model.moduli.gstar,
        images(state.cell), pairs.i, pairs.j, pairs.history, model.law, force, shear,
    )  # fmt: skip
    largest_turn = np.abs(p.omega).sum(axis=1).max() * DT
    assert (largest_turn > 2 * SMALL_ANGLE) == (spin > 1.0)  # the slow path taken, or not
    compute_forces(
        *stepping_bundles(state, model, model.dynamics, model.law), FORWARD, DT, 0.0,
        empty_events(), 1, True,
    )  # fmt: skip
    assert np.array_equal(pairs.force[:n_pairs], force)
    assert np.array_equal(pairs.history[:n_pairs], shear)
    apart = pairs.overlap[:n_pairs] <= 0.0
    assert apart.any() == (jitter > 0.0) and not apart.all()
    assert not force[apart].any() and not shear[apart].any()


def test_the_shares_of_the_list_settle_where_the_threads_finish_together():
    """`pairs.balanced`: chunks whose threads take 1 and 3 ns a pair come to hold 3/4 and 1/4
    of the pairs, each call halfway from the last; a thread 100 times slower keeps the least
    share, LEAST_PART of an even one; a call on another number of chunks starts even."""
    first_pair = np.arange(0, 10_001, 10, dtype=np.int32)  # 1 000 particles, 10 pairs each
    n_pairs = 10_000
    for costs, settled in (((1.0, 3.0), (0.75, 0.25)), ((1.0, 100.0), None)):
        balance = empty_balance(4)
        parts = []
        for _ in range(40):
            balanced(balance, 2, first_pair, n_pairs)
            parts.append(balance[:2, PART].copy())
            first = int(balance[1, FIRST])
            assert first_pair[first] >= int(n_pairs * parts[-1][0]) > first_pair[first - 1]
            balance[:2, TOOK] = parts[-1] * n_pairs * np.array(costs)  # ns, as the threads took
        assert np.array_equal(parts[0], [0.5, 0.5])  # nothing timed yet: even
        assert np.isclose(parts[1][0], 0.5 * (0.5 + costs[1] / sum(costs)), rtol=1e-12)
        if settled is not None:
            assert np.allclose(parts[-1], settled, rtol=1e-12)
        else:
            assert np.allclose(parts[-1], [1 - LEAST_PART / 2, LEAST_PART / 2], rtol=1e-12)
    balanced(balance, 3, first_pair, n_pairs)  # timed on two chunks, now three
    assert np.array_equal(balance[:3, PART], [1 / 3, 1 / 3, 1 / 3])
    balance[:3, TOOK] = (1.0, 1.0, 1.0)  # timed on three, now two: even, then by pace again
    balanced(balance, 2, first_pair, n_pairs)
    assert np.array_equal(balance[:2, PART], [0.5, 0.5]) and not balance[:, TOOK].any()
    balance[:2, TOOK] = (1.0, 3.0)
    balanced(balance, 2, first_pair, n_pairs)
    assert np.isclose(balance[0, PART], 0.5 * (0.5 + 0.75), rtol=1e-12)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two threads")
@pytest.mark.parametrize("took", [(1, 9), (9, 1)], ids=["first-heavy", "second-heavy"])
def test_the_forces_do_not_depend_on_where_the_list_is_cut(took):
    """Each sphere's sums, each pair's force and history are bit for bit those of one thread
    however the pair loop cuts the list between two (`pairs.balanced`), the particles with
    partners in both chunks summed apart (`sum_foreign`) wherever the cut falls."""
    scenario = fcc(4)  # 256 spheres: the parallel build
    model = Model.of(scenario)
    results = []
    for threads in (1, 2):
        state = initial_state(scenario)
        p, pairs = state.particles, state.pairs
        rng = np.random.default_rng(3)
        n_pairs = int(pairs.count[0])
        p.x[:] += rng.normal(size=p.x.shape) * 1e-5
        p.omega[:] = rng.normal(size=p.omega.shape)
        pairs.history[:n_pairs] = rng.normal(size=(n_pairs, 3)) * 1e-4
        pairs.balance[:2, PART] = 0.5
        pairs.balance[:2, TOOK] = took  # as if one thread had taken 9 times the other's time
        was = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            for _ in range(3):  # the first call's cut as `took` gives it, then as timed
                pairs.history[:n_pairs] = rng.normal(size=(n_pairs, 3)) * 1e-4
                compute_forces(
                    *stepping_bundles(state, model, model.dynamics, model.law), FORWARD, DT,
                    0.0, empty_events(), 1, True,
                )  # fmt: skip
                results.append((threads, pairs.balance[:2, PART].copy(), p.f.copy(),
                                p.torque.copy(), pairs.force[:n_pairs].copy(),
                                pairs.history[:n_pairs].copy()))  # fmt: skip
        finally:
            numba.set_num_threads(was)
    one, two = results[:3], results[3:]
    heavier = int(np.argmax(took))
    assert np.isclose(two[0][1][heavier], 0.5 * (0.5 + 0.1), rtol=1e-12)  # off the even cut
    for (_, _, *a), (_, _, *b) in zip(one, two, strict=True):
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x, y)
