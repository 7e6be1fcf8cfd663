"""Walls: infinite planes and the inside of cylinders, moving at prescribed velocities."""

import math

from revdem_cli.kernels import jit

PLANE = 0
CYLINDER = 1


@jit
def wall_overlap(walls, w, x, r):
    """(overlap, unit normal from the sphere towards wall w) for a sphere at x of radius r.

    Plane: `point` on it, `axis` its unit normal into the domain. Cylinder: `point` on its
    axis, `axis` the axis direction, spheres inside it.
    """
    a = (walls.axis[w, 0], walls.axis[w, 1], walls.axis[w, 2])
    rel = (x[0] - walls.point[w, 0], x[1] - walls.point[w, 1], x[2] - walls.point[w, 2])
    along = rel[0] * a[0] + rel[1] * a[1] + rel[2] * a[2]
    if walls.kind[w] == PLANE:
        return r - along, (-a[0], -a[1], -a[2])
    rho = (rel[0] - along * a[0], rel[1] - along * a[1], rel[2] - along * a[2])
    d = math.sqrt(rho[0] ** 2 + rho[1] ** 2 + rho[2] ** 2)
    if d == 0.0:
        return r - walls.radius[w], (1.0, 0.0, 0.0)
    return r - (walls.radius[w] - d), (rho[0] / d, rho[1] / d, rho[2] / d)


@jit
def place_walls(walls, elapsed):
    """Wall positions after `elapsed` seconds of the stage: origin + velocity elapsed.

    A function of the step alone, so both directions put each wall at the same place.
    """
    for w in range(walls.point.shape[0]):
        for d in range(3):
            walls.point[w, d] = walls.origin[w, d] + walls.velocity[w, d] * elapsed
