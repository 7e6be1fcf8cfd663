"""Relative acceleration at a contact of two rigid bodies (Peng 2020 Section 2, Eq 1-19).

`contact_acceleration` follows Eq 1-19 for any two bodies (principal moments on their body
axes), any orientations and any contact point; `mobility` is the matrix that maps the contact
force on body 2 to ẍ_c at zero spin, the paper's diag(A_x, A_y, A_z) of Eq 25 where the
configuration makes it diagonal. The configurations of Figure 2 and the two scans of
Appendix A (Figures A2 and A4) are built here; quaternions (w, x, y, z) give the body-to-world
matrix of Eq 7-8.

The paper writes M_L = R M_G (Eq 5-6) with R of Eq 7; since that R maps body axes to the
world for the rotations it quotes (45° about -y in Appendix A), the world-to-body map used
here is its transpose, M_L = Rᵀ M_G.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from revdem_cli.kernels.rigid_pair import quaternion_product, rotation_matrix
from revdem_cli.timestep.shapes import Body

IDENTITY = (1.0, 0.0, 0.0, 0.0)


def axis_angle(axis, angle: float) -> tuple[float, float, float, float]:
    """The unit quaternion of a rotation by `angle` (rad) about `axis`."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return (math.cos(0.5 * angle), *(math.sin(0.5 * angle) * axis))


def aligning(start, end) -> tuple[float, float, float, float]:
    """The shortest-arc rotation that takes the direction `start` to `end`."""
    start = np.asarray(start, float) / np.linalg.norm(start)
    end = np.asarray(end, float) / np.linalg.norm(end)
    cosine = float(np.clip(start @ end, -1.0, 1.0))
    axis = np.cross(start, end)
    if np.linalg.norm(axis) < 1e-12:  # parallel or opposite: any perpendicular axis
        axis = np.cross(start, np.eye(3)[np.argmin(np.abs(start))])
    return axis_angle(axis, math.acos(cosine))


def compose(*quaternions) -> tuple[float, float, float, float]:
    """The product q₁ q₂ ... (apply the last first)."""
    result = IDENTITY
    for q in quaternions:
        result = quaternion_product(result, tuple(float(v) for v in q))
    return result


def matrix(q) -> np.ndarray:
    """Body-to-world rotation matrix of the unit quaternion q (Peng 2020 Eq 7-8)."""
    return rotation_matrix(np.asarray(q, dtype=float))


@dataclass(frozen=True)
class Placement:
    """Two bodies placed: centres (m), orientations (quaternions) and the contact point (m)."""

    centres: tuple[np.ndarray, np.ndarray]
    orientations: tuple[tuple, tuple]
    point: np.ndarray


def contact_acceleration(bodies, placement: Placement, force, spins=None):
    """ẍ_c = ẍ_c2 - ẍ_c1 for force F on body 2 (-F on body 1), world spins ω_G (rad/s),
    both zero unless given."""
    force = np.asarray(force, dtype=float)
    spins = np.zeros((2, 3)) if spins is None else np.asarray(spins, dtype=float)
    accelerations = []
    for body, centre, q, spin, sign in zip(
        bodies, placement.centres, placement.orientations, spins, (-1.0, 1.0), strict=True
    ):
        rotation = matrix(q)
        inertia = np.asarray(body.axis_moments)
        arm = placement.point - centre  # Peng 2020 Eq 1-2
        moment = np.cross(arm, sign * force)  # Peng 2020 Eq 3-4 (no contact moment M)
        spin_local = rotation.T @ spin  # Peng 2020 Eq 15-16
        local = rotation.T @ moment  # Peng 2020 Eq 5-6
        angular = (local - np.cross(spin_local, inertia * spin_local)) / inertia  # Eq 11-12
        angular = rotation @ angular  # Peng 2020 Eq 13-14
        accelerations.append(
            np.cross(angular, arm)
            + np.cross(spin, np.cross(spin, arm))
            + sign * force / body.mass  # Peng 2020 Eq 17-18
        )
    return accelerations[1] - accelerations[0]  # Peng 2020 Eq 19


def mobility(bodies, placement: Placement) -> np.ndarray:
    """The matrix A with ẍ_c = A F at zero spin (Peng 2020 Eq 25, from Eq 1-19)."""
    return np.column_stack([contact_acceleration(bodies, placement, e) for e in np.eye(3)])


def support_point(body: Body, q, normal) -> np.ndarray:
    """The point of an ellipsoid's surface (from its centre, world frame) whose outward normal
    is `normal`: R D² m / |D m|, m = Rᵀ n, D = diag(a, b, c)."""
    rotation = matrix(q)
    semi = np.asarray(body.surface[:3])
    local = rotation.T @ np.asarray(normal, dtype=float)
    return rotation @ (semi**2 * local / np.linalg.norm(semi * local))


# Figure 2, ellipsoid 1 axis-aligned at the origin. Body 2's orientations: (A, B) its long
# axis along z and its y axis along y, so its z axis lies along x; (C) on its side, x along
# y, y along z and z along x. Eq 22-24 then give the mobilities these orientations do.
STANDING = axis_angle((0.0, 1.0, 0.0), 0.5 * math.pi)
ON_SIDE = axis_angle((1.0, 1.0, 1.0), 2.0 * math.pi / 3.0)


