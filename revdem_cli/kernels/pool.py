"""revdem's own threads for numba's parallel regions, whatever threading layer numba loaded.

numba compiles each `prange` loop into a kernel over rows of a schedule, one row a thread,
and hands it to its threading layer's `parallel_for`. What a layer charges for a region
decides whether parallel loops pay at DEM sizes: about 1.5 us under OpenMP, whose threads
spin between regions; about 60 us under workqueue, whose threads sleep on a condition
variable; under TBB, which builds a task arena for each region, tens of microseconds at
first and milliseconds once a process has started some thousands. A step starts several.

So revdem runs the regions itself (`install`: the symbols numba's kernels link to,
`numba_parallel_for` and `get_thread_id`, are its own), on threads of its own that wait
for work by spinning, giving the core away at each turn (`sched_yield`, after POLLS
reads), and nap once they have been idle for a while (`IDLE_TURNS`). Row r is thread r's
own (the caller's row 0, helper k's row k): each thread claims its own row first, then any
row still unclaimed (one atomic step a row, `_claim`), and the region is over once every
row is done. So where every thread is running, row r runs on the same thread in every
region, and the pair arrays a chunk of the pair loop wrote stay in that core's caches for
the next region that reads them; a thread that is asleep, or descheduled on busy cores,
never holds a region up unless it claimed a row, for the others take its row once theirs
are done; with no helper awake the caller runs every row. Row r always runs as thread r
(`get_thread_id`, which a kernel's reductions index), so a reduction combines the same
partial results in the same order whichever thread ran each row, as the layers do.

numba's layer still keeps each thread's thread count (`numba.set_num_threads`), which
sizes the schedule. A region started while another is running (another Python thread's, or
from inside a row) runs its rows in the calling thread. A schedule with more rows than
threads (or than MOST_ROWS), or a kernel with more arguments than MOST_ARRAYS, goes to the
layer's own `parallel_for`; revdem's kernels have neither.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import threading

import llvmlite.binding as ll
import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from revdem_cli.kernels import (
    LIBC,
    count_now,
    external,
    jit,
    link_libc,
    store_now,
    swap_if,
    take,
    yield_core,
)

NEXT = 0  # (job << 32) | 0 once the job is posted, CLOSED while it is being posted; the job
# numbered modulo 2^31
DONE = 8  # rows of the current job done
BUSY = 16  # a job is in flight: taken by the thread that posts it
JOBS = 17  # jobs posted
FN, ARGS, DIMS, STEPS, DATA, INNER, ARRAYS, ROWS = range(18, 26)  # the job: numba's
# `parallel_for` arguments, and the rows of its schedule
LAYER = 26  # the address of the layer's own `parallel_for`
STOP = 27  # the helpers are to return (the process is ending)
CLAIMS = 32  # row r's claim: `open_in(job)` while nobody has claimed it in `job`, else the
# last job it was claimed in: MOST_ROWS words
MOST_ROWS = 256
"""Rows of a schedule the pool runs; one with more goes to the layer's `parallel_for`."""

WORDS = CLAIMS + MOST_ROWS
"""NEXT, which the helpers read while they wait, and DONE, which the caller reads, lie 64
bytes from each other and from the rest, and the claims start a cache line of their own, so
that none of them shares a line with the job's arguments: the caller's writes of a job would
otherwise take the line from under the helpers' reads."""

CLOSED = 1 << 31
"""NEXT's low word while a job's arguments are written."""

MOST_ARRAYS = 1024
"""Arguments of a kernel the pool runs (numba passes each array and scalar as one); a
kernel with more goes to the layer's `parallel_for`."""

MOST_DIMS = 64
"""Inner dimensions of a kernel the pool runs; one with more goes to the layer."""

POLLS = 100
"""Reads of a word a thread waits on between two turns (`sched_yield`): a thread that has a
core to itself sees a new job, or the last row done, within some nanoseconds, not after a
system call."""

IDLE_TURNS = 20_000
"""Turns a helper waits for work (POLLS reads and a `sched_yield` each, about 0.3-1 us)
before it naps."""

NAP_US = (100, 10_000)
"""A napping helper looks for work after this many microseconds, the first nap the shortest,
each twice the last up to the longest: a pool left idle wakes about a hundred times a
second, and the first region after the idle time does not wait for it."""

