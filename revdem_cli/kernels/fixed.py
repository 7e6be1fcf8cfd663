"""Fixed-point arithmetic: positions, velocities and angular velocities (and the edges of a
cell driven by the inertial servo) held as 64-bit integers on fixed grids.

Every kick and drift adds an integer increment, the floating-point increment divided by
the grid step and rounded half away from zero: round(-y) = -round(y) exactly, so the
reversed step, which adds the increment of -dt, subtracts exactly what the forward step
added (Levesque & Verlet 1993; Hanley 2020 §3.2 mentions it). Forces are computed in
floating point from the state the integers give, a deterministic function of them, and
each sphere's contact forces are summed on a force grid to their integer sum (in doubles
where every partial sum is an integer a double holds, `sum_exact`), so the sum does not
depend on the order of its terms. The floating-point arrays the force loops read (x, v,
omega, the cell's edges) are refreshed from the integers after every update.

A value that would leave the range of the grid (|n| > RANGE) is not wrapped: the update
is counted in `overflow` and the stepping loop stops with an error naming it.
"""

import math

import numba
import numpy as np

from revdem_cli.kernels import LIGHT, by_parts, by_size, inline, inline_arrays, jit

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


HISTORY_BITS = 40
"""A shear history lies on a grid of 2^-40 of the power of two at or below its contact's
elastic normal force (a rolling history: of that force times R*), so its grid is as fine,
relative to it, for a contact pressed by micronewtons as for one pressed by kilonewtons;
and 12 bits coarser than a float64 there, so that the history's remap and turn (Hanley
2020 Eq 7-9), undone in floating point by the reversed step, mostly land within half a step
of where they started and round back onto it."""

EXPONENT = np.int64(0x7FF0000000000000)


@inline
def binade(x):
    """The power of two at or below |x| (x normal): x with its mantissa bits cleared."""
    return np.int64(np.float64(x).view(np.int64) & EXPONENT).view(np.float64)


@inline
def snapped(vector, step):
    """A 3-vector rounded to the grid of `step` (`rounded`), held as doubles: a multiple of a
    power of two below 2^52 steps is a double exactly; zero is +0.0, whatever the sign it was
    rounded from. step = 0 (from a force below the normal doubles): the vector as it is."""
    if step == 0.0:
        return vector
    per = 1.0 / step
    return (
        rounded(vector[0] * per) * step + 0.0,
        rounded(vector[1] * per) * step + 0.0,
        rounded(vector[2] * per) * step + 0.0,
    )


@inline
def to_grid(y):
    """`rounded(y)` as an integer (|y| <= RANGE): the conversion truncates, as np.trunc does."""
    return np.int64(y + math.copysign(0.5, y))


@inline
def moved_on_grid(n, steps):
    """n + round(steps), `steps` a value in grid steps, and whether it stayed in range: a value
    that would leave it stays n (nothing wraps around). Selections, not branches, so that a
    loop over particles stays straight."""
    fits = abs(steps) <= RANGE
    moved = n + to_grid(steps if fits else 0.0)
    fits = fits and abs(moved) <= RANGE
    return (moved if fits else n), fits


OUT = 2.0**62
"""RANGE + 1 grid steps: a term held here (`in_range`, `snapped_in_range`) is out of range,
and a sum judged by `sum_in_range` stays below it."""


@inline
def in_range(y):
    """y in grid steps, held to +-OUT (NaN to OUT), where its conversion is defined."""
    return y if abs(y) < OUT else math.copysign(OUT, y)


@inline
def snapped_value(value, step):
    """A value rounded to the grid of `step` (`rounded`), held as a double and clamped to +-OUT
    grid steps (NaN to OUT): see `snapped_in_range`."""
    return in_range(rounded(value * (1.0 / step))) * step + 0.0


@inline
def snapped_in_range(vector, step):
    """A 3-vector rounded to the grid of `step` (`rounded`), held as doubles, each component
    clamped to +-OUT grid steps (NaN to OUT): the pair loop stores each pair's force so, once
    a pair, and the gather converts it to integers exactly, with no rounding and no
    undefined conversion, and sees a force beyond the range as a sum out of range."""
    return (snapped_value(vector[0], step), snapped_value(vector[1], step),
            snapped_value(vector[2], step))  # fmt: skip


@inline
def in_range3(y):
    """`in_range` of each component of a 3-vector in grid steps."""
    return in_range(y[0]), in_range(y[1]), in_range(y[2])


