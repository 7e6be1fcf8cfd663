"""The threads a run computes with, and the driver of the compiled stage loop (`Stepper`).

How many threads the parallel loops may use (`use`, `--threads`), and the threading layer
numba loaded (in the order `kernels.LAYERS` gives), for the run's header and
`revdem info --system`. The parallel regions run on revdem's own threads whatever the layer
(`kernels.pool`). Loops too small to pay for a parallel region run serially
(`kernels.by_size`, `kernels.CROSSOVERS`), and with one thread every loop does.

Results do not depend on the thread count (every sum is in a fixed order), so the `Stepper`
may change it between any two steps: it steps in pauses of about `PAUSE` seconds, times each,
and computes on the count that steps fastest on this machine as it is now. On busy cores a
region waits for a row a descheduled helper took, and a helper that is not running takes
none, so that one thread can be faster than two; on a quiet machine the other way round.

The thread count is per thread in numba: `use` sets it in the calling thread, and the
`Stepper` sets the count it chose before each stretch, in whichever thread steps.
"""

from __future__ import annotations

import os
import time

import numba
import numpy as np

import revdem_cli.kernels  # noqa: F401  (its threading-layer order, before any layer loads)

_count: int | None = None  # the most threads `use` allows, for the `Stepper`


def available() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0))


def most() -> int:
    """The most threads a parallel loop can use: numba's pool (NUMBA_NUM_THREADS)."""
    return numba.config.NUMBA_NUM_THREADS


def check(count: int) -> None:
    """ValueError for a thread count outside 1 to numba's pool, which a run cannot use: a
    run's own (`use`), or each of a local sweep's variants', whose workers would make a
    pool of that many."""
    if not 1 <= count <= most():
        raise ValueError(f"{count} threads: between 1 and {most()} (NUMBA_NUM_THREADS)")


def use(threads: int | None = None) -> int:
    """Compute with at most `threads` threads (default: the cores this process may use, at
    most the pool) from here on, in this thread and in the stage loops `Stepper` drives."""
    global _count
    count = min(available(), most()) if threads is None else threads
    check(count)
    numba.set_num_threads(count)
    _count = count
    return count


def layer() -> str:
    """The threading layer numba loaded (loading it if no parallel loop has run yet)."""
    numba.get_num_threads()  # launches the layer
    return numba.threading_layer()


def summary() -> dict:
    """What the parallel loops run on: the layer, threads in use, the pool, the cores."""
    from revdem_cli.kernels import pool

    return {
        "threading_layer": layer(),
        "pool_helpers": pool.helpers(),
        "threads": numba.get_num_threads(),
        "thread_pool": most(),
        "cores_available": available(),
        "layer_priority": list(numba.config.THREADING_LAYER_PRIORITY),
    }


PAUSE = 0.25
"""Seconds of stepping between two returns of the compiled loop to the `Stepper`."""

PROBE_EVERY = 5.0
"""Seconds of stepping before the thread count not in use is timed again; doubled each time
it loses, up to `PROBE_EVERY_MOST`."""

PROBE_EVERY_MOST = 320.0

PROBE = 0.02
"""A trial of the thread count not in use lasts this many seconds at the faster count's last
rate; so does the first stretch on a count chosen on a rate older than the other count's."""


