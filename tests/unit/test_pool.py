"""revdem's threads for numba's parallel regions (`kernels.pool`): the regions run on them
under any threading layer, each row as its own thread id, with the same results."""

import json
import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import llvmlite.binding as ll
import numba
import numpy as np
import pytest

from revdem_cli.kernels import count_now, pool, store_now, yield_core

ROOT = Path(__file__).resolve().parents[2]
TWO = numba.config.NUMBA_NUM_THREADS >= 2
needs_two = pytest.mark.skipif(not TWO, reason="needs NUMBA_NUM_THREADS >= 2")


KERNEL = """
import numba, numpy as np
from numba.np.ufunc.parallel import get_thread_id


@numba.njit(parallel=True)
def ids_and_sum(x, rows):
    ids = np.full(rows, -1)
    total = 0.0
    for r in numba.prange(rows):
        ids[r] = get_thread_id()
        for k in range(r * x.shape[0] // rows, (r + 1) * x.shape[0] // rows):
            total += x[k]
    return ids, total
"""
"""Each row's thread id, and a sum over x that numba reduces across the rows; compiled in
this process and in those of other layers alike."""

namespace: dict = {}
exec(KERNEL, namespace)
ids_and_sum = namespace["ids_and_sum"]


def test_numba_links_its_regions_to_the_pool():
    assert ll.address_of_symbol("numba_parallel_for") == pool.parallel_for.address
    assert ll.address_of_symbol("get_thread_id") == pool.thread_id.address
    assert pool.helpers() == numba.config.NUMBA_NUM_THREADS - 1


@needs_two
def test_each_row_runs_as_its_own_thread_id_and_reduces_in_row_order():
    """Row r runs as thread r whoever takes it, so numba combines the partial sums in row
    order: the sum is that of the two halves, each summed in order, added."""
    x = np.random.default_rng(7).random(100_001)
    numba.set_num_threads(2)
    ids, total = ids_and_sum(x, 2)
    assert ids.tolist() == [0, 1]
    half = x.shape[0] // 2
    assert total == sum_in_order(x[:half]) + sum_in_order(x[half:])


def sum_in_order(x):
    total = 0.0
    for value in x:
        total += value
    return total


@numba.njit(parallel=True)
def meet(flags, turns):
    """Each of two rows raises its flag, then waits (at most `turns` turns) for the other's;
    flags[2 + r]: whether row r saw it."""
    for r in numba.prange(2):
        store_now(flags, r, 1)
        for _ in range(turns):
            if count_now(flags, 1 - r) != 0:
                store_now(flags, 2 + r, 1)
                break
            yield_core()


@needs_two
def test_a_helper_takes_a_row_while_the_caller_runs_the_other():
    """Two rows that each wait for the other can only both see it if two threads run them
    at once: the caller and a helper."""
    numba.set_num_threads(2)
    flags = np.zeros(4, dtype=np.int64)
    meet(flags, 10_000_000)
    assert flags.tolist() == [1, 1, 1, 1]


OWN_ROWS = """
import ctypes, json, threading
import numba, numpy as np
from revdem_cli.kernels import count_now, pool, take, yield_core

pthread_self = ctypes.CDLL(None).pthread_self
pthread_self.restype = ctypes.c_ulong
pthread_self.argtypes = []
WAIT = 2_000_000  # turns of a row's wait, a sched_yield each: about a second


@numba.njit(parallel=True, nogil=True)
def rows_on(threads, started, together, rows):
    # each row notes the thread it runs on, then waits until every row has started, for at
    # most WAIT turns: a thread descheduled for longer (a busy machine) leaves its row to
    # another, and the region's rows did not all run at once (together[r] = 0). Without the
    # GIL, as revdem's kernels run: a helper still starting (in Python) needs it
    for r in numba.prange(rows):
        threads[r] = pthread_self()
        take(started, 0)
        for _ in range(WAIT):
            if count_now(started, 0) >= rows:
                together[r] = 1
                break
            yield_core()


def helper_of(ident):
    names = {threading.get_ident(): 0} | {h.ident: k + 1 for k, h in enumerate(pool._helpers)}
    return names.get(ident, -1)


seen = {}
for rows in (4, 2):
    numba.set_num_threads(rows)
    seen[rows] = []
    for _ in range(20):
        threads, started = np.zeros(rows, dtype=np.uint64), np.zeros(1, dtype=np.int64)
        together = np.zeros(rows, dtype=np.int64)
        rows_on(threads, started, together, rows)
        if together.all():
            seen[rows].append([helper_of(int(t)) for t in threads])
print(json.dumps(seen))
"""