@inline
def largest_of(value, largest):
    """The largest magnitude of a component of the 3-vector `value` and `largest`."""
    return max(largest, max(abs(value[0]), max(abs(value[1]), abs(value[2]))))


@inline
def add_on_grid(total, value, factor, per_step, largest):
    """total + factor value on a grid of 1 / per_step: total a 3-tuple of integers, factor
    value rounded to the grid first (the steps are powers of two, so multiplying by per_step
    divides by the step exactly). Returns (sum, the largest magnitude of a term so far in
    grid steps, before rounding, `largest` before), which `sum_in_range` judges once the sum
    is complete, where judging each partial sum would put two branches into every term of
    the gather's sums. A term beyond the range is held at its end value by value
    (`in_range`), which the largest then reports: a selection of the whole term, which each
    conversion waited for, made the history gather take 15 % longer."""
    scale = factor * per_step
    y = in_range3((value[0] * scale, value[1] * scale, value[2] * scale))
    return (total[0] + to_grid(y[0]), total[1] + to_grid(y[1]), total[2] + to_grid(y[2])), (
        largest_of(y, largest)
    )


EXACT = 2.0**53
"""Grid steps below which every integer is a double: a sum of values on one grid whose every
partial sum stays below it is exact in floating point, in any order."""


@inline
def add_rounded(total, value, step, per_step):
    """total + value rounded to the grid of `step`, as `add_on_grid` rounds it, in doubles:
    total a 3-tuple of doubles on the grid, each sum exact while `sum_exact` holds."""
    y = in_range3((value[0] * per_step, value[1] * per_step, value[2] * per_step))
    return (total[0] + rounded(y[0]) * step, total[1] + rounded(y[1]) * step,
            total[2] + rounded(y[2]) * step)  # fmt: skip


MAGNITUDE = np.int64(0x7FFFFFFFFFFFFFFF)


@inline
def magnitude_bits(x):
    """The bits of |x| as an integer, which orders as |x| does (x not NaN)."""
    return np.float64(x).view(np.int64) & MAGNITUDE


@inline
def sum_exact(largest, terms):
    """Whether a sum of `terms` terms on a grid, none larger than `largest` grid steps before
    rounding, is exact in doubles whatever their order (`EXACT`); then it is also in range
    (`sum_in_range`)."""
    return (largest + 0.5) * terms < EXACT


@inline
def add_snapped(total, value, factor, per_step, largest):
    """`add_on_grid` of a value already on the grid and in range (`snapped_in_range`) and
    factor +-1: value times per_step is an integer, converted exactly."""
    y0 = factor * value[0] * per_step
    y1 = factor * value[1] * per_step
    y2 = factor * value[2] * per_step
    largest = largest_of((y0, y1, y2), largest)
    return (total[0] + np.int64(y0), total[1] + np.int64(y1), total[2] + np.int64(y2)), largest


@inline
def within_range(y):
    """Whether a value in grid steps is within the range (NaN is not)."""
    return abs(y) <= RANGE


@inline
def in_grid_range(y0, y1, y2):
    """Whether values in grid steps are all within the range (`within_range`)."""
    return within_range(y0) and within_range(y1) and within_range(y2)


@inline
def sum_in_range(largest, terms):
    """Whether a sum of `terms` terms on a grid, none larger than `largest` grid steps before
    rounding (half a step more after), stays in range whatever their order: a sum that might
    not is taken to have left it (the product in doubles rounds, monotonically: below OUT,
    the exact one is at most RANGE)."""
    return (largest + 0.5) * terms < OUT


@inline
def kick_steps(h, f, inv_m, step):
    """A half kick h f / m of one component in grid steps of `step`, before rounding (grid
    steps are powers of two: multiplying by 1 / step divides exactly)."""
    return h * f * inv_m * (1.0 / step)


KICK_BLOCK = 64
"""Particles a half kick on the grid takes at a time (`_kick`): their inverse masses, each
three times, fill 1.5 KB, which stays in the first-level cache."""


