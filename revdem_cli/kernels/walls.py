"""Walls of the shapes of `revdem_cli.wall_shapes`, moving at prescribed velocities."""

from revdem_cli.kernels import jit
from revdem_cli.wall_shapes import overlap

wall_overlap = overlap()
"""wall_overlap(kind, point, axis, radius, x, r): (overlap, unit normal from the sphere towards
the wall) of a sphere at x of radius r and a wall of shape number `kind`
(`revdem_cli.wall_shapes`). Vectors are 3-tuples."""


@jit
def place_walls(walls, elapsed):
    """Wall positions after `elapsed` seconds of the stage: origin + velocity elapsed.

    A function of the step alone, so both directions put each wall at the same place.
    """
    for w in range(walls.point.shape[0]):
        for d in range(3):
            walls.point[w, d] = walls.origin[w, d] + walls.velocity[w, d] * elapsed
