"""Compiled kernels: small pure functions over arrays. Nothing here imports config, io or cli.

JIT flags live here, in one place. `fastmath` stays off everywhere: it reorders arithmetic
and would break the reversibility that is the point of revdem.

Compiled code is cached on disk. numba invalidates a cached function only when its own file
changes, yet a caller's cache holds the compiled code of the functions it calls from other
files; so the cache directory is keyed by a hash of every kernel source file, and any change
to any kernel starts a fresh cache.
"""

import hashlib
import os
import types
from functools import partial
from pathlib import Path

import numba


def _cache_dir() -> str:
    sources = sorted(Path(__file__).parent.glob("*.py"))
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()[:16]
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "revdem", "numba"
    )
    return os.path.join(base, f"{numba.__version__}-{digest}")


numba.config.CACHE_DIR = _cache_dir()

jit = partial(numba.njit, cache=True, fastmath=False, error_model="numpy")
"""Serial compiled function."""

inline = partial(numba.njit, cache=True, fastmath=False, error_model="numpy", forceinline=True)
"""Serial compiled helper over scalars and tuples, always inlined into its callers (LLVM's
alwaysinline): a loop over a block of pairs that calls it stays one loop body, which LLVM
can vectorise."""

pjit = partial(numba.njit, cache=True, fastmath=False, error_model="numpy", parallel=True)
"""Compiled function with `numba.prange` loops; each iteration writes only its own slot."""


def serial_and_parallel(loop):
    """A serial and a parallel build of one `prange` loop.

    The parallel build is compiled from a copy with its own name: numba's disk cache is
    keyed by the function's name, and would otherwise hand one build's code to the other.
    """
    twin = types.FunctionType(
        loop.__code__,
        loop.__globals__,
        loop.__name__ + "_parallel",
        loop.__defaults__,
        loop.__closure__,
    )
    twin.__qualname__ = loop.__qualname__ + "_parallel"
    twin.__doc__ = loop.__doc__
    return jit(loop), pjit(twin)