@inline_arrays
def kick_coordinates(begin, end, n, mirror, f, inv_m, h, step):
    """The half kick of coordinates `begin` to `end` - 1 of the flat arrays n, mirror and f,
    coordinate k with the inverse mass inv_m[k - begin]: n += round(h f / m / step), mirror =
    n step; elementwise, which LLVM vectorises. Returns (coordinates whose value would have
    left the range, which stay as they were; the last of them or -1)."""
    out = 0
    last = -1
    for k in range(begin, end):
        c = np.uint64(k)  # unsigned: no wraparound, which stops LLVM
        moved, fine = moved_on_grid(n[c], kick_steps(h, f[c], inv_m[c - np.uint64(begin)], step))
        n[c] = moved
        mirror[c] = moved * step
        out += not fine
        last = max(last, -1 if fine else k)
    return out, last


def _kick(begin, end, n, mirror, f, inv_m, h, step):
    """The half kick of particles `begin` to `end` - 1 on their grid (`by_parts`), n +=
    round(h f / m / step), mirror = n step: KICK_BLOCK particles at a time, their inverse
    masses copied three times each, so that the kick runs over their coordinates in one
    elementwise loop (`kick_coordinates`: 3.4-3.9 ns a sphere against 8.2-11.7 a particle at
    a time, which LLVM did not vectorise; 55 296 spheres, one core). Returns (values out of
    range, the particle of the last of them or -1)."""
    n, mirror, f = n.reshape(-1), mirror.reshape(-1), f.reshape(-1)
    per_coordinate = np.empty(3 * KICK_BLOCK)
    out = 0
    last = -1
    for first in range(begin, end, KICK_BLOCK):
        size = min(KICK_BLOCK, end - first)
        for k in range(size):
            inverse = inv_m[np.uint64(first + k)]
            for d in range(3):
                per_coordinate[3 * k + d] = inverse
        counts = kick_coordinates(3 * first, 3 * (first + size), n, mirror, f, per_coordinate, h,
                                  step)  # fmt: skip
        out += counts[0]
        last = max(last, counts[1])
    return out, last // 3 if last >= 0 else -1


def _drift(n, v, h, step, mid, in_cell):
    """n += round(h v / step) on the grid of each axis; in a deforming cell the grid is of the
    cell coordinate, n += round(h v / (step L_mid)) with L_mid the edges halfway through the
    step. Returns as `_kick`."""
    out = 0
    last = -1
    for q in numba.prange(n.shape[0]):
        ok = True
        for d in range(3):
            size = step[d] * mid[d] if in_cell else step[d]
            n[q, d], fine = moved_on_grid(n[q, d], h * v[q, d] / size)
            ok = ok & fine
        if not ok:
            out += 1
            last = max(last, q)
    return out, last


def _drift_uniform(begin, end, n, x, v, h, step):
    """`_drift` of positions outside a deforming cell whose axes share one grid step, over
    the flat arrays of all their coordinates (n, x, v reshaped to one row), from `begin` to
    `end` - 1 of those (`by_parts`), with the positions the integers give, x = n step
    (`_mirror_positions`), in the same pass: unit strides, which LLVM vectorises (3.0
    against 7.3 ns a sphere for `_drift` and the mirror, n = 24 fcc, one core). Returns the
    coordinates out of range and the particle of the last of them."""
    per = 1.0 / step  # a power of two: multiplying by it divides exactly, as `_drift` does
    out = 0
    last = -1
    for k in range(begin, end):
        i = np.uint64(k)  # unsigned: no wraparound, which stops LLVM
        moved, fine = moved_on_grid(n[i], h * v[i] * per)
        n[i] = moved
        x[i] = moved * step
        out += not fine
        last = max(last, -1 if fine else k)  # the coordinate: a division here stops LLVM
    return out, last // 3 if last >= 0 else -1


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


kick = by_parts(_kick, LIGHT)
kick_part = inline_arrays(_kick)
"""`_kick` inlined into another loop's part (`gather.damp_and_kick_on_grids`)."""
drift = by_size(_drift, LIGHT)
drift_uniform = by_parts(_drift_uniform, LIGHT)
mirror = by_size(_mirror_positions, LIGHT)


@jit
def note_overflow(fixed, quantity, counts):
    """Remember the first update that left its grid: (quantity, particle)."""
    out, last = counts
    if out > 0 and fixed.overflow[0] == 0:
        fixed.overflow[0] = 1 + quantity
        fixed.overflow[1] = last


def onto_grid(values: np.ndarray, step) -> np.ndarray:
    """Round floating-point values to their grid in place (half away from zero, as
    `rounded`); returns the integers."""
    n = np.trunc(values / step + np.copysign(0.5, values)).astype(np.int64)
    values[...] = n * step
    return n