def test_each_thread_runs_its_own_row_in_every_region():
    """Four threads of numba's pool (more than this machine may have cores: the rows give
    their core away as they wait): in each region whose rows all run at once, row r runs on
    thread r (0: the caller, k: helper k), on four threads and on two, where helpers 2 and
    3 take no row. So a chunk of the pair loop meets the caches it filled the step before."""
    env = os.environ | {"NUMBA_NUM_THREADS": "4"}
    done = subprocess.run(
        [sys.executable, "-c", OWN_ROWS], capture_output=True, text=True, env=env,
        timeout=300, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert min(len(seen["4"]), len(seen["2"])) >= 15, seen  # of 20: most regions
    assert all(rows == [0, 1, 2, 3] for rows in seen["4"]), seen
    assert all(rows == [0, 1] for rows in seen["2"]), seen


@needs_two
def test_the_jobs_count_round_modulo_two_to_the_31_and_helpers_follow():
    """The pool numbers its jobs in 31 bits; past the last number the count starts again at
    0, and a helper still takes its row."""
    numba.set_num_threads(2)
    pool._pool[pool.JOBS] = 2**31 - 2
    for _ in range(3):
        flags = np.zeros(4, dtype=np.int64)
        meet(flags, 10_000_000)
        assert flags.tolist() == [1, 1, 1, 1]
    assert pool._pool[pool.JOBS] == 1


@needs_two
def test_a_region_started_inside_another_runs_its_rows_in_the_calling_thread():
    """While the pool is busy (here: marked so), a region runs every row itself, each as its
    own thread id: the same ids and the same sum."""
    x = np.random.default_rng(8).random(10_001)
    numba.set_num_threads(2)
    alone = ids_and_sum(x, 2)
    pool._pool[pool.BUSY] = 1
    try:
        inside = ids_and_sum(x, 2)
    finally:
        pool._pool[pool.BUSY] = 0
    assert inside[0].tolist() == alone[0].tolist() == [0, 1]
    assert inside[1] == alone[1]


LAYER_RUN = """
import json, llvmlite.binding as ll
from revdem_cli.kernels import count_now, pool, store_now, yield_core
numba.set_num_threads(2)
ids, total = ids_and_sum(np.random.default_rng(9).random(200_003), 2)
print(json.dumps({"layer": numba.threading_layer(), "ids": ids.tolist(), "bits": total.hex(),
                  "pool": ll.address_of_symbol("numba_parallel_for") == pool.parallel_for.address}))
"""


@needs_two
@pytest.mark.parametrize("layer", ["omp", "workqueue", "tbb"])
def test_every_threading_layer_runs_the_regions_on_the_pool_with_the_same_bits(layer):
    """Whichever layer numba loads, the regions run on the pool, with the same row ids and
    the same sum to the bit, and the process ends cleanly (its helpers stop first)."""
    env = os.environ | {"NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": "2"}
    done = subprocess.run(
        [sys.executable, "-c", KERNEL + LAYER_RUN],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        cwd=ROOT,
    )
    if done.returncode != 0 and "No threading layer could be loaded" in done.stderr:
        pytest.skip(f"{layer} does not load here")
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    x = np.random.default_rng(9).random(200_003)
    numba.set_num_threads(2)
    assert result == {
        "layer": layer,
        "ids": [0, 1],
        "bits": ids_and_sum(x, 2)[1].hex(),
        "pool": True,
    }


def _region_in_child(queue):
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    queue.put((pool.helpers(), float(ids_and_sum(np.arange(1000.0), 2)[1])))


def test_a_forked_child_starts_its_own_helpers_and_runs_regions():
    """A child has none of its parent's threads: the pool starts afresh in it, and a region
    does not wait for helpers that are not there."""
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_region_in_child, args=(queue,))
    child.start()
    helpers, total = queue.get(timeout=120)
    child.join(timeout=60)
    assert child.exitcode == 0
    assert helpers == numba.config.NUMBA_NUM_THREADS - 1
    assert total == sum(range(1000))
