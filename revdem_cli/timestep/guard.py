"""Critical time step of a sphere scenario, estimated from its input before it runs.

Every contact is bounded by the two-body limit of velocity Verlet, 2/√(kA) undamped (Peng
2020 Eq 47; for two spheres Eq 49, confirmed on the engine by `engine_pair`), taken with
the smallest particle mass and the stiffest contact the scenario can form:

- a sphere pair has A_n = 1/m₁ + 1/m₂ ≤ 2/m_min; a sphere on a wall, which does not move
  under forces, has A_n = 1/m, the sphere's own mass;
- across the contact, shear springs act with A_t = 7/2 A_n (Peng 2020 Eq 26, I = 2/5 m r²);
- a linear contact has its given k_n, k_s. A Hertz contact stiffens as it closes: its
  stiffness is taken at the largest overlap of a head-on impact at the largest approach
  speed the scenario allows. Hanley 2020 §3.2.1 quotes 325 µs for its collision at about
  1 m/s, from Burns, Piiroinen & Hanley 2019 (its ref 22); this estimate gives 480 µs there,
  the same order. Hertz scenarios also get the Rayleigh time step; the smaller is returned.

The approach speed of a particle is its starting speed, raised by a free fall onto each
plane wall from its starting gap (the normal component of gravity); a pair approaches at
most at the sum of the two largest such speeds, a wall at a particle's plus the wall's own.
Speed gained by sliding down an inclined wall, or from stored elastic energy, is not
bounded; several contacts on one particle lower the limit further, to no less than 1/√12
of it among equal spheres (`CROWDED`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from revdem_cli import laws
from revdem_cli.config import Material, Scenario
from revdem_cli.kernels.contact import reduced, viscous_coefficient
from revdem_cli.state import pair_moduli, sphere_masses
from revdem_cli.timestep.criteria import dt_damped

SHEAR_LEVER = 3.5  # A_t / A_n of a sphere contact: 1 + r²/(2/5 r²) (Peng 2020 Eq 26)

CROWDED = 12
"""The most equal spheres that touch one. The start-up estimate is one contact's limit; Z
contacts on a sphere, each no stiffer, raise the largest eigenvalue of M⁻¹K at most Z times
(normal springs, Gershgorin's theorem by 3 x 3 blocks: 2Zk/m against a pair's 2k/m), so a
packing's limit lies above 1/√Z of it: 0.29 for Z = 12 (measured: 1/2 in an fcc lattice,
1/2.6 in a dense random packing)."""


@dataclass(frozen=True)
class Kind:
    """The most demanding contact of one kind (sphere pair or sphere on a wall)."""

    name: str
    inverse_mass: float  # A_n, 1/kg
    rstar: float  # effective radius, m
    estar: float  # largest effective Young's modulus, Pa
    gstar: float  # largest effective shear modulus, Pa
    speed: float  # largest approach speed, m/s
    inverse_inertia: float  # A_r of the rolling spring: 1/I_1 + 1/I_2, or 1/I on a wall, 1/(kg m²)


def rayleigh_dt(radius: float, material: Material) -> float:
    """Rayleigh time step: the time a Rayleigh wave takes to cross half the sphere."""
    nu = material.poisson_ratio
    # dt_r of the LIGGGHTS documentation, fix check/timestep/gran (Rayleigh-wave speed fit)
    return (
        math.pi
        * radius
        * math.sqrt(material.density / material.shear_modulus)
        / (0.1631 * nu + 0.8766)
    )


def rayleigh_limit(scenario: Scenario) -> float:
    """The smallest Rayleigh time step of the scenario's spheres, each material's smallest."""
    spheres = scenario.spheres
    return min(
        rayleigh_dt(float(spheres.radius[spheres.material == k].min()), material)
        for k, material in enumerate(scenario.materials.values())
        if (spheres.material == k).any()
    )


def head_on_limit(scenario: Scenario) -> float:
    """The smallest two-body limit of the scenario's kinds of contact at their head-on impact
    stiffness (`contact_dt`); ∞ without contacts."""
    return min((contact_dt(scenario, kind) for kind in contact_kinds(scenario)), default=math.inf)


def particle_speeds(scenario: Scenario) -> np.ndarray:
    """Largest speed of each particle on reaching a plane wall: starting speed plus free fall
    along the wall's normal from the starting gap, v² = |v₀|² + 2 g_n gap (as hypotenuses,
    which do not overflow)."""
    spheres = scenario.spheres
    v = spheres.velocity
    speed = np.hypot(np.hypot(v[:, 0], v[:, 1]), v[:, 2])
    gravity = np.array(scenario.gravity, dtype=float)
    fall = np.zeros(len(speed))  # the largest 2 g_n gap
    for wall in (w for w in scenario.walls if w.type == "plane"):
        normal = np.array(wall.normal, dtype=float) / math.hypot(*wall.normal)
        toward = max(0.0, -float(gravity @ normal))  # gravity's component towards the plane
        gap = (spheres.position - np.array(wall.point)) @ normal - spheres.radius
        fall = np.maximum(fall, 2.0 * toward * gap)
    return np.hypot(speed, np.sqrt(fall))


def kinematic_dt(scenario: Scenario) -> tuple[float, str]:
    """The largest Δt at which no sphere moves more than half the neighbour skin in a step,
    and one line on it: PFC's kinematic constraint (Peng 2020 §1). The pair list is rebuilt
    once spheres may have closed half the skin; a sphere faster than this could pass a
    contact, or another sphere, between two checks. Speeds as `particle_speeds`, and the
    walls' own in every stage."""
    from revdem_cli.state import default_skin

    if scenario.sphere_count < 2 and not scenario.walls:
        return math.inf, "one sphere and no walls: no contact to miss"
    walls = [w.velocity for w in scenario.walls]
    walls += [v for stage in scenario.stages for v in stage.wall_velocities.values()]
    fastest = max([float(particle_speeds(scenario).max())] + [math.hypot(*v) for v in walls])
    if fastest == 0.0:
        return math.inf, "nothing moves at the start"
    half_skin = 0.5 * default_skin(scenario)
    return half_skin / fastest, (
        f"the fastest sphere or wall, at {fastest:.3g} m/s, would move more than half the "
        f"neighbour skin ({half_skin:.3g} m) in a step, and contacts could be missed"
    )


