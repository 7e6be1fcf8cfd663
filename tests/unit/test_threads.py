"""The stage loop's driver (`threads.Stepper`): stretches that end where asked with every
observables row kept, the thread count that steps fastest on the machine as it is, and
trajectories that do not depend on where the count changes."""

from types import SimpleNamespace

import h5py
import numba
import numpy as np
import pytest

from revdem_cli import threads
from revdem_cli.engine import run_scenario
from revdem_cli.kernels import HEAVY, LIGHT, one_thread, threads_for
from revdem_cli.kernels.pairs import pair_loop
from revdem_cli.threads import Stepper
from tests.conftest import crossovers
from tests.physics.test_determinism import lattice

pytestmark = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")

EVERY = 10


class Clock:
    """The stepper's clock (`threads.time.perf_counter`), moved on by the fake stage loops'
    work alone: a stretch takes exactly what its steps cost, whatever else the machine runs
    (the stepper's choices are tested, not this machine's timing)."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now


def fake_loop(clock: Clock, cost: dict[int, float], first_call: dict[int, float] | None = None):
    """A stage loop whose step costs cost[thread count] seconds of `clock`, and whose first
    call on a count first_call[count] more, with an observables row every EVERY steps,
    stopping at `until`."""
    warming = dict(first_call or {})

    def loop(particles, stepping, step, stop, until, obs, obs_steps):
        seconds = cost[numba.get_num_threads()]
        clock.now += warming.pop(numba.get_num_threads(), 0.0)
        rows = 0
        while step != until:
            clock.now += seconds
            step += 1 if until > step else -1
            if step % EVERY == 0:
                obs_steps[rows] = step
                obs[rows, 0] = step
                rows += 1
        return 0, step, rows, None

    return loop


PARTICLES = 256
"""The fake stage's particles, from which the tests' crossovers (`quick`) run it in parallel."""


@pytest.fixture
def quick(monkeypatch) -> Clock:
    """Stretches and trials short enough for a test, a stage large enough to time two
    threads on any threading layer, and the stepper's clock (`Clock`)."""
    monkeypatch.setattr(threads, "PAUSE", 0.005)
    monkeypatch.setattr(threads, "PROBE_EVERY", 0.05)
    monkeypatch.setattr(threads, "PROBE", 0.01)
    monkeypatch.setattr(threads, "_count", 2)
    clock = Clock()
    monkeypatch.setattr(threads, "time", clock)
    with crossovers(PARTICLES, PARTICLES):
        yield clock


def step_with(
    clock: Clock, cost: dict[int, float], stop: int, start=0, first_call=None, stepper=None
) -> tuple[Stepper, tuple, np.ndarray]:
    stepper = stepper or Stepper()
    particles = SimpleNamespace(x=np.zeros((PARTICLES, 3)))
    rows = abs(stop - start) // EVERY + 2
    obs, obs_steps = np.zeros((rows, 1)), np.zeros(rows, dtype=np.int64)
    loop = fake_loop(clock, cost, first_call)
    done = stepper.advance(loop, (particles,), None, start, stop, obs, obs_steps)
    return stepper, done, obs_steps[: done[2]]


@pytest.mark.parametrize(("start", "stop"), [(0, 3000), (3000, 0)])
def test_a_stage_is_stepped_to_its_stop_in_stretches_keeping_every_row(quick, start, stop):
    stepper, (status, reached, rows, _), steps = step_with(quick, {1: 2e-5, 2: 2e-5}, stop, start)
    assert status == 0 and reached == stop
    direction = 1 if stop > start else -1
    assert np.array_equal(
        steps, np.arange(start + direction * EVERY, stop + direction, direction * EVERY)
    )
    assert sum(stepper.steps_with.values()) == 3000
    assert set(stepper.steps_with) == {1, 2}  # both counts were timed


@pytest.mark.parametrize(("slow", "fast"), [(2, 1), (1, 2)])
def test_the_stepper_computes_on_the_thread_count_that_steps_faster(quick, slow, fast):
    """Two threads five times slower (busy cores: a barrier waits for a descheduled
    thread), or five times faster: most steps go to the faster count, a few to trials."""
    stepper, (_, reached, _, _), _ = step_with(quick, {slow: 1e-4, fast: 2e-5}, 40000)
    assert reached == 40000
    assert stepper.steps_with[fast] > 0.9 * 40000, stepper.steps_with


