"""Verlet pair lists from cell lists, with fixed capacity and an overflow signal.

A pair list holds every pair (i < j) closer than r_i + r_j + skin, sorted by (i, j), across
periodic boundaries to the nearest image. The list is rebuilt when some pair could have
closed half the skin since the last build; a list that does not fit its arrays reports the
size it needs, and the caller reallocates. Contact history is keyed by the pair and carried
from the old list to the new one in place.
"""

import math

import numba
import numpy as np

from revdem_cli.kernels import LIGHT, by_size, jit
from revdem_cli.kernels.cell import nearest_image


@jit
def cell_grid(x, periodic, length, cutoff, max_cells):
    """(lower corner, cell edge, cells) per axis of a grid of cells at least `cutoff` wide,
    at most `max_cells` of them: the periodic box [0, L) on periodic axes, the particles'
    bounding box on the others."""
    lo = np.zeros(3)
    edge = np.empty(3)
    dims = np.empty(3, dtype=np.int64)
    span = cutoff
    while True:
        for d in range(3):
            extent = length[d] if periodic[d] else x[:, d].max() - x[:, d].min()
            dims[d] = max(1, int(min(extent / span, max_cells)))  # no overflow, however far
            if periodic[d]:
                edge[d] = length[d] / dims[d]
            else:
                lo[d] = x[:, d].min()
                edge[d] = span
        if float(dims[0]) * float(dims[1]) * float(dims[2]) <= max_cells:
            return lo, edge, dims
        span *= 2.0


@jit
def within(u, dims):
    """int(u) kept inside [0, dims - 1], taken before the conversion (a float beyond the
    int64 range converts to an arbitrary integer) and NaN to 0: never an index outside the
    grid, however far or wrong the position."""
    if u >= dims - 1:
        return dims - 1
    if u > 0.0:
        return int(u)
    return 0


@jit
def axis_cell(xd, lo, edge, dims, periodic, length):
    """Cell coordinate along one axis of a position component."""
    if periodic:
        u = xd / length
        return within((u - math.floor(u)) * dims, dims)
    return within((xd - lo) / edge, dims)


@jit
def axis_span(c, dims, periodic):
    """Range of neighbouring cell coordinates along one axis, each cell once, to be taken
    modulo `dims`."""
    if periodic:
        if dims < 3:
            return 0, dims
        return c - 1, c + 2
    return max(0, c - 1), min(dims, c + 2)


@jit
def _bin(x, periodic, length, lo, edge, dims):
    """Counting sort of the particles into cells: (cell of each particle, CSR offsets of
    each cell, particles by cell)."""
    n = x.shape[0]
    cells = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, dtype=np.int64)
    for p in range(n):
        c0 = axis_cell(x[p, 0], lo[0], edge[0], dims[0], periodic[0], length[0])
        c1 = axis_cell(x[p, 1], lo[1], edge[1], dims[1], periodic[1], length[1])
        c2 = axis_cell(x[p, 2], lo[2], edge[2], dims[2], periodic[2], length[2])
        cell[p] = (c0 * dims[1] + c1) * dims[2] + c2
    start = np.zeros(cells + 1, dtype=np.int64)
    for p in range(n):
        start[cell[p] + 1] += 1
    for c in range(cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, dtype=np.int32)
    for p in range(n):
        members[fill[cell[p]]] = p
        fill[cell[p]] += 1
    return cell, start, members


