"""Compiled kernels: small pure functions over arrays. Nothing here imports config, io or cli.

JIT flags live here, in one place. `fastmath` stays off everywhere: it reorders arithmetic
and would break the reversibility that is the point of revdem.
"""

from functools import partial

import numba

jit = partial(numba.njit, cache=True, fastmath=False, error_model="numpy")
"""Serial compiled function."""

pjit = partial(numba.njit, cache=True, fastmath=False, error_model="numpy", parallel=True)
"""Compiled function with `numba.prange` loops; each iteration writes only its own slot."""
