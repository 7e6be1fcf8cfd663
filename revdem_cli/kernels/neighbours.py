"""Verlet pair lists from cell lists, with fixed capacity and an overflow signal.

A pair list holds every pair (i < j) closer than r_i + r_j + skin, sorted by (i, j). The
list is rebuilt when some particle could have moved half the skin since the last build; a
list that does not fit its arrays reports the size it needs, and the caller reallocates.
Contact history is keyed by the pair and carried from the old list to the new one.
"""

import math

import numpy as np

from revdem_cli.kernels import jit


@jit
def _cell_grid(x, cutoff, max_cells):
    """Origin, cell size and cells per axis for a grid over the particles' bounding box."""
    lo = np.empty(3)
    hi = np.empty(3)
    for d in range(3):
        lo[d] = x[:, d].min()
        hi[d] = x[:, d].max()
    size = cutoff
    while True:
        dims = np.empty(3, dtype=np.int64)
        for d in range(3):
            dims[d] = max(1, int((hi[d] - lo[d]) / size))
        if dims[0] * dims[1] * dims[2] <= max_cells:
            return lo, size, dims
        size *= 2.0


@jit
def _cell_of(x, lo, size, dims):
    c = np.empty(3, dtype=np.int64)
    for d in range(3):
        c[d] = min(dims[d] - 1, int((x[d] - lo[d]) / size))
    return c


@jit
def build_pairs(x, radius, skin, pair_i, pair_j):
    """Fill pair_i/pair_j with the sorted pairs within reach; return how many there are.

    When the result exceeds the arrays' capacity the arrays hold only a prefix and the
    caller must reallocate and build again.
    """
    n = x.shape[0]
    cutoff = 2.0 * radius.max() + skin
    lo, size, dims = _cell_grid(x, cutoff, 8 * n + 64)
    ncells = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, dtype=np.int64)
    for p in range(n):
        c = _cell_of(x[p], lo, size, dims)
        cell[p] = (c[0] * dims[1] + c[1]) * dims[2] + c[2]
    start = np.zeros(ncells + 1, dtype=np.int64)
    for p in range(n):
        start[cell[p] + 1] += 1
    for c in range(ncells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, dtype=np.int64)
    for p in range(n):
        members[fill[cell[p]]] = p
        fill[cell[p]] += 1

    capacity = pair_i.shape[0]
    found = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        ci = _cell_of(x[i], lo, size, dims)
        nfound = 0
        for a in range(max(0, ci[0] - 1), min(dims[0], ci[0] + 2)):
            for b in range(max(0, ci[1] - 1), min(dims[1], ci[1] + 2)):
                for c in range(max(0, ci[2] - 1), min(dims[2], ci[2] + 2)):
                    cid = (a * dims[1] + b) * dims[2] + c
                    for m in range(start[cid], start[cid + 1]):
                        j = members[m]
                        if j <= i:
                            continue
                        reach = radius[i] + radius[j] + skin
                        dx = x[j, 0] - x[i, 0]
                        dy = x[j, 1] - x[i, 1]
                        dz = x[j, 2] - x[i, 2]
                        if dx * dx + dy * dy + dz * dz < reach * reach:
                            found[nfound] = j
                            nfound += 1
        neighbours = np.sort(found[:nfound])
        for k in range(nfound):
            if count < capacity:
                pair_i[count] = i
                pair_j[count] = neighbours[k]
            count += 1
    return count


@jit
def carry_history(old_i, old_j, old_history, n_old, new_i, new_j, new_history, n_new):
    """Copy each surviving pair's history into the new list (both lists sorted by (i, j))."""
    new_history[:n_new] = 0.0
    k = 0
    for m in range(n_new):
        while k < n_old and (old_i[k] < new_i[m] or (old_i[k] == new_i[m] and old_j[k] < new_j[m])):
            k += 1
        if k < n_old and old_i[k] == new_i[m] and old_j[k] == new_j[m]:
            new_history[m] = old_history[k]


@jit
def index_by_particle(pair_i, pair_j, n_pairs, start, slots):
    """CSR index: the pair slots of particle p are slots[start[p]:start[p+1]], ascending.

    Gathering forces through this index sums each particle's contacts in the order of its
    partners' indices, whatever the thread count or the rebuild history.
    """
    n = start.shape[0] - 1
    start[:] = 0
    for k in range(n_pairs):
        start[pair_i[k] + 1] += 1
        start[pair_j[k] + 1] += 1
    for p in range(n):
        start[p + 1] += start[p]
    fill = start[:-1].copy()
    for k in range(n_pairs):
        slots[fill[pair_i[k]]] = k
        fill[pair_i[k]] += 1
        slots[fill[pair_j[k]]] = k
        fill[pair_j[k]] += 1


@jit
def largest_reach(x, x_built, v, f, inv_mass, dt, direction):
    """Largest distance a particle can be from its position at the last build after the next
    drift: |x - x_built| + dt |v + direction dt/2 f/m| (half-step velocity, Hanley 2020 Eq 1)."""
    worst = 0.0
    for p in range(x.shape[0]):
        moved = 0.0
        step = 0.0
        for d in range(3):
            dm = x[p, d] - x_built[p, d]
            moved += dm * dm
            vh = v[p, d] + direction * 0.5 * dt * f[p, d] * inv_mass[p]
            step += vh * vh
        reach = math.sqrt(moved) + dt * math.sqrt(step)
        if reach > worst:
            worst = reach
    return worst