def _partners(x, radius, skin, periodic, length, dims, cell, start, members, offsets, out_j):
    """For each particle i, its partners j > i within r_i + r_j + skin: counted into
    offsets[i + 1] when out_j is empty, else written, ascending, into out_j from offsets[i]."""
    fill = out_j.shape[0] > 0
    image = (
        length[0],
        length[1],
        length[2],
        1.0 / length[0] if periodic[0] else 0.0,
        1.0 / length[1] if periodic[1] else 0.0,
        1.0 / length[2] if periodic[2] else 0.0,
    )
    for i in numba.prange(x.shape[0]):
        c = cell[i]
        c2 = c % dims[2]
        c1 = (c // dims[2]) % dims[1]
        c0 = c // (dims[1] * dims[2])
        lo0, hi0 = axis_span(c0, dims[0], periodic[0])
        lo1, hi1 = axis_span(c1, dims[1], periodic[1])
        lo2, hi2 = axis_span(c2, dims[2], periodic[2])
        found = 0
        first = offsets[i] if fill else 0
        for a in range(lo0, hi0):
            for b in range(lo1, hi1):
                for e in range(lo2, hi2):
                    cid = ((a % dims[0]) * dims[1] + b % dims[1]) * dims[2] + e % dims[2]
                    for m in range(start[cid], start[cid + 1]):
                        j = members[m]
                        if j <= i:
                            continue
                        reach = radius[i] + radius[j] + skin
                        d = nearest_image(
                            (x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]), image
                        )
                        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < reach * reach:
                            if fill:  # insertion sort into place
                                slot = first + found
                                while slot > first and out_j[slot - 1] > j:
                                    out_j[slot] = out_j[slot - 1]
                                    slot -= 1
                                out_j[slot] = j
                            found += 1
        if not fill:
            offsets[i + 1] = found


partners = by_size(_partners)


@jit
def build_pairs(x, radius, skin, periodic, length, pair_i, pair_j):
    """Fill pair_i/pair_j with the sorted pairs within reach; return how many there are.

    When that exceeds the arrays' capacity they are left as they were, and the caller must
    reallocate and build again.
    """
    n = x.shape[0]
    cutoff = 2.0 * radius.max() + skin
    lo, edge, dims = cell_grid(x, periodic, length, cutoff, 8 * n + 64)
    cell, start, members = _bin(x, periodic, length, lo, edge, dims)
    offsets = np.zeros(n + 1, dtype=np.int64)
    grid = (x, radius, skin, periodic, length, dims, cell, start, members, offsets)
    counting = np.empty(0, dtype=np.int32)
    partners(n, *grid, counting)
    for i in range(n):
        offsets[i + 1] += offsets[i]
    count = offsets[n]
    if count > pair_i.shape[0]:
        return count
    partners(n, *grid, pair_j)
    for i in range(n):
        for k in range(offsets[i], offsets[i + 1]):
            pair_i[k] = i
    return count


@jit
def _before(i1, j1, i2, j2):
    return i1 < i2 or (i1 == i2 and j1 < j2)


@jit
def _copy_row(a, source, target):
    for d in range(3):
        a[target, d] = a[source, d]


@jit
def carry_history(old_i, old_j, n_old, new_i, new_j, n_new, history):
    """Move each surviving pair's history from its slot in the old list to its slot in the
    new one, in place (both lists sorted by (i, j)); new pairs start with none.

    With k(m) the old slot of new pair m, increasing in m: pairs with k(m) < m move in
    descending m, then pairs with k(m) > m in ascending m, then new pairs are zeroed. No
    slot is written before it has been read: a slot m with k(m) < m is never the source of
    a pair with k > m (k is increasing), and the zeroed slots are no pair's source left.
    """
    k = n_old - 1
    for m in range(n_new - 1, -1, -1):  # k(m) < m, descending
        while k >= 0 and _before(new_i[m], new_j[m], old_i[k], old_j[k]):
            k -= 1
        if k >= 0 and old_i[k] == new_i[m] and old_j[k] == new_j[m] and k < m:
            _copy_row(history, k, m)
    k = 0
    for m in range(n_new):  # k(m) > m, ascending
        while k < n_old and _before(old_i[k], old_j[k], new_i[m], new_j[m]):
            k += 1
        if k < n_old and old_i[k] == new_i[m] and old_j[k] == new_j[m] and k > m:
            _copy_row(history, k, m)
    k = 0
    for m in range(n_new):  # no k(m): a new contact
        while k < n_old and _before(old_i[k], old_j[k], new_i[m], new_j[m]):
            k += 1
        if not (k < n_old and old_i[k] == new_i[m] and old_j[k] == new_j[m]):
            for d in range(3):
                history[m, d] = 0.0


