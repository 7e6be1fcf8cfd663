"""The contacts of a state: which spheres touch each other and the walls, where, and with
what force, read from the arrays the last step left (nothing is computed again).

A contact of spheres i < j has the unit normal n from i to j (across a periodic face, to
j's nearest image), the overlap δ = r_i + r_j - |x_j - x_i| > 0, both as the pair loop
finds them (`kernels.pairs.contact_normals`, to the bit), and the contact point
x_i + (r_i - δ/2) n, the engine's lever arm (Hanley 2020 Eq 5, 22; `contact.lever_arm`).
The force on i from j is split into its normal part (f·n) n and the rest, the tangential
force. A sphere on a wall takes n from the sphere towards the wall. A contact slides when
the Coulomb cap (Hanley 2020 §5.1) cut its shear force in the last step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from revdem_cli.kernels.cell import images
from revdem_cli.kernels.contact import lever_arm
from revdem_cli.kernels.pairs import contact_normals
from revdem_cli.kernels.wall_contacts import wall_normals


@dataclass(frozen=True)
class Touching:
    """Sphere pairs in overlap: i < j, the unit normal n from i to j's nearest image, δ."""

    i: np.ndarray  # (K,) int64
    j: np.ndarray  # (K,) int64
    slot: np.ndarray  # each pair's slot in the pair list, (K,)
    normal: np.ndarray  # (K, 3)
    overlap: np.ndarray  # m, (K,)


def touching_pairs(state) -> Touching:
    """The pairs of the pair list whose spheres overlap now, by the geometry of the pair loop
    (`kernels.pairs.pair_geometry`, through `contact_normals`)."""
    p, pairs = state.particles, state.pairs
    count = int(pairs.count[0])
    normal, overlap = np.zeros((count, 3)), np.zeros(count)
    listed = (pairs.i, pairs.j, np.int64(count), normal, overlap)
    contact_normals(len(p.x), p.x, p.radius, images(state.cell), *listed)
    slot = np.flatnonzero(overlap > 0.0)
    i, j = pairs.i[slot].astype(np.int64), pairs.j[slot].astype(np.int64)
    return Touching(i, j, slot, normal[slot], overlap[slot])


def wall_touches(state) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sphere, wall, unit normal from the sphere towards the wall) of every sphere on a
    wall, by sphere then wall."""
    q, w = np.nonzero(state.walls.overlap > 0.0)
    p, walls = state.particles, state.walls
    n = np.zeros((len(q), 3))
    wall_normals(p, walls, q, w, n)
    return q, w, n


@dataclass(frozen=True)
class ContactList:
    """Every contact of a state: sphere pairs in the order of the pair list, then spheres on
    walls. `partner` is the other sphere, or -1 - w on wall w."""

    particle: np.ndarray  # (K,) int64
    partner: np.ndarray  # (K,) int64
    point: np.ndarray  # contact point, m, (K, 3)
    normal_force: np.ndarray  # normal part of the force on `particle`, N, (K, 3)
    tangential_force: np.ndarray  # tangential part of the force on `particle`, N, (K, 3)
    overlap: np.ndarray  # m, (K,)
    sliding: np.ndarray  # 1 where the Coulomb cap cut the shear force in the last step, (K,)

    FIELDS = ("point", "normal_force", "tangential_force", "overlap", "sliding")

    def __len__(self) -> int:
        return len(self.particle)


def _split(force: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    normal = (force * n).sum(axis=1)[:, None] * n
    return normal, force - normal


def _slid(destroyed: np.ndarray, index) -> np.ndarray:
    """1 where shear force was destroyed in the last step; 0 everywhere without a shear law
    (its arrays then have length 0)."""
    if destroyed.size == 0:
        return np.zeros(len(index[0]) if isinstance(index, tuple) else len(index), np.int8)
    return (destroyed[index] > 0.0).astype(np.int8)


def contact_list(state) -> ContactList:
    """The contacts of `state` as the last step left them."""
    p, pairs, walls = state.particles, state.pairs, state.walls
    t = touching_pairs(state)
    n = t.normal
    q, w, n_wall = wall_touches(state)
    wall_overlap = walls.overlap[q, w]
    pair_normal, pair_tangential = _split(pairs.force[t.slot], n)
    wall_normal_force, wall_tangential = _split(walls.force[q, w], n_wall)
    arm = np.concatenate(
        [lever_arm(p.radius[t.i], t.overlap), lever_arm(p.radius[q], wall_overlap)]
    )
    particle = np.concatenate([t.i, q])
    normal = np.concatenate([n, n_wall])
    return ContactList(
        particle=particle,
        partner=np.concatenate([t.j, -1 - w]),
        point=p.x[particle] + arm[:, None] * normal,
        normal_force=np.concatenate([pair_normal, wall_normal_force]),
        tangential_force=np.concatenate([pair_tangential, wall_tangential]),
        overlap=np.concatenate([t.overlap, wall_overlap]),
        sliding=np.concatenate([_slid(pairs.destroyed, t.slot), _slid(walls.destroyed, (q, w))]),
    )
