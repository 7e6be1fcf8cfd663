"""Whether a state is still physical: every number finite, no overlap deeper than a limit.

A blown-up run (a time step above the critical one, a wall driven into a packing) shows
first as overlaps far deeper than any contact law is meant for, then as inf and NaN. The
stage loop checks at every observables row and stops there, so that nothing written is
from a state past that point.
"""

import math

from revdem_cli.kernels import jit
from revdem_cli.kernels.cell import images
from revdem_cli.kernels.forces import pair_overlap, separation

HEALTHY, NOT_FINITE, TOO_DEEP = range(3)
"""What `examine` found, alarm[0]; alarm[1:4] then hold (particle, partner, value): for
NOT_FINITE the particle, -1, and 0, 1 or 2 for its position, velocity or angular velocity;
for TOO_DEEP the pair (a wall as partner -1 - wall index) with the deepest overlap and that
overlap / the smaller radius."""


@jit
def _first_not_finite(a):
    for q in range(a.shape[0]):
        for d in range(3):
            if not math.isfinite(a[q, d]):
                return q
    return -1


@jit
def examine(p, pairs, walls, cell, limit, alarm):
    """Whether the state is HEALTHY, or what is wrong with it (see above), filling `alarm`.
    `limit`: the deepest overlap allowed, as a fraction of the smaller radius of a contact."""
    for quantity, values in enumerate((p.x, p.v, p.omega)):
        q = _first_not_finite(values)
        if q >= 0:
            alarm[0], alarm[1], alarm[2], alarm[3] = NOT_FINITE, q, -1, quantity
            return NOT_FINITE
    deepest, who, partner = 0.0, -1, -1
    image = images(cell)
    for k in range(pairs.count[0]):
        i, j = pairs.i[k], pairs.j[k]
        overlap, _ = pair_overlap(separation(p.x, i, j, image), p.radius[i] + p.radius[j])
        depth = overlap / min(p.radius[i], p.radius[j])
        if depth > deepest:
            deepest, who, partner = depth, i, j
    for q in range(walls.overlap.shape[0]):
        for b in range(walls.overlap.shape[1]):
            depth = walls.overlap[q, b] / p.radius[q]
            if depth > deepest:
                deepest, who, partner = depth, q, -1 - b
    if deepest > limit:
        alarm[0], alarm[1], alarm[2], alarm[3] = TOO_DEEP, who, partner, deepest
        return TOO_DEEP
    return HEALTHY
