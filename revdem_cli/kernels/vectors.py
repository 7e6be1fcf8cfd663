"""3-tuples and rows of arrays: the vector algebra every kernel shares."""

import math

import numpy as np

from revdem_cli.kernels import inline, jit

ZERO = (0.0, 0.0, 0.0)


@inline
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inline
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@inline
def axpy(s, a, b):
    """s a + b."""
    return (s * a[0] + b[0], s * a[1] + b[1], s * a[2] + b[2])


@inline
def scaled(s, a):
    return (s * a[0], s * a[1], s * a[2])


@inline
def norm(a):
    return math.sqrt(dot(a, a))


@inline
def sign(a):
    """1, -1 or 0 (0 for NaN) without a branch: a branch on the sign of a velocity component
    is mispredicted half the time (local damping's sign(v) made the gather 1.6 times
    slower, n = 24 fcc)."""
    return np.float64(a > 0.0) - np.float64(a < 0.0)


@inline
def row(a, k):
    """Row k of an (n, 3) array as a 3-tuple."""
    return (a[k, 0], a[k, 1], a[k, 2])


@inline
def put(a, k, vector):
    a[k, 0], a[k, 1], a[k, 2] = vector


@jit
def cell_of(a, q, b):
    """Entry (q, b) of an (n, m, 3) array as a 3-tuple."""
    return (a[q, b, 0], a[q, b, 1], a[q, b, 2])


@jit
def place(a, q, b, vector):
    a[q, b, 0], a[q, b, 1], a[q, b, 2] = vector