@jit
def index_by_particle(pair_i, pair_j, n_pairs, first, start, slots):
    """Index of each particle's pairs: its pairs (q, j) are the list's slots first[q] to
    first[q+1] (the list is sorted by i), and its pairs (p, q) with p < q are
    slots[start[q]:start[q+1]], ascending in p.

    Gathering forces through this index sums each particle's contacts in the order of its
    partners' indices, whatever the thread count or the rebuild history.
    """
    n = start.shape[0] - 1
    first[:] = 0
    start[:] = 0
    for k in range(n_pairs):
        first[pair_i[k] + 1] += 1
        start[pair_j[k] + 1] += 1
    for p in range(n):
        first[p + 1] += first[p]
        start[p + 1] += start[p]
    fill = start[:-1].copy()
    for k in range(n_pairs):
        slots[fill[pair_j[k]]] = k
        fill[pair_j[k]] += 1


BUILT_ROUNDING = 2.0**-23
"""At most how far, relative, a position at the last build lies from its single-precision
copy (`Pairs.x_built`, rounded to nearest: 2^-24), with room for the product that carries it
with the cell."""


def _largest_reach(x, x_built, v, f, inv_mass, dt, direction, length, built):
    """A bound on how far any particle can be from its position at the last build, carried
    with the cell, after the next drift: the largest |x - x_built L / L_built|, plus the
    largest dt |v + direction dt/2 f/m| (half-step velocity, Hanley 2020 Eq 1), plus the
    most that x_built, single precision, can be from the position it was (`BUILT_ROUNDING`),
    each largest found apart. Each is the integer maximum of the bits of its squares (a
    nonnegative double orders as its bits do), a reduction LLVM vectorises, then one square
    root: 3.4 ns a sphere on one core (n = 24 fcc), its 84 bytes' time, against 5.2 for the
    largest sum found particle by particle (two roots a sphere, a floating-point maximum
    LLVM does not vectorise without fast math)."""
    r0 = length[0] / built[0]
    r1 = length[1] / built[1]
    r2 = length[2] / built[2]
    most_moved = np.int64(0)  # the bits of the largest of each: nonnegative doubles
    most_speed = np.int64(0)
    most_off = np.int64(0)
    for p in numba.prange(x.shape[0]):
        b0 = x_built[p, 0] * r0
        b1 = x_built[p, 1] * r1
        b2 = x_built[p, 2] * r2
        d0 = x[p, 0] - b0
        d1 = x[p, 1] - b1
        d2 = x[p, 2] - b2
        off = BUILT_ROUNDING * (abs(b0) + abs(b1) + abs(b2))
        vh0 = v[p, 0] + direction * 0.5 * dt * f[p, 0] * inv_mass[p]
        vh1 = v[p, 1] + direction * 0.5 * dt * f[p, 1] * inv_mass[p]
        vh2 = v[p, 2] + direction * 0.5 * dt * f[p, 2] * inv_mass[p]
        moved_squared = d0 * d0 + d1 * d1 + d2 * d2
        speed_squared = vh0 * vh0 + vh1 * vh1 + vh2 * vh2
        most_moved = max(most_moved, np.float64(moved_squared).view(np.int64))
        most_speed = max(most_speed, np.float64(speed_squared).view(np.int64))
        most_off = max(most_off, np.float64(off).view(np.int64))
    moved = math.sqrt(np.int64(most_moved).view(np.float64))
    speed = math.sqrt(np.int64(most_speed).view(np.float64))
    return moved + np.int64(most_off).view(np.float64) + dt * speed


largest_reach = by_size(_largest_reach, LIGHT)
