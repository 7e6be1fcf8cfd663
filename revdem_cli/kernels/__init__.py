"""Compiled kernels: small pure functions over arrays. Nothing here imports config, io or cli.

JIT flags live here, in one place. `fastmath` stays off everywhere: it reorders arithmetic
and would break the reversibility that is the point of revdem. Compiled code is cached on
disk, where `revdem_cli.kernel_cache` says, which is imported before anything compiles.
"""

import ctypes
import math
import os
import time
import types
from functools import partial

import llvmlite.binding as ll
import numba
from llvmlite import ir
from numba.core import cgutils
from numba.extending import intrinsic

from revdem_cli import kernel_cache  # noqa: F401  (where the compiled code is cached)

LAYERS = ("omp", "workqueue", "tbb")
"""numba's threading layers in the order revdem takes the first that loads. revdem's kernels
run their parallel regions on revdem's own threads whatever the layer (`pool`); the layer
keeps each thread's thread count (`numba.set_num_threads`) and cuts a region's schedule.
An environment that names a layer or an order (NUMBA_THREADING_LAYER,
NUMBA_THREADING_LAYER_PRIORITY) is the user's choice, and kept."""

if os.environ.get("NUMBA_THREADING_LAYER", "default").lower() == "default" and not os.environ.get(
    "NUMBA_THREADING_LAYER_PRIORITY"
):
    numba.config.THREADING_LAYER_PRIORITY = list(LAYERS)
try:  # loads the layer now: compiled code (`threads_here`) links to it
    numba.get_num_threads()
except ValueError as exc:  # a layer numba does not know, or cannot load
    from revdem_cli.errors import InputError

    chosen = os.environ.get("NUMBA_THREADING_LAYER") or os.environ.get(
        "NUMBA_THREADING_LAYER_PRIORITY"
    )
    raise InputError(f"NUMBA_THREADING_LAYER {chosen}: {' '.join(str(exc).split())}") from None

jit = partial(numba.njit, cache=True, fastmath=False, error_model="numpy", nogil=True)
"""Serial compiled function. It runs without the GIL, so that while the main thread steps,
the thread that watches for signals can set the loop's halt flag (`checkpoint.watching`)."""

inline = partial(numba.njit, cache=True, fastmath=False, error_model="numpy", forceinline=True)
"""Serial compiled helper over scalars and tuples, always inlined into its callers (LLVM's
alwaysinline): a loop over a block of pairs that calls it stays one loop body, which LLVM
can vectorise."""

inline_arrays = partial(
    numba.njit, cache=True, fastmath=False, error_model="numpy", inline="always"
)
"""Compiled helper that takes arrays, inlined by numba itself before compiling its caller:
an LLVM-inlined call (`inline`) still takes and gives back a reference to each array it is
passed, which numba does not prune where the helper branches; in a loop over entries that
costs more than the work (the information tape's `_apply`: 6 ms a step of 91 000 entries).
Also a function called from compiled code alone, to spare a level of compilation:
numba links each callee's code into its caller and compiles all of it again (`integrate`'s
steps)."""

pjit = partial(
    numba.njit, cache=True, fastmath=False, error_model="numpy", parallel=True, nogil=True
)
"""Compiled function with `numba.prange` loops; each iteration writes only its own slot."""


def renamed(function, name, **constants):
    """A copy of `function` under its own name, with `constants` in place of globals of
    its module (numba compiles globals as constants). numba's disk cache is keyed by the
    function's name, and would otherwise hand one copy's code to the other. With
    `constants`, the copy sees its module's globals as they are when this is called: call
    it after everything the function uses is defined."""
    twin = types.FunctionType(
        function.__code__,
        {**function.__globals__, **constants} if constants else function.__globals__,
        name,
        function.__defaults__,
        function.__closure__,
    )
    twin.__qualname__ = function.__qualname__.replace(function.__name__, name)
    twin.__doc__ = function.__doc__
    return twin


LIGHT, HEAVY = 0, 1
"""A loop's weight: a few flops a particle (a half kick, a drift, the largest reach), or tens
of nanoseconds and more (the pair loop, the walls, the neighbour search)."""

NEVER = 2**62
"""A crossover no system reaches."""

CROSSOVERS = (864, 256)
"""Particles from which a loop's parallel build pays on two threads, (LIGHT, HEAVY): what a
parallel region costs on revdem's threads (`pool`: about 0.5 us, under any threading layer)
against the half of the loop it saves. Measured on a 2-core AMD EPYC in the fcc step with
history (`benchmarks/crossover.py`, the same under omp, workqueue and tbb): heavy, from
where two threads step faster than one; light, from where the light loops in parallel step
faster than serially, which they do for the sake of the loops after them (a thread's
particles stay in its core's cache), never below the heavy loops'."""

