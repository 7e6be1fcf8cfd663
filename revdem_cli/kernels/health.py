"""Whether a state is still physical: every number finite, no overlap deeper than a limit.

A blown-up run (a time step above the critical one, a wall driven into a packing) shows
first as overlaps far deeper than any contact law is meant for, then as inf and NaN. The
stage loop checks at every observables row and stops there, so that nothing written is
from a state past that point.
"""

import math
from collections import namedtuple

import numba

from revdem_cli.kernels import jit
from revdem_cli.kernels.cell import images
from revdem_cli.kernels.pairs import pair_overlap, separation
from revdem_cli.kernels.sums import blocks_of, by_blocks, span

HEALTHY, NOT_FINITE, TOO_DEEP = range(3)
"""What `examine` found."""

Finding = namedtuple("Finding", ["what", "particle", "partner", "value"])
"""What `examine` found and where: HEALTHY (-1, -1, 0); NOT_FINITE, the particle, -1, and
0, 1 or 2 for its position, velocity or angular velocity; TOO_DEEP, the pair (a wall as
partner -1 - wall index) with the deepest overlap, and that overlap / the smaller radius."""


def _scan(x, v, w, radius, image, pi, pj, first, partials):
    """Of each block of particles (`kernels.sums`): the first particle whose position,
    velocity or angular velocity is not finite, partials[b, 0:3] (-1: none), and, of the
    pairs listed under the block, the deepest overlap / the smaller radius (0 if none
    overlaps) and its pair, the first in list order, partials[b, 3:6]."""
    n = x.shape[0]
    for b in numba.prange(blocks_of(n)):
        lo, hi = span(b, n)
        for quantity, values in enumerate((x, v, w)):
            partials[b, quantity] = -1
            for q in range(lo, hi):
                if not (
                    math.isfinite(values[q, 0])
                    and math.isfinite(values[q, 1])
                    and math.isfinite(values[q, 2])
                ):
                    partials[b, quantity] = q
                    break
        deepest, who, partner = 0.0, -1, -1
        for k in range(first[lo], first[hi]):
            i, j = pi[k], pj[k]
            overlap, _ = pair_overlap(separation(x, i, j, image), radius[i] + radius[j])
            depth = overlap / min(radius[i], radius[j])
            if depth > deepest:
                deepest, who, partner = depth, i, j
        partials[b, 3], partials[b, 4], partials[b, 5] = deepest, who, partner


scan = by_blocks(_scan)


@jit
def examine(p, pairs, walls, cell, limit):
    """The `Finding` of whether the state is HEALTHY, or what is wrong with it. `limit`: the
    deepest overlap allowed, as a fraction of the smaller radius of a contact."""
    n = p.x.shape[0]
    parts = pairs.partials
    args = (p.x, p.v, p.omega, p.radius, images(cell), pairs.i, pairs.j, pairs.first, parts)
    scan(n, *args)
    for quantity in range(3):
        for b in range(blocks_of(n)):
            q = parts[b, quantity]
            if q >= 0:
                return Finding(NOT_FINITE, int(q), -1, float(quantity))
    deepest, who, partner = 0.0, -1, -1
    for b in range(blocks_of(n)):
        if parts[b, 3] > deepest:
            deepest, who, partner = parts[b, 3], int(parts[b, 4]), int(parts[b, 5])
    for q in range(walls.overlap.shape[0]):
        for b in range(walls.overlap.shape[1]):
            depth = walls.overlap[q, b] / p.radius[q]
            if depth > deepest:
                deepest, who, partner = depth, q, -1 - b
    if deepest > limit:
        return Finding(TOO_DEEP, who, partner, deepest)
    return Finding(HEALTHY, -1, -1, 0.0)