def _largest_moduli(scenario: Scenario, pairs) -> tuple[float, float]:
    both = [pair_moduli(scenario, a, b) for a, b in pairs]
    return max(e for e, _ in both), max(g for _, g in both)


def contact_kinds(scenario: Scenario) -> list[Kind]:
    """The sphere pair (two or more particles) and the sphere on a wall (any wall)."""
    spheres = scenario.spheres
    masses, inertias = sphere_masses(scenario)
    mass, inertia = float(masses.min()), float(inertias.min())
    radius = float(spheres.radius.max())
    used = set(spheres.material_names())
    speeds = np.sort(particle_speeds(scenario))[::-1]
    kinds = []
    if scenario.sphere_count > 1:
        moduli = _largest_moduli(scenario, [(a, b) for a in used for b in used])
        kinds.append(
            Kind(
                "sphere pair",
                2.0 / mass,  # A_n = 1/m + 1/m
                reduced(radius, radius),
                *moduli,
                float(speeds[0] + speeds[1]),
                2.0 / inertia,
            )
        )
    if scenario.walls:
        moduli = _largest_moduli(scenario, [(a, w.material) for a in used for w in scenario.walls])
        wall_speed = max(math.hypot(*w.velocity) for w in scenario.walls)
        kinds.append(
            Kind(
                "sphere on a wall",
                1.0 / mass,
                radius,
                *moduli,
                float(speeds[0]) + wall_speed,
                1.0 / inertia,
            )
        )
    return kinds


def impact_stiffness(scenario: Scenario, kind: Kind) -> tuple[float, float]:
    """(k_n, k_s) in N/m at the largest overlap of a head-on impact at kind.speed, from the
    scenario's laws (for Hertz, Hanley 2020 Eq 6 and 10); k_s = 0 without shear springs. The
    overlap stores the impact's kinetic energy, ½ m* v²."""
    contact = scenario.contact
    energy = 0.5 * kind.speed * kind.speed / kind.inverse_mass  # inf, not OverflowError
    overlap = laws.evaluate(contact, "normal", "impact_overlap", energy, kind.rstar, kind.estar)
    kn = laws.evaluate(contact, "normal", "force", overlap, kind.rstar, kind.estar)[1]
    if laws.chosen(contact, "tangential") is None:
        return kn, 0.0
    return kn, laws.evaluate(contact, "tangential", "stiffness", overlap, kind.rstar, kind.gstar)


def _limit(
    stiffness: float, beta: float, inverse_mass: float, reduced_mass: float, order: int = 0
) -> float:
    """Velocity-Verlet limit of one direction; damping β × 2√(m* k) as the engine applies it,
    read from the half-step velocity or (order > 0) from the velocity predictor's."""
    if stiffness == 0.0:
        return math.inf
    damping = viscous_coefficient(beta, reduced_mass, stiffness)
    return dt_damped(stiffness, damping, inverse_mass, order)  # Peng 2020 Eq 30, 47


