"""An infinite plane: spheres on the side its normal points to."""

import numpy as np

from revdem_cli.kernels import inline

NAME = "plane"
SUMMARY = "an infinite plane: point on it, normal into the domain"
SIDE = "on the inner side of every plane (where its normal points)"
FIELDS = {}
REQUIRED = ()


@inline
def overlap(point, axis, radius, x, r):
    """(overlap, normal towards the plane) of a sphere at x of radius r; `axis` the plane's
    unit normal into the domain. Vectors are 3-tuples."""
    along = (x[0] - point[0]) * axis[0] + (x[1] - point[1]) * axis[1] + (x[2] - point[2]) * axis[2]
    return r - along, (-axis[0], -axis[1], -axis[2])


def reach_past(wall, x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """How far each sphere reaches past the plane, m."""
    axis = np.array(wall.normal) / max(abs(c) for c in wall.normal)
    axis /= np.linalg.norm(axis)
    return r - (x - np.array(wall.point)) @ axis