_pool = (ctypes.c_int64 * WORDS)()
_row_key = ctypes.c_uint32(0)
if LIBC.pthread_key_create(ctypes.byref(_row_key), None) != 0:
    raise OSError("pthread_key_create failed: no thread-local slot for the pool's row")
_key = ctypes.c_int64(_row_key.value)
ll.add_symbol("revdem_pool", ctypes.addressof(_pool))
ll.add_symbol("revdem_row_key", ctypes.addressof(_key))
link_libc("pthread_setspecific", "pthread_getspecific", "usleep")


@intrinsic
def pool_words(typingctx):
    """The pool's control words (`_pool`), as a pointer compiled code reads through the
    symbol it is registered under."""

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        words = external(builder, "revdem_pool", ir.ArrayType(i64, WORDS))
        return builder.gep(words, [ir.Constant(i64, 0), ir.Constant(i64, 0)])

    return types.CPointer(types.int64)(), codegen


@intrinsic
def words_at(typingctx, address):
    """The int64 words from `address` on, as a pointer (`numba.carray` views them)."""

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.PointerType(ir.IntType(64)))

    return types.CPointer(types.int64)(address), codegen


@intrinsic
def address_of(typingctx, pointer):
    """A pointer's address, as an int64."""

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], ir.IntType(64))

    return types.int64(pointer), codegen


@intrinsic
def scratch_words(typingctx):
    """MOST_ARRAYS + MOST_DIMS int64 words on the calling function's stack."""

    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(builder, ir.IntType(64), size=MOST_ARRAYS + MOST_DIMS)

    return types.CPointer(types.int64)(), codegen


@intrinsic
def run_kernel(typingctx, fn, args, dims, steps, data):
    """fn(args, dims, steps, data): a kernel numba built for a parallel region, called
    through its address."""

    def codegen(context, builder, signature, arguments):
        byte_ptr = ir.PointerType(ir.IntType(8))
        i64_ptr = ir.PointerType(ir.IntType(64))
        targets = (ir.PointerType(byte_ptr), i64_ptr, i64_ptr, byte_ptr)
        kind = ir.FunctionType(ir.VoidType(), targets)
        kernel = builder.inttoptr(arguments[0], ir.PointerType(kind))
        pointers = [builder.inttoptr(a, t) for a, t in zip(arguments[1:], targets, strict=True)]
        builder.call(kernel, pointers)
        return context.get_dummy_value()

    return types.none(fn, args, dims, steps, data), codegen


@intrinsic
def run_layer(typingctx, fn, args, dims, steps, data, inner, arrays, threads):
    """The layer's own `parallel_for` (its address in the pool's LAYER word) with these
    arguments."""

    def codegen(context, builder, signature, arguments):
        byte_ptr = ir.PointerType(ir.IntType(8))
        i64 = ir.IntType(64)
        kind = ir.FunctionType(ir.VoidType(), [byte_ptr] * 5 + [i64] * 3)
        words = external(builder, "revdem_pool", ir.ArrayType(i64, WORDS))
        at = builder.gep(words, [ir.Constant(i64, 0), ir.Constant(i64, LAYER)])
        layer = builder.inttoptr(builder.load(at), ir.PointerType(kind))
        pointers = [builder.inttoptr(a, byte_ptr) for a in arguments[:5]]
        builder.call(layer, pointers + list(arguments[5:]))
        return context.get_dummy_value()

    return types.none(fn, args, dims, steps, data, inner, arrays, threads), codegen


def _key_of(builder):
    key = external(builder, "revdem_row_key", ir.IntType(64))
    return builder.trunc(builder.load(key), ir.IntType(32))


@intrinsic
def set_row(typingctx, row):
    """The calling thread's row (`get_thread_id`), in its thread-local slot."""

    def codegen(context, builder, signature, args):
        byte_ptr = ir.PointerType(ir.IntType(8))
        kind = ir.FunctionType(ir.IntType(32), [ir.IntType(32), byte_ptr])
        call = cgutils.get_or_insert_function(builder.module, kind, "pthread_setspecific")
        builder.call(call, [_key_of(builder), builder.inttoptr(args[0], byte_ptr)])
        return context.get_dummy_value()

    return types.none(row), codegen