def figure2(body1: Body, body2: Body) -> dict[str, Placement]:
    """The three configurations of Peng 2020 Figure 2 as the paper sets them (Eq 22-24).

    (A) orthogonal tip to tip: body 2's tip on body 1's tip (a₁, 0, 0), its centre at
    (a₁, 0, a₂). (B) body 2 standing on its tip on body 1's face (0, 0, c₁). (C) body 2 lying
    on its side on that face, touching with its b-side. Body 1's principal frame is the world.
    """
    a1, _, c1 = body1.surface[:3]
    a2, b2, _ = body2.surface[:3]
    origin = np.zeros(3)
    return {
        "A": Placement(
            (origin, np.array([a1, 0.0, a2])), (IDENTITY, STANDING), np.array([a1, 0.0, 0.0])
        ),
        "B": Placement(
            (origin, np.array([0.0, 0.0, c1 + a2])), (IDENTITY, STANDING), np.array([0, 0, c1])
        ),
        "C": Placement(
            (origin, np.array([0.0, 0.0, c1 + b2])), (IDENTITY, ON_SIDE), np.array([0, 0, c1])
        ),
    }


# Appendix A: ellipsoid 2 turned 45° about -y (Gaschler's converter, the paper's ref 23);
# scenario 2 turns it a further 90° about its own x axis.
APPENDIX_TILT = axis_angle((0.0, -1.0, 0.0), 0.25 * math.pi)
SCENARIO_TURN = {1: IDENTITY, 2: axis_angle((1.0, 0.0, 0.0), 0.5 * math.pi)}
APPENDIX_FORCE = (1.0, 1.0, 1.0)  # N, on body 2


def octant_directions(count: int) -> np.ndarray:
    """Unit vectors of the first octant, `count` polar × `count` azimuthal angles from 0 to
    π/2 both included."""
    polar, azimuth = np.meshgrid(
        np.linspace(0.0, 0.5 * math.pi, count), np.linspace(0.0, 0.5 * math.pi, count)
    )
    return np.stack(
        [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1
    ).reshape(-1, 3)


def octant_points(body: Body, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Points of an ellipsoid's first octant (the directions of `octant_directions` scaled
    by the semi-axes) and their outward unit normals (body frame = world)."""
    semi = np.asarray(body.surface[:3])
    points = semi * octant_directions(count)
    normals = points / semi**2
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def scan_contact_points(body1: Body, body2: Body, scenario: int, count: int) -> dict:
    """Figure A2: ellipsoid 2 at a fixed orientation touches ellipsoid 1 at each point of its
    first octant (centre moved, the surfaces tangent there); |ẍ_c| for APPENDIX_FORCE."""
    q2 = compose(APPENDIX_TILT, SCENARIO_TURN[scenario])
    points, normals = octant_points(body1, count)
    rows = []
    for point, normal in zip(points, normals, strict=True):
        centre2 = point - support_point(body2, q2, -normal)
        placement = Placement((np.zeros(3), centre2), (IDENTITY, q2), point)
        accel = contact_acceleration((body1, body2), placement, APPENDIX_FORCE)
        rows.append((*point, *centre2, np.linalg.norm(accel)))
    names = ("x", "y", "z", "centre2_x", "centre2_y", "centre2_z", "acceleration")
    return dict(zip(names, np.array(rows).T, strict=True))


def scan_orientations(body1: Body, body2: Body, scenario: int, count: int) -> dict:
    """Figure A4: the contact at ellipsoid 1's tip (a₁, 0, 0); ellipsoid 2's long axis turned
    to every direction u of the first octant (shortest arc from x, then the scenario's turn).

    `acceleration`: the paper's construction, ellipsoid 2's tip on that point, its centre
    at (a₁, 0, 0) + a₂ u. `tangent_acceleration`: ellipsoid 2 at the same orientation moved
    to touch ellipsoid 1 there, tangent to it (normal x), as smooth bodies can.
    """
    a1, a2 = body1.surface[0], body2.surface[0]
    tip = np.array([a1, 0.0, 0.0])
    rows = []
    for u in octant_directions(count):
        q2 = compose(aligning((1.0, 0.0, 0.0), u), SCENARIO_TURN[scenario])
        centre2 = tip + a2 * u
        paper = Placement((np.zeros(3), centre2), (IDENTITY, q2), tip)
        tangent_centre = tip - support_point(body2, q2, (-1.0, 0.0, 0.0))
        tangent = Placement((np.zeros(3), tangent_centre), (IDENTITY, q2), tip)
        rows.append(
            (
                *centre2,
                np.linalg.norm(contact_acceleration((body1, body2), paper, APPENDIX_FORCE)),
                np.linalg.norm(contact_acceleration((body1, body2), tangent, APPENDIX_FORCE)),
            )
        )
    names = ("centre2_x", "centre2_y", "centre2_z", "acceleration", "tangent_acceleration")
    return dict(zip(names, np.array(rows).T, strict=True))
