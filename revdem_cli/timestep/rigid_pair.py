"""The critical time step of two rigid superquadrics found by integrating them.

`kernels.rigid_pair` steps the two bodies in full: contact found on their surfaces every step,
Euler's equations, the contact point free to slide over both surfaces as they turn. Here the
pair is placed in a configuration, touching with their surfaces tangent, the contact made
bonded (the linear spring pulls as well as pushes, the paper's linear model, Eq 29), body 2
moved by a small displacement and released from rest. A Δt is stable when the contact
displacement √(δ² + |stretch|²) over the second half of STEPS steps stays within GROWTH of
its peak over the first; the limit is bisected as for Eq 30 (`verify.largest_stable_dt`).

Configurations (`tangent_configurations`): the three of Peng 2020 Figure 2 as tangent
contacts and the coaxial tip-to-tip contact; and random ones (`random_configurations`):
uniformly random orientations and contact points on both surfaces, seeded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from revdem_cli.errors import RunFailed
from revdem_cli.kernels import rigid_pair as kernel
from revdem_cli.timestep.contact_kinematics import (
    IDENTITY,
    ON_SIDE,
    STANDING,
    aligning,
    axis_angle,
    compose,
    matrix,
)
from revdem_cli.timestep.criteria import Contact, a_max
from revdem_cli.timestep.shapes import Body
from revdem_cli.timestep.verify import largest_stable_dt

STEPS = 2000  # steps per trial Δt
GROWTH = 2.0  # late/early peak displacement that counts as unstable
DISPLACEMENT = 1e-6  # body 2's starting displacement / the larger body's longest semi-axis
BLOW_UP = 1e-3  # displacement / that semi-axis at which a trial stops as unstable
BISECTION_RTOL = 1e-4
DRAWS = 8  # random configurations of `rigid_body_limit`
SEED = 2020
KICK_DIRECTION = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)  # no symmetry of a configuration


@dataclass(frozen=True)
class Configuration:
    """Two bodies touching: orientations (quaternions) and the contact point on each surface
    in its own body frame, the outward normals there opposite in the world."""

    name: str
    orientations: tuple[tuple, tuple]
    points: tuple[np.ndarray, np.ndarray]


def tangent_configurations(body1: Body, body2: Body) -> tuple[Configuration, ...]:
    """Peng 2020 Figure 2 with the surfaces tangent at the contact, and the coaxial tips.

    (A) body 2 across body 1's tip: the paper's orthogonal tip-to-tip placement cannot be a
    tangent contact of smooth bodies (the tips' normals are x and z), so body 2 keeps the
    paper's orientation and touches the tip with its side (lever arm c₂). (B) body 2 standing
    on its tip on body 1's face. (C) body 2 on its side on that face. (tips) the two long axes
    in line, tip on tip, axes parallel: the largest |ẍ_c| of Appendix A's Figure A4, and the
    largest mobility of any tangent contact of two equal ellipsoids found.

    Empty unless both bodies are ellipsoids: at an axis tip a superquadric has a flat face
    (ε < 1) or a vertex (ε > 1), where two bodies meet in a patch or without one normal, and
    no point contact can be solved for.
    """
    if any(e != 1.0 for body in (body1, body2) for e in body.surface[3:]):
        return ()
    a1, _, c1 = body1.surface[:3]
    a2, b2, c2 = body2.surface[:3]
    return (
        Configuration("A", (IDENTITY, STANDING), (np.array([a1, 0, 0.0]), np.array([0, 0, -c2]))),
        Configuration("B", (IDENTITY, STANDING), (np.array([0, 0, c1]), np.array([a2, 0, 0.0]))),
        Configuration("C", (IDENTITY, ON_SIDE), (np.array([0, 0, c1]), np.array([0, -b2, 0.0]))),
        Configuration(
            "tips", (IDENTITY, IDENTITY), (np.array([a1, 0, 0.0]), np.array([-a2, 0, 0]))
        ),
    )


def _surface(body: Body) -> np.ndarray:
    return np.array(body.surface, dtype=float)


def surface_point(body: Body, direction) -> tuple[np.ndarray, np.ndarray]:
    """The surface point along `direction` from the centre and its outward unit normal (body
    frame): G is homogeneous of degree two, so the point is d / √G(d)."""
    direction = np.asarray(direction, dtype=float)
    value = kernel.shape_function(_surface(body), direction)[0]
    point = direction / math.sqrt(value)
    gradient = kernel.shape_function(_surface(body), point)[1]
    return point, gradient / np.linalg.norm(gradient)


def random_configurations(body1: Body, body2: Body, count: int, seed: int):
    """`count` configurations: uniform random orientation of body 1, random contact points on
    both surfaces, body 2 turned so its normal opposes body 1's, then spun about it at random."""
    rng = np.random.default_rng(seed)
    drawn = []
    for i in range(count):
        q1 = rng.normal(size=4)
        q1 /= np.linalg.norm(q1)
        point1, normal1 = surface_point(body1, rng.normal(size=3))
        point2, normal2 = surface_point(body2, rng.normal(size=3))
        normal = matrix(q1) @ normal1
        spin = axis_angle(normal, rng.uniform(0.0, 2.0 * math.pi))
        q2 = compose(spin, aligning(normal2, -normal))
        drawn.append(Configuration(f"random {i + 1}", (tuple(q1), q2), (point1, point2)))
    return tuple(drawn)


@dataclass(frozen=True)
class Pair:
    """The compiled integrator's arrays for one configuration, at the start of every trial."""

    bodies: tuple[np.ndarray, ...]
    law: np.ndarray
    shapes: np.ndarray
    moments: np.ndarray
    masses: np.ndarray
    anchors: np.ndarray
    solution: np.ndarray

    def arguments(self):
        """The kernel's arguments for a fresh trial: copies of what a trial changes."""
        return (
            tuple(a.copy() for a in self.bodies),
            np.zeros((2, 2, 3)),
            self.law,
            self.shapes,
            self.moments,
            self.masses,
            self.anchors,
            self.solution.copy(),
        )


def place(body1: Body, body2: Body, configuration: Configuration, law) -> Pair:
    """Body 1 at the origin, body 2 tangent to it at the configuration's contact point, then
    moved by DISPLACEMENT along KICK_DIRECTION; both at rest."""
    rotations = [matrix(q) for q in configuration.orientations]
    contact = rotations[0] @ configuration.points[0]
    size = max(body1.surface[0:3] + body2.surface[0:3])
    positions = np.array([np.zeros(3), contact - rotations[1] @ configuration.points[1]])
    positions[1] += DISPLACEMENT * size * KICK_DIRECTION
    bodies = (
        positions,
        np.zeros((2, 3)),
        np.array(configuration.orientations, dtype=float),
        np.zeros((2, 3)),
    )
    shapes = np.array([_surface(body1), _surface(body2)])
    try:
        solution = kernel.cold_contact(shapes, positions, np.array(rotations))
    except np.linalg.LinAlgError:  # a singular Newton matrix: no unique contact point
        raise ContactLost(configuration.name) from None
    return Pair(
        bodies=bodies,
        law=np.asarray(law, dtype=float),
        shapes=shapes,
        moments=np.array([body1.axis_moments, body2.axis_moments]),
        masses=np.array([body1.mass, body2.mass]),
        anchors=np.array(configuration.points, dtype=float),
        solution=solution,
    )


def bonded_law(contact: Contact) -> np.ndarray:
    """The kernel's law row: k_n, k_s, c_n, c_s, bonded, blow-up size."""
    return np.array([contact.kn, contact.ks, contact.cn, contact.cs, 1.0, BLOW_UP])


class ContactLost(RunFailed):
    """The contact solver could not follow a configuration's contact: a flat face on a flat
    face, an edge or a vertex, where the surfaces meet in more than one point or without
    one normal."""

    def __init__(self, name: str):
        super().__init__(f"rigid pair, configuration {name}: the contact solver lost the contact")
        self.configuration = name


def is_stable(pair: Pair, dt: float, name: str) -> bool:
    """Whether the pair's contact stays bounded over STEPS steps of dt."""
    try:
        status, early, late = kernel.stability_trial(*pair.arguments(), dt, STEPS)
    except np.linalg.LinAlgError:  # a singular Newton matrix: no unique contact point
        raise ContactLost(name) from None
    if status == kernel.NOT_CONVERGED:
        raise ContactLost(name)
    return status == kernel.STABLE and late <= GROWTH * early


def configuration_limit(body1: Body, body2: Body, contact: Contact, configuration) -> float:
    """Largest stable Δt of the pair integrated from one configuration."""
    pair = place(body1, body2, configuration, bonded_law(contact))
    guess = 1.0 / math.sqrt(max(contact.kn, contact.ks) * a_max(body1, body2))
    return largest_stable_dt(
        lambda dt: is_stable(pair, dt, configuration.name), guess, BISECTION_RTOL
    )


def _limit_or_lost(body1, body2, contact, configuration) -> float | None:
    """`configuration_limit`, or None where the solver lost the contact."""
    try:
        return configuration_limit(body1, body2, contact, configuration)
    except ContactLost:
        return None


def rigid_body_limits(
    body1: Body, body2: Body, contact: Contact, draws: int = DRAWS, seed: int = SEED
) -> dict[str, float | None] | None:
    """The integrated limit of each tangent configuration and of each of `draws` random ones
    (seeded), None for one whose contact the solver lost (see `ContactLost`); None unless
    both bodies are superquadrics (ellipsoids and spheres included) with exponents below 2
    (at 2 the surface has edges: no normal there)."""
    if body1.surface is None or body2.surface is None:
        return None
    if any(e >= 2.0 for body in (body1, body2) for e in body.surface[3:]):
        return None
    configurations = tangent_configurations(body1, body2) + random_configurations(
        body1, body2, draws, seed
    )
    return {c.name: _limit_or_lost(body1, body2, contact, c) for c in configurations}


def rigid_body_limit(body1: Body, body2: Body, contact: Contact) -> float | None:
    """Smallest integrated limit over the tangent and DRAWS random configurations (seed SEED)
    whose contact the solver followed; None where there is none."""
    limits = rigid_body_limits(body1, body2, contact)
    found = [dt for dt in (limits or {}).values() if dt is not None]
    return min(found) if found else None