@intrinsic
def row_now(typingctx):
    """The calling thread's row: 0 outside the pool's regions."""

    def codegen(context, builder, signature, args):
        byte_ptr = ir.PointerType(ir.IntType(8))
        kind = ir.FunctionType(byte_ptr, [ir.IntType(32)])
        call = cgutils.get_or_insert_function(builder.module, kind, "pthread_getspecific")
        return builder.ptrtoint(builder.call(call, [_key_of(builder)]), ir.IntType(64))

    return types.int64(), codegen


@intrinsic
def nap(typingctx, microseconds):
    """usleep(3)."""

    def codegen(context, builder, signature, args):
        kind = ir.FunctionType(ir.IntType(32), [ir.IntType(32)])
        call = cgutils.get_or_insert_function(builder.module, kind, "usleep")
        builder.call(call, [builder.trunc(args[0], ir.IntType(32))])
        return context.get_dummy_value()

    return types.none(microseconds), codegen


@jit
def _run_row(fn, args, dims, steps, data, inner, arrays, row):
    """Row `row` of a job's schedule in the calling thread, as thread `row`: each argument
    moved on by its outer step `row` times (only the schedule's is not zero), the outer
    dimension one row."""
    scratch = numba.carray(scratch_words(), MOST_ARRAYS + MOST_DIMS)
    moved, shape = scratch[:MOST_ARRAYS], scratch[MOST_ARRAYS:]
    given = numba.carray(words_at(args), arrays)
    step = numba.carray(words_at(steps), arrays)
    for j in range(arrays):
        moved[j] = given[j] + step[j] * row
    outer = numba.carray(words_at(dims), inner + 1)
    shape[0] = 1
    for j in range(1, inner + 1):
        shape[j] = outer[j]
    set_row(row)
    run_kernel(fn, moved.ctypes.data, shape.ctypes.data, steps, data)


@jit
def open_in(job):
    """A row's claim while it is open in job `job` (negative: no job's number). Every row a
    job opens is claimed before the job is over, so only the current job's rows are ever
    open, and a thread that read an earlier job's number can claim nothing."""
    return -job - 1


@jit
def _claim(pool, job, row):
    """Whether the calling thread claims row `row` of job `job`: it was open, and is now
    the caller's, as one atomic step."""
    return swap_if(pool, CLAIMS + row, open_in(job), job)


@jit
def _work(pool, job, own):
    """Claim and run rows of job `job`: the calling thread's own row `own` first, where the
    job has it, then each other row still open, from own + 1 on round to own - 1. A thread
    without a row of its own in the job (own >= its rows) takes none: the threads that have
    one take what is left. Returns whether the job has a row of the thread's own."""
    fn, args, dims, steps, data = pool[FN], pool[ARGS], pool[DIMS], pool[STEPS], pool[DATA]
    inner, arrays = pool[INNER], pool[ARRAYS]
    rows = pool[ROWS]  # a later job's where `job` is over: then no row is open in `job`
    if own >= rows:
        return False
    for turn in range(rows):
        row = (own + turn) % rows
        if _claim(pool, job, row):
            _run_row(fn, args, dims, steps, data, inner, arrays, row)
            take(pool, DONE)
    return True


@jit
def _serve(own):
    """A helper's life, row `own` its own: wait for a job, claim its rows (`_work`), and
    again, until the pool stops. Jobs without a row of its own (a run on fewer threads than
    numba's pool) leave it idle, so that it naps: it does not spin on a core the run was
    not given."""
    pool = numba.carray(pool_words(), WORDS)
    served = count_now(pool, NEXT) >> 32
    idle = 0
    sleep = NAP_US[0]
    while True:
        now = _next_job(pool, served)
        if now < 0:
            if count_now(pool, STOP) != 0:
                return
            idle += 1
            if idle < IDLE_TURNS:
                yield_core()
            else:
                nap(sleep)
                sleep = min(2 * sleep, NAP_US[1])
            continue
        served = now >> 32
        # a job's arguments are read after its NEXT and checked by the row's claim: they
        # are rewritten only once every row of the job is done, which this row is not
        if _work(pool, served, own):
            idle = 0
            sleep = NAP_US[0]


@jit
def _next_job(pool, served):
    """NEXT, where within POLLS reads it shows an open job other than `served`; else -1."""
    for _ in range(POLLS):
        now = count_now(pool, NEXT)
        if now >> 32 != served and now & (CLOSED * 2 - 1) < CLOSED:
            return now
    return -1


