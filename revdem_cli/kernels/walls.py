"""Walls: infinite planes and the inside of cylinders, moving at prescribed velocities."""

import math

from revdem_cli.kernels import jit

PLANE = 0
CYLINDER = 1


@jit
def wall_overlap(kind, point, axis, radius, x, r):
    """(overlap, unit normal from the sphere towards the wall) for a sphere at x of radius r.

    Plane: `point` on it, `axis` its unit normal into the domain. Cylinder of `radius`:
    `point` on its axis, `axis` the axis direction, spheres inside it. Vectors are 3-tuples.
    """
    rel = (x[0] - point[0], x[1] - point[1], x[2] - point[2])
    along = rel[0] * axis[0] + rel[1] * axis[1] + rel[2] * axis[2]
    if kind == PLANE:
        return r - along, (-axis[0], -axis[1], -axis[2])
    rho = (rel[0] - along * axis[0], rel[1] - along * axis[1], rel[2] - along * axis[2])
    d = math.sqrt(rho[0] ** 2 + rho[1] ** 2 + rho[2] ** 2)
    if d == 0.0:
        return r - radius, (1.0, 0.0, 0.0)
    return r - (radius - d), (rho[0] / d, rho[1] / d, rho[2] / d)


@jit
def place_walls(walls, elapsed):
    """Wall positions after `elapsed` seconds of the stage: origin + velocity elapsed.

    A function of the step alone, so both directions put each wall at the same place.
    """
    for w in range(walls.point.shape[0]):
        for d in range(3):
            walls.point[w, d] = walls.origin[w, d] + walls.velocity[w, d] * elapsed