parallel_from = (ctypes.c_int64 * 2)(*CROSSOVERS)
"""The crossovers, which compiled code reads at each call (`threads_for`). Lowering them
runs the parallel builds of small systems (the thread-count tests do)."""
ll.add_symbol("revdem_parallel_from", ctypes.addressof(parallel_from))

SERIAL = PARALLEL = FROM = LEAST = None  # the globals `_by_size` sees as constants in each copy


def _by_size(n, *args):
    if n >= LEAST and threads_for(n, FROM) > 1:
        return PARALLEL(*args)
    return SERIAL(*args)


def by_size(loop, weight=HEAVY, least=0, **serial_constants):
    """One compiled entry to a `prange` loop of the given `weight`, called as f(n, *args): its
    parallel build for n items from the weight's crossover (`parallel_from`) and `least` on
    when the calling thread computes with more than one thread (`revdem_cli.threads`), its
    serial build otherwise (`threads_for`, which `by_parts` asks too); the serial build sees
    `serial_constants` in place of its module's globals (`renamed`; `one_thread`)."""
    name = loop.__name__.lstrip("_")
    serial = jit(renamed(loop, name + "_serial", **serial_constants))
    parallel = pjit(renamed(loop, name + "_parallel"))
    constants = dict(SERIAL=serial, PARALLEL=parallel, FROM=weight, LEAST=least)
    return jit(renamed(_by_size, name, **constants))


PART = None  # the global `_in_parts` and `_over_parts` see as a constant in each copy


def _over_parts(parts, *args):
    items = args[0].shape[0]
    out = 0
    last = -1
    for c in numba.prange(parts):
        counted, at = PART(c * items // parts, (c + 1) * items // parts, *args)
        out += counted
        last = max(last, at)
    return out, last


def _in_parts(n, *args):
    parts = threads_for(n, FROM)
    if parts > 1:
        return PARALLEL(parts, *args)
    return PART(0, args[0].shape[0], *args)


def by_parts(part, weight=HEAVY):
    """One compiled entry to a loop of the given `weight` over the items of its first array,
    each item on its own, written over a range of them: part(begin, end, *args) -> (items
    that left their range, the last of them or -1). Called as f(n, *args), n the particles:
    from the weight's crossover on with more than one thread (`threads_for`, as `by_size`
    chooses) the items are cut into one contiguous part a thread, each run by the serial
    build, else all at once. A `prange` over single items is not vectorised by LLVM where it
    counts and keeps its reductions (the fixed-point drift at n = 24 fcc: 4.0-6.1 ns a sphere
    on two threads, against 2.5 on one); each part is."""
    name = part.__name__.lstrip("_")
    serial = jit(part)
    parallel = pjit(renamed(_over_parts, name + "_parallel", PART=serial))
    return jit(renamed(_in_parts, name, PART=serial, PARALLEL=parallel, FROM=weight))


NUMBER = CHOSEN = OTHERS = None  # the globals each link of a `choice` sees as constants


def _pick(which, *args):
    if which == NUMBER:
        return CHOSEN(*args)
    return OTHERS(which, *args)


def _last(which, *args):
    return CHOSEN(*args)


def _nothing(which, *args):
    return math.nan


def choice(functions, name):
    """One compiled function that calls functions[number - 1], f(number, *args): a chain of
    comparisons, each link `renamed` (`name` and its place) and inlined into its caller, so
    that a registry of laws or shapes needs no hand-written dispatch. The last function takes
    every number the chain did not (the registries' validation admits no other); with no
    functions it returns NaN."""
    chain = None
    for k in range(len(functions), 0, -1):
        link = f"{name}_from_{k}"
        if chain is None:
            chain = inline(renamed(_last, link, CHOSEN=functions[k - 1]))
        else:
            constants = dict(NUMBER=k, CHOSEN=functions[k - 1], OTHERS=chain)
            chain = inline(renamed(_pick, link, **constants))
    return chain or inline(renamed(_nothing, f"{name}_of_nothing"))


@intrinsic
def threads_here(typingctx):
    """The thread count of the calling thread (`numba.set_num_threads`), read from the
    threading layer's own `get_num_threads`, linked by name as numba's parallel loops link
    it; `numba.get_num_threads()` in compiled code holds a ctypes pointer, which numba
    cannot cache."""

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        get = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, []), "get_num_threads"
        )
        return builder.sext(builder.call(get, []), context.get_value_type(numba.types.intp))

    return numba.types.intp(), codegen


def external(builder, name, kind):
    """The global `name` of LLVM type `kind` that compiled code reads through the symbol it
    is registered under (`ll.add_symbol`), declared in the module being built."""
    variable = builder.module.globals.get(name)
    if variable is None:
        variable = ir.GlobalVariable(builder.module, kind, name)
        variable.linkage = "external"
    return variable


