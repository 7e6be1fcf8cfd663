"""The inside of an infinite cylinder: spheres within `radius` of its axis."""

import math

import numpy as np
from pydantic import Field

from revdem_cli.kernels import inline

NAME = "cylinder"
SUMMARY = "the inside of an infinite cylinder: point on its axis, normal along it, and radius"
SIDE = "inside every cylinder"
FIELDS = {"radius": Field(default=None, gt=0, description="cylinder radius, m")}
REQUIRED = ("radius",)


@inline
def overlap(point, axis, radius, x, r):
    """(overlap, normal towards the wall) of a sphere at x of radius r inside a cylinder of
    `radius` about the line through `point` along the unit `axis`. Vectors are 3-tuples."""
    rel = (x[0] - point[0], x[1] - point[1], x[2] - point[2])
    along = rel[0] * axis[0] + rel[1] * axis[1] + rel[2] * axis[2]
    rho = (rel[0] - along * axis[0], rel[1] - along * axis[1], rel[2] - along * axis[2])
    d = math.sqrt(rho[0] ** 2 + rho[1] ** 2 + rho[2] ** 2)
    if d == 0.0:
        return r - radius, (1.0, 0.0, 0.0)
    return r - (radius - d), (rho[0] / d, rho[1] / d, rho[2] / d)


def reach_past(wall, x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """How far each sphere reaches past the cylinder, m."""
    axis = np.array(wall.normal) / max(abs(c) for c in wall.normal)
    axis /= np.linalg.norm(axis)
    along = (x - np.array(wall.point)) @ axis
    rho = np.linalg.norm(x - np.array(wall.point) - along[:, None] * axis, axis=1)
    return r - (wall.radius - rho)
