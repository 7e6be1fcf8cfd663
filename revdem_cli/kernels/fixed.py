"""Fixed-point arithmetic: positions, velocities and angular velocities (and the edges of a
cell driven by the inertial servo) held as 64-bit integers on fixed grids.

Every kick and drift adds an integer increment, the floating-point increment divided by
the grid step and rounded half away from zero: round(-y) = -round(y) exactly, so the
reversed step, which adds the increment of -dt, subtracts exactly what the forward step
added (Levesque & Verlet 1993; Hanley 2020 §3.2 mentions it). Forces are computed in
floating point from the state the integers give, a deterministic function of them, and
each sphere's contact forces are summed as integers on a force grid, so the sum does not
depend on the order of its terms. The floating-point arrays the force loops read (x, v,
omega, the cell's edges) are refreshed from the integers after every update.

A value that would leave the range of the grid (|n| > RANGE) is not wrapped: the update
is counted in `overflow` and the stepping loop stops with an error naming it.
"""

import math

import numba
import numpy as np

from revdem_cli.kernels import jit, serial_and_parallel

RANGE = 2**62 - 1
"""Largest magnitude of a value on a grid, in grid steps: the sum of two such values still
fits in int64, so a step past the range is detected before anything wraps around."""

X, Y, Z, VELOCITY, ANGULAR_VELOCITY, FORCE, TORQUE, EDGE, EDGE_RATE = range(9)
"""Entries of a grid array: the position step of each axis (m; in a deforming cell, of the
cell coordinate), then the steps of velocity (m/s), angular velocity (rad/s), contact force
(N), moment (N m), cell edge (m) and edge rate (m/s)."""

QUANTITIES = ("position", "velocity", "angular_velocity", "force", "moment", "cell edge")
"""What an overflow names: fixed.overflow[0] is 1 + the index of one of these."""
OF_POSITION, OF_VELOCITY, OF_ANGULAR_VELOCITY, OF_FORCE, OF_MOMENT, OF_CELL = range(6)


@jit
def rounded(y):
    """y rounded half away from zero, as a float: exactly odd, rounded(-y) = -rounded(y)."""
    return np.trunc(y + math.copysign(0.5, y))


@jit
def in_range(n):
    return abs(n) <= RANGE


def _kick(n, mirror, f, inv_m, h, step):
    """n += round(h f / m / step), mirror = n step: a half kick on the grid. Returns (values
    out of range, the last particle with one)."""
    out = 0
    last = -1
    per_step = 1.0 / step  # grid steps are powers of two: multiplying divides exactly
    for q in numba.prange(n.shape[0]):
        bad = False
        for d in range(3):
            increment = rounded(h * f[q, d] * inv_m[q] * per_step)
            value = n[q, d] + np.int64(increment) if abs(increment) <= RANGE else n[q, d]
            bad = bad or not (abs(increment) <= RANGE and in_range(value))
            n[q, d] = value
            mirror[q, d] = value * step
        if bad:
            out += 1
            last = max(last, q)
    return out, last


def _drift(n, v, h, step, mid, in_cell):
    """n += round(h v / step) on the grid of each axis; in a deforming cell the grid is of the
    cell coordinate, n += round(h v / (step L_mid)) with L_mid the edges halfway through the
    step. Returns as `_kick`."""
    out = 0
    last = -1
    for q in numba.prange(n.shape[0]):
        bad = False
        for d in range(3):
            size = step[d] * mid[d] if in_cell else step[d]
            increment = rounded(h * v[q, d] / size)
            value = n[q, d] + np.int64(increment) if abs(increment) <= RANGE else n[q, d]
            bad = bad or not (abs(increment) <= RANGE and in_range(value))
            n[q, d] = value
        if bad:
            out += 1
            last = max(last, q)
    return out, last


def _mirror_positions(n, x, s, step, length):
    """x = n step, or in a deforming cell (s given) s = n step and x = s L: the positions
    the integers give."""
    in_cell = s.shape[0] > 0
    for q in numba.prange(n.shape[0]):
        for d in range(3):
            if in_cell:
                s[q, d] = n[q, d] * step[d]
                x[q, d] = s[q, d] * length[d]
            else:
                x[q, d] = n[q, d] * step[d]


kick_serial, kick_parallel = serial_and_parallel(_kick)
drift_serial, drift_parallel = serial_and_parallel(_drift)
mirror_serial, mirror_parallel = serial_and_parallel(_mirror_positions)


@jit
def note_overflow(fixed, quantity, counts):
    """Remember the first update that left its grid: (quantity, particle)."""
    out, last = counts
    if out > 0 and fixed.overflow[0] == 0:
        fixed.overflow[0] = 1 + quantity
        fixed.overflow[1] = last


@jit
def on_grid(value, step):
    """A floating-point value's nearest grid point, as an integer (of a value in range)."""
    return np.int64(rounded(value / step))