@jit
def _all_done(pool, rows):
    """Whether DONE reaches `rows` within POLLS reads."""
    for _ in range(POLLS):
        if count_now(pool, DONE) >= rows:
            return True
    return False


@numba.cfunc(
    types.void(
        types.voidptr,
        types.voidptr,
        types.voidptr,
        types.voidptr,
        types.voidptr,
        types.intp,
        types.intp,
        types.intp,
    ),  # fmt: skip
    nopython=True,
    cache=True,
)
def parallel_for(fn, args, dims, steps, data, inner, arrays, threads):
    """numba's `parallel_for`, on the pool: the rows of the schedule (the outer dimension of
    `dims`) claimed by the calling thread and the helpers, each its own row first, each row
    run as its own thread id."""
    pool = numba.carray(pool_words(), WORDS)
    fn_at, args_at, dims_at = address_of(fn), address_of(args), address_of(dims)
    steps_at, data_at = address_of(steps), address_of(data)
    rows = numba.carray(words_at(dims_at), 1)[0]
    if rows > min(threads, MOST_ROWS) or arrays > MOST_ARRAYS or inner >= MOST_DIMS:
        run_layer(fn_at, args_at, dims_at, steps_at, data_at, inner, arrays, threads)
        return
    if rows < 2 or not swap_if(pool, BUSY, 0, 1):  # alone, or inside another region
        caller = row_now()
        for row in range(rows):
            _run_row(fn_at, args_at, dims_at, steps_at, data_at, inner, arrays, row)
        set_row(caller)
        return
    job = (pool[JOBS] + 1) & (CLOSED - 1)  # 31 bits, so that NEXT stays positive
    pool[JOBS] = job
    store_now(pool, NEXT, (job << 32) | CLOSED)
    pool[FN], pool[ARGS], pool[DIMS], pool[STEPS], pool[DATA] = (
        fn_at, args_at, dims_at, steps_at, data_at,
    )  # fmt: skip
    pool[INNER], pool[ARRAYS], pool[ROWS] = inner, arrays, rows
    store_now(pool, DONE, 0)
    for row in range(rows):
        store_now(pool, CLAIMS + row, open_in(job))
    store_now(pool, NEXT, job << 32)  # posted: helpers may claim rows
    _work(pool, job, np.int64(0))  # row 0, the caller's own
    while not _all_done(pool, rows):  # rows the helpers took
        yield_core()
    set_row(0)
    store_now(pool, BUSY, 0)


@numba.cfunc(types.intp(), nopython=True, cache=True)
def thread_id():
    """numba's `get_thread_id` on the pool: the row the calling thread runs."""
    return row_now()


_helpers: list[threading.Thread] = []


def _start_helpers() -> None:
    """One helper thread for each thread of numba's pool but the caller's."""
    _helpers.clear()
    for k in range(numba.config.NUMBA_NUM_THREADS - 1):
        helper = threading.Thread(
            target=_serve, args=(k + 1,), name=f"revdem-pool-{k + 1}", daemon=True
        )
        helper.start()
        _helpers.append(helper)


def install() -> None:
    """Run numba's parallel regions on the pool from here on: the kernels compiled or loaded
    after this link to its `parallel_for` and `get_thread_id`."""
    if _pool[LAYER]:
        return
    numba.get_num_threads()  # the layer first: its symbols, which these replace
    _pool[LAYER] = ll.address_of_symbol("numba_parallel_for")
    ll.add_symbol("numba_parallel_for", parallel_for.address)
    ll.add_symbol("get_thread_id", thread_id.address)
    _start_helpers()
    os.register_at_fork(after_in_child=_after_fork)
    atexit.register(_stop)


def _stop() -> None:
    """The helpers returned before the interpreter ends: a thread still in compiled code as
    it frees the compiled code's memory would run into freed pages."""
    _pool[STOP] = 1
    for helper in _helpers:
        helper.join(timeout=1.0 + NAP_US[1] * 1e-6)


def _after_fork() -> None:
    """A forked child has none of its parent's threads: the pool starts afresh."""
    for k in range(WORDS):
        if k != LAYER:
            _pool[k] = 0
    _start_helpers()


def helpers() -> int:
    """Helper threads alive."""
    return sum(helper.is_alive() for helper in _helpers)