@intrinsic
def crossover(typingctx, weight):
    """The particles from which a loop of `weight` runs in parallel: its entry of
    `parallel_from`, read through the symbol it is registered under, as `threads_here` reads
    the layer's thread count."""

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        table = external(builder, "revdem_parallel_from", ir.ArrayType(i64, 2))
        return builder.load(builder.gep(table, [ir.Constant(i64, 0), args[0]]))

    return numba.types.int64(weight), codegen


def _word(context, builder, signature, args):
    """The address of words[k] (an int64 array, k an integer)."""
    kind = signature.args[0]
    array = context.make_array(kind)(context, builder, args[0])
    k = context.cast(builder, args[1], signature.args[1], numba.types.intp)
    return cgutils.get_item_pointer(context, builder, kind, array, [k])


@intrinsic
def take(typingctx, words, k):
    """words[k] += 1 as one atomic step (sequentially consistent: what the calling thread
    wrote before is seen by whoever reads the count after), returning the count before."""

    def codegen(context, builder, signature, args):
        at = _word(context, builder, signature, args)
        return builder.atomic_rmw("add", at, ir.Constant(ir.IntType(64), 1), "seq_cst")

    return numba.types.int64(words, k), codegen


@intrinsic
def count_now(typingctx, words, k):
    """words[k], read as one atomic step (sequentially consistent: what was written before
    the word was last written is seen after it is read)."""

    def codegen(context, builder, signature, args):
        return builder.load_atomic(_word(context, builder, signature, args), "seq_cst", 8)

    return numba.types.int64(words, k), codegen


@intrinsic
def store_now(typingctx, words, k, value):
    """words[k] = value as one atomic step (sequentially consistent)."""

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[2], signature.args[2], numba.types.int64)
        builder.store_atomic(value, _word(context, builder, signature, args), "seq_cst", 8)
        return context.get_dummy_value()

    return numba.types.none(words, k, value), codegen


@intrinsic
def swap_if(typingctx, words, k, expected, value):
    """words[k] = value where it is `expected`, as one atomic step (sequentially
    consistent); whether it was."""

    def codegen(context, builder, signature, args):
        at = _word(context, builder, signature, args)
        return builder.extract_value(builder.cmpxchg(at, args[2], args[3], "seq_cst", "seq_cst"), 1)

    return numba.types.boolean(words, k, expected, value), codegen


LIBC = ctypes.CDLL(None)


def link_libc(*names):
    """The C library's functions `names`, registered for compiled code to call by name."""
    for name in names:
        ll.add_symbol(name, ctypes.cast(getattr(LIBC, name), ctypes.c_void_p).value)


link_libc("sched_yield", "clock_gettime")


@intrinsic
def yield_core(typingctx):
    """sched_yield(2): the core to another thread that is ready, if one is."""

    def codegen(context, builder, signature, args):
        kind = ir.FunctionType(ir.IntType(32), [])
        builder.call(cgutils.get_or_insert_function(builder.module, kind, "sched_yield"), [])
        return context.get_dummy_value()

    return numba.types.none(), codegen


@intrinsic
def clock_ns(typingctx):
    """Nanoseconds on the monotonic clock (clock_gettime(2), CLOCK_MONOTONIC): how long a
    thread's part of a loop took, to share out the next call's by (`pairs.balanced`)."""

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        spec = cgutils.alloca_once(builder, ir.LiteralStructType([i64, i64]))  # timespec
        kind = ir.FunctionType(ir.IntType(32), [ir.IntType(32), spec.type])
        call = cgutils.get_or_insert_function(builder.module, kind, "clock_gettime")
        builder.call(call, [ir.Constant(ir.IntType(32), time.CLOCK_MONOTONIC), spec])
        seconds = builder.load(cgutils.gep_inbounds(builder, spec, 0, 0))
        nanoseconds = builder.load(cgutils.gep_inbounds(builder, spec, 0, 1))
        return builder.add(builder.mul(seconds, ir.Constant(i64, 10**9)), nanoseconds)

    return numba.types.int64(), codegen


@inline
def threads_for(n, weight):
    """The threads a loop of `weight` over n items computes with: those of the calling thread
    (`threads_here`) from the weight's crossover on, one below; the one place `by_size` and
    `by_parts` choose."""
    return threads_here() if n >= crossover(weight) else 1


@inline
def one_thread(n, weight):
    """`threads_for` as a serial build sees it (`by_size`'s serial constants): one thread, a
    constant, so that the build's code for more folds away."""
    return 1


from revdem_cli.kernels import pool  # noqa: E402  (needs the helpers above)

pool.install()