def largest_damping(scenario: Scenario) -> tuple[float, float]:
    """The largest viscous normal and tangential damping of any stage, its own
    (`stages[].contact`) or [contact]'s: the damped limit falls as the damping rises, so these
    bound every stage."""
    law = scenario.contact
    own = [stage.contact for stage in scenario.stages if stage.contact is not None]
    normal = [law.normal_damping] + [c.normal_damping for c in own if c.normal_damping is not None]
    tangential = [law.tangential_damping] + [
        c.tangential_damping for c in own if c.tangential_damping is not None
    ]
    return max(normal), max(tangential)


def contact_dt(scenario: Scenario, kind: Kind) -> float:
    """Two-body limit of one kind of contact: the smallest of its normal and shear
    directions, at the largest viscous damping of any stage, and, with a rolling law, its
    rolling spring on the bodies' rotations."""
    kn, ks = impact_stiffness(scenario, kind)
    law, mstar = scenario.contact, 1.0 / kind.inverse_mass
    order = scenario.integrator.predictor_order
    normal_damping, tangential_damping = largest_damping(scenario)
    limits = [
        _limit(kn, normal_damping, kind.inverse_mass, mstar, order),
        _limit(ks, tangential_damping, SHEAR_LEVER * kind.inverse_mass, mstar, order),
    ]
    if laws.chosen(law, "rolling") is not None:
        kr = laws.evaluate(law, "rolling", "stiffness", 0.0, kind.rstar)
        limits.append(_limit(kr, 0.0, kind.inverse_inertia, 0.0))
    return min(limits)


def critical_time_step(scenario: Scenario) -> tuple[float, str]:
    """Estimated critical Δt (s) of a sphere scenario and one line on where it comes from."""
    estimates = {kind.name: (contact_dt(scenario, kind), kind) for kind in contact_kinds(scenario)}
    if not estimates:
        return math.inf, "one particle and no walls: no contact, no stability limit"
    name, (contact, kind) = min(estimates.items(), key=lambda item: item[1][0])
    shear = "" if scenario.contact.tangential == "none" else " with shear springs"
    order = scenario.integrator.predictor_order
    if order:
        shear += f" (damping read from the velocity predictor of order {order})"
    normal = laws.chosen(scenario.contact, "normal")
    if not normal.FROM_MATERIALS:
        return contact, (
            f"{normal.NAME} contact: {contact:.3g} s, the velocity-Verlet limit of a {name}{shear} "
            f"(Peng 2020 Eq 47-49) with the smallest particle mass"
        )
    rayleigh = rayleigh_limit(scenario)
    return min(rayleigh, contact), (
        f"{normal.NAME.capitalize()} contact: the smaller of the Rayleigh time step "
        f"{rayleigh:.3g} s and {contact:.3g} s, the velocity-Verlet limit of a {name}{shear} at "
        f"the {normal.NAME.capitalize()} stiffness of a head-on impact at {kind.speed:.3g} m/s "
        f"(Peng 2020 Eq 47, {normal.EQUATION.split(' (')[0]})"
    )


def times_above(ratio: float) -> str:
    """A ratio above 1 with as many digits as show it above 1 (1.005, where 3 digits said
    1, as if the time step were at its limit, not above it)."""
    for digits in range(3, 18):
        text = f"{ratio:.{digits}g}"
        if float(text) > 1.0:
            break
    return text


@dataclass(frozen=True)
class Excess:
    """A time step above a limit: the field that sets it, its value, the limit's name and
    value (s), and where the limit comes from."""

    field: str
    dt: float
    limit_name: str
    limit: float
    reason: str

    def __str__(self) -> str:
        times = f"{times_above(self.dt / self.limit)} times" if self.limit > 0.0 else "above"
        return (
            f"{self.field} = {self.dt:.3g} s is {times} the {self.limit_name} {self.limit:.3g} s "
            f"({self.reason})"
        )


def time_step_excess(scenario: Scenario) -> Excess | None:
    """The largest time step the scenario sets (integrator.dt or a stage's; 'auto' is below
    both limits) where it is above the critical estimate or the kinematic limit; None where
    it is not."""
    steps = [("integrator.dt", scenario.integrator.dt)] + [
        (f"stages[{i}].dt", stage.dt) for i, stage in enumerate(scenario.stages) if stage.dt
    ]
    steps = [(field, dt) for field, dt in steps if dt != "auto"]
    if not steps:
        return None
    field, dt = max(steps, key=lambda item: item[1])
    limits = [
        ("critical time step", *critical_time_step(scenario)),
        ("kinematic limit", *kinematic_dt(scenario)),
    ]
    if limits[0][1] == 0.0:  # speeds so high that no contact law bounds them: say so
        limits.reverse()
    for name, limit, reason in limits:
        if dt > limit:
            return Excess(field, dt, name, limit, reason)
    return None
