"""System-wide sums (observables, the health check, the cell's stress) in an order that
does not depend on the thread count.

The particles are cut into blocks of SPAN; a sum over particles, or over the pairs listed
under them, is summed block by block in order, each block by one thread into its row of a
`partials` array, and the rows are then added in block order. A system of at most SPAN
particles is one block, summed in plain order on one thread.
"""

import numpy as np

from revdem_cli.kernels import LIGHT, by_size, inline

SPAN = 1024
"""Particles in a block of a system-wide sum: few enough that a system of a few thousand
spheres has a block for each thread to sum. A servo's periodic cell sums its stress every
step; for 4 000 spheres on two threads (`configs/packings/dense_periodic.toml`) that took
29 ns a sphere in one block of 4 096, 17 in four of 1 024."""

COLUMNS = 9
"""Partial sums a block holds: the most any sum needs (the stress's nine components)."""


@inline
def blocks_of(n):
    """Blocks of SPAN particles that n particles make."""
    return (n + SPAN - 1) // SPAN


@inline
def span(b, n):
    """(first, one past the last) particle of block b of n particles."""
    return b * SPAN, min((b + 1) * SPAN, n)


def by_blocks(loop):
    """`kernels.by_size` for a loop over blocks, a light loop: in parallel only where there is
    more than one block, above SPAN particles."""
    return by_size(loop, LIGHT, least=SPAN + 1)


def empty_partials(n_particles: int) -> np.ndarray:
    """Rows for the partial sums of every block of `n_particles` particles."""
    return np.zeros((max(1, blocks_of.py_func(n_particles)), COLUMNS))