class Stepper:
    """Drives the compiled stage loop (`kernels.integrate.advance`) from a step to a pause.

    It returns to Python about every `PAUSE` seconds, and there chooses the thread count of
    the next stretch: the one of the fastest recent stepping, with a short trial of the other
    now and then; the calling thread's own kernel calls between stretches (frames, stop
    conditions) take the same count. The loop runs in the calling thread, the one thread of
    the run that computes in parallel: a region another thread starts while one is running
    runs serially in it (`kernels.pool`). A signal sets `halt`, which the loop reads at every step
    (`integrate.HALTED`), from a thread of its own (`checkpoint.Checkpoints.on_signals`)."""

    def __init__(self):
        self.halt = np.zeros(1, dtype=np.int64)
        self.steps_with: dict[int, int] = {}  # steps stepped on each thread count
        self._rate: dict[int, float] = {}  # steps a second, the latest stretch on each count
        self._stretch: dict[int, int] = {}  # steps of the next stretch on each count
        self._warm: set[int] = set()  # counts past their first stretch
        self._timed_at: dict[int, float] = {}  # seconds of stepping when each rate was taken
        self._last = 0  # the count of the last stretch
        self._stepped = 0.0  # seconds of stepping
        self._probe_at = PROBE_EVERY
        self._probe_every = PROBE_EVERY

    def new_stage(self) -> None:
        """Forget what the stretches so far measured: a stage steps loops of its own (its
        laws, its direction), at a cost a step of their own, and their first calls load their
        code. A rate from the stage before, or from such a first call, chose the wrong count
        for as long as the next trial was away: on the smoke oedometer (300 spheres) a
        stage's first stretch on one thread measured 859 steps a second, and two threads,
        20 times slower than one there, stepped 10 s of a 19 s run."""
        self._rate.clear()
        self._stretch.clear()
        self._warm.clear()
        self._timed_at.clear()
        self._probe_every = PROBE_EVERY
        self._probe_at = self._stepped + PROBE_EVERY

    def advance(self, loop, bundles, stepping, step, stop, obs, obs_steps) -> tuple:
        """`loop(*bundles, stepping, step, stop, until, rows, steps)` from `step` to `stop` in
        stretches; returns as it does, its rows recorded in `obs`, `obs_steps`."""
        counts = self._counts(len(bundles[0].x))
        direction = 1 if stop > step else -1
        rows = 0
        while True:
            count, length = self._next(counts)
            until = step + direction * min(length, abs(stop - step))
            started = time.perf_counter()
            status, reached, recorded, finding = self._call(
                count, loop, *bundles, stepping, step, stop, until, obs[rows:],
                obs_steps[rows:],
            )  # fmt: skip
            self._learn(count, abs(reached - step), time.perf_counter() - started)
            numba.set_num_threads(self._best(counts))  # for this thread's own kernel calls
            step, rows = reached, rows + recorded
            if status != 0 or step == stop:
                return status, step, rows, finding

    @staticmethod
    def _counts(particles: int) -> tuple[int, ...]:
        """The thread counts worth timing: one, and the count in use where loops of this
        many particles run in parallel at all."""
        from revdem_cli.kernels import HEAVY, parallel_from

        most_now = _count or numba.get_num_threads()
        parallel = most_now > 1 and particles >= parallel_from[HEAVY]
        return (1, most_now) if parallel else (most_now,)

    def _next(self, counts: tuple[int, ...]) -> tuple[int, int]:
        """The thread count and the length in steps of the next stretch."""
        untimed = [count for count in counts if count not in self._rate]
        if untimed:
            return untimed[0], self._stretch.get(untimed[0], 1)
        best = self._best(counts)
        if len(counts) == 1:
            return best, self._stretch[best]
        other = next(count for count in counts if count != best)
        trial = max(1, int(self._rate[best] * PROBE))  # steps of PROBE seconds
        if self._stepped >= self._probe_at:
            self._probe_at = self._stepped + self._probe_every
            return other, trial
        if best != self._last and self._timed_at[best] < self._timed_at[other]:
            # chosen on an older rate than the one it beat (a stage whose steps grow
            # costlier, as a pour gains contacts, made the other's fresh rate the lower):
            # timed again first, not stepped for a stretch sized by that rate
            return best, min(self._stretch[best], trial)
        return best, self._stretch[best]

    def _best(self, counts: tuple[int, ...]) -> int:
        """The count of the fastest stepping timed so far (the largest before any)."""
        timed = [count for count in counts if count in self._rate]
        return max(timed, key=self._rate.get) if timed else counts[-1]

    def _learn(self, count: int, steps: int, seconds: float) -> None:
        """What a stretch took: the count's next length (at most four times the last), its
        rate, and the trials' schedule. A count's first stretch only warms it up (its first
        calls find their code and threads: at 256 spheres the first step on one thread took
        0.13 s against 0.05 ms for the next), and until a count has a rate, only a stretch
        of at least PROBE seconds (or half a PAUSE, if shorter) gives it one."""
        self.steps_with[count] = self.steps_with.get(count, 0) + steps
        self._stepped += seconds
        self._last = count
        if steps == 0:
            return
        rate = steps / max(seconds, 1e-9)
        self._stretch[count] = max(1, min(int(rate * PAUSE), 4 * self._stretch.get(count, 1)))
        if count not in self._warm:
            self._warm.add(count)
            return
        if count not in self._rate and seconds < min(PROBE, 0.5 * PAUSE):
            return
        was_best = max(self._rate, key=self._rate.get) if self._rate else count
        self._rate[count] = rate
        self._timed_at[count] = self._stepped
        if count != was_best:  # a trial: it won, or it waits twice as long for the next
            won = rate > self._rate[was_best]
            self._probe_every = PROBE_EVERY if won else min(2 * self._probe_every, PROBE_EVERY_MOST)

    @staticmethod
    def _call(count: int, loop, *args):
        numba.set_num_threads(count)
        return loop(*args)