def test_a_new_stage_times_its_thread_counts_afresh(quick):
    """A stage after one where two threads lost every trial: its first call on one thread
    is slowed by a warm-up (its code loaded), which is not taken for one thread's rate, so
    its steps go to one thread, five times faster."""
    stepper, _, _ = step_with(
        quick, {1: 2e-5, 2: 1e-4}, 100000
    )  # its trials further and further apart
    before = dict(stepper.steps_with)
    stepper.new_stage()
    step_with(quick, {1: 2e-5, 2: 1e-4}, 20000, first_call={1: 0.05}, stepper=stepper)
    assert stepper.steps_with[1] - before[1] > 0.9 * 20000, stepper.steps_with


def test_a_count_chosen_on_a_rate_older_than_the_other_s_is_timed_again_first(quick, monkeypatch):
    """A stage whose steps grow costlier, as a pour gains contacts: one thread leads, then
    every step costs five times more. One thread's fresh rate falls below the rate two
    threads had when steps were cheap; two threads, still the slower, then step for a
    trial's length (PROBE seconds at that rate, or at one thread's for a trial), not for a
    stretch sized by it (PAUSE seconds)."""
    monkeypatch.setattr(threads, "PROBE", 0.001)  # a trial shorter than a stretch, as in a run
    costlier_from = 6000
    stretches = []  # (count, first step, steps, the rates the stepper held)
    stepper = Stepper()

    def loop(particles, stepping, step, stop, until, obs, obs_steps):
        count = numba.get_num_threads()
        stretches.append((count, step, until - step, dict(stepper._rate)))
        while step != until:
            quick.now += (2e-5 if count == 1 else 4e-5) * (5 if step >= costlier_from else 1)
            step += 1
        return 0, step, 0, None

    particles = SimpleNamespace(x=np.zeros((PARTICLES, 3)))
    obs, obs_steps = np.zeros((1, 1)), np.zeros(1, dtype=np.int64)
    stepper.advance(loop, (particles,), None, 0, 12000, obs, obs_steps)
    after = [s for s in stretches if s[0] == 2 and s[1] >= costlier_from]
    assert after, "two threads never tried once steps grew costlier"
    count, first, steps, rates = after[0]
    assert steps <= max(1, int(max(rates.values()) * threads.PROBE)), (first, steps, rates)
    assert stepper.steps_with[1] > 0.8 * 12000, stepper.steps_with


def test_a_loop_computes_on_the_threads_from_its_weights_crossover_read_at_each_call():
    """`threads_for`, where every parallel loop chooses: one thread below the crossover of its
    weight, the calling thread's count from it on; a crossover changed after the first call
    is the one the next call obeys (compiled code reads `parallel_from`, it does not keep
    the value it was compiled with)."""
    numba.set_num_threads(2)
    try:
        with crossovers(100, 256):
            assert (threads_for(255, HEAVY), threads_for(256, HEAVY)) == (1, 2)
            with crossovers(10, 10**6):
                assert (threads_for(9, LIGHT), threads_for(10, LIGHT)) == (1, 2)
                assert threads_for(10**6 - 1, HEAVY) == 1
                numba.set_num_threads(1)
                assert threads_for(10**6, HEAVY) == 1
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def test_the_pair_loops_serial_build_is_told_one_thread():
    """`by_size`'s serial constants: the pair loop's serial build sees `threads_for` as
    `one_thread`, a constant, so that its code for several chunks folds away; its parallel
    build asks the calling thread."""
    builds = pair_loop.py_func.__globals__
    assert builds["SERIAL"].py_func.__globals__["threads_for"] is one_thread
    assert builds["PARALLEL"].py_func.__globals__["threads_for"] is threads_for


def test_a_run_is_bitwise_the_same_wherever_the_thread_count_changes(
    tmp_path, monkeypatch, every_loop_parallel
):
    """The fcc lattice (parallel loops, frictional contacts, a servo) stepped on 2 threads
    throughout, then with the count changed every 7 steps."""
    scenario = lattice()
    monkeypatch.setattr(threads, "_count", 2)
    monkeypatch.setattr(Stepper, "_next", lambda self, counts: (2, 10**9))
    run_scenario(scenario, "", ".toml", tmp_path / "steady", reverse=False)
    turns = iter(range(10**9))
    monkeypatch.setattr(Stepper, "_next", lambda self, counts: (1 + next(turns) % 2, 7))
    run_scenario(scenario, "", ".toml", tmp_path / "switching", reverse=False)
    with (
        h5py.File(tmp_path / "steady" / "lattice.forward.h5") as a,
        h5py.File(tmp_path / "switching" / "lattice.forward.h5") as b,
    ):
        for name in ("position", "velocity", "angular_velocity"):
            first, second = a[f"particles/all/{name}/value"][:], b[f"particles/all/{name}/value"][:]
            assert np.abs(first[-1] - first[0]).max() > 0  # it moved
            assert np.array_equal(first, second), name
        assert np.array_equal(a["observables/stress/value"][:], b["observables/stress/value"][:])
