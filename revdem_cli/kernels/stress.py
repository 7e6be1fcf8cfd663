"""Stress: the average stress of the periodic cell (Hanley 2020 Eq 23) and each sphere's
(Eq 22)."""

import math

import numba

from revdem_cli.kernels import jit
from revdem_cli.kernels.cell import images, volume
from revdem_cli.kernels.contact import lever_arm
from revdem_cli.kernels.pairs import pair_geometry, separation
from revdem_cli.kernels.sums import blocks_of, by_blocks, span
from revdem_cli.kernels.vectors import row
from revdem_cli.kernels.wall_contacts import wall_normal


def _stress_sums(x, image, pi, pj, first, force, partials):
    """sum of -d (x) f over the pairs listed under each block of particles (`kernels.sums`),
    in list order, partials[b, 3 a + c]."""
    n = x.shape[0]
    for b in numba.prange(blocks_of(n)):
        partials[b, :9] = 0.0
        lo, hi = span(b, n)
        for k in range(first[lo], first[hi]):
            f = row(force, k)
            if f[0] != 0.0 or f[1] != 0.0 or f[2] != 0.0:
                d = separation(x, pi[k], pj[k], image)
                for a in range(3):
                    for c in range(3):
                        partials[b, 3 * a + c] -= d[a] * f[c]


stress_sums = by_blocks(_stress_sums)


@jit
def stress_of(p, pairs, cell, sigma):
    """Average stress in the cell into `sigma` (3, 3), -1/V sum over contacts of d (x) f with d
    the branch vector from i to j and f the force on i (Hanley 2020 Eq 22-23 summed over
    the particles; compression positive), summed over the pair list by blocks
    (`kernels.sums`)."""
    n = p.x.shape[0]
    parts = pairs.partials
    args = (p.x, images(cell), pairs.i, pairs.j, pairs.first, pairs.force, parts)
    stress_sums(n, *args)
    sigma[:, :] = 0.0
    for b in range(blocks_of(n)):
        for a in range(3):
            for c in range(3):
                sigma[a, c] += parts[b, 3 * a + c]
    scale = 1.0 / volume(cell)
    for a in range(3):
        for c in range(3):
            sigma[a, c] *= scale


@jit
def particle_stress(p, pairs, walls, cell, out):
    """Stress of each particle, -1/V_p sum over its contacts of x_c (x) f_c with x_c from its
    centre to the contact point (Hanley 2020 Eq 22; compression positive), Pa, (N, 3, 3).

    A pair's force f on i acts on j as -f at -arm_j n: both particles get arm n (x) f."""
    out[:] = 0.0
    image = images(cell)
    for k in range(pairs.count[0]):
        f = row(pairs.force, k)
        if f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0:
            continue
        i, j = pairs.i[k], pairs.j[k]
        overlap, n, _ = pair_geometry(separation(p.x, i, j, image), p.radius[i], p.radius[j])
        for q in (i, j):
            arm = lever_arm(p.radius[q], overlap)
            for a in range(3):
                for b in range(3):
                    out[q, a, b] -= arm * n[a] * f[b]
    for q in range(p.x.shape[0]):
        for b in range(walls.force.shape[1]):
            if walls.overlap[q, b] > 0.0:
                n = wall_normal(p, walls, q, b)
                arm = lever_arm(p.radius[q], walls.overlap[q, b])
                for a in range(3):
                    for c in range(3):
                        out[q, a, c] -= arm * n[a] * walls.force[q, b, c]
        out[q] *= 3.0 / (4.0 * math.pi * p.radius[q] ** 3)
