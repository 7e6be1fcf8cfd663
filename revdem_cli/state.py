"""The simulation state: struct-of-arrays numpy bundles, built from a scenario or a restart."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from revdem_cli.config import Damping, Material, Scenario
from revdem_cli.kernels import contact, walls
from revdem_cli.kernels.arrays import ContactLaw, Dynamics, Moduli, Pairs, Particles, Walls
from revdem_cli.kernels.events import COLUMNS, KINDS
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.integrate import rebuild_pairs


def youngs_modulus(material: Material) -> float:
    """E = 2G(1 + nu) (isotropic elasticity)."""
    return 2.0 * material.shear_modulus * (1.0 + material.poisson_ratio)


def effective_modulus(a: Material, b: Material) -> float:
    """1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b (Hertz; for equal materials E* = G/(1 - nu),
    which gives Hanley 2020's H = 4G/(3(1 - nu)) sqrt(R*) in Eq 6)."""
    return 1.0 / (
        (1.0 - a.poisson_ratio**2) / youngs_modulus(a)
        + (1.0 - b.poisson_ratio**2) / youngs_modulus(b)
    )


def effective_shear_modulus(a: Material, b: Material) -> float:
    """1/G* = (2 - nu_a)/G_a + (2 - nu_b)/G_b (Mindlin; for equal materials 8 G* sqrt(R* d)
    equals Hanley 2020's H^s = H^n sqrt(d) 3(1 - nu)/(2 - nu) in Eq 10)."""
    return 1.0 / (
        (2.0 - a.poisson_ratio) / a.shear_modulus + (2.0 - b.poisson_ratio) / b.shear_modulus
    )


_TANGENTIAL = {"none": contact.NO_SHEAR, "linear": contact.LINEAR_SHEAR, "mindlin": contact.MINDLIN}


def moduli(scenario: Scenario) -> Moduli:
    """E* and G* of every pair of materials, in the order of [materials]."""
    ms = list(scenario.materials.values())
    return Moduli(
        estar=np.array([[effective_modulus(a, b) for b in ms] for a in ms]),
        gstar=np.array([[effective_shear_modulus(a, b) for b in ms] for a in ms]),
    )


def contact_law(scenario: Scenario) -> ContactLaw:
    law = scenario.contact
    return ContactLaw(
        model=contact.LINEAR if law.model == "linear" else contact.HERTZ,
        kn=float(law.kn or 0.0),
        tangential=_TANGENTIAL[law.tangential],
        ks=float(law.ks or 0.0),
        mu=math.inf if law.friction is None else float(law.friction),
        beta_n=law.normal_damping,
        beta_t=law.tangential_damping,
    )


def dynamics(scenario: Scenario, damping: Damping | None = None) -> Dynamics:
    """Gravity and damping: `damping` if given (a stage's), else the scenario's."""
    damping = damping or scenario.damping
    return Dynamics(np.array(scenario.gravity, dtype=np.float64), damping.local, damping.drag)


def particles(scenario: Scenario) -> Particles:
    names = list(scenario.materials)
    ps = scenario.spheres
    n = len(ps)
    radius = np.array([p.radius for p in ps], dtype=np.float64)
    density = np.array([scenario.materials[p.material].density for p in ps])
    mass = 4.0 / 3.0 * np.pi * radius**3 * density
    inertia = 0.4 * mass * radius**2  # solid sphere, I = 2/5 m r^2 (Hanley 2020 §2)
    return Particles(
        x=np.array([p.position for p in ps], dtype=np.float64),
        v=np.array([p.velocity for p in ps], dtype=np.float64),
        omega=np.array([p.angular_velocity for p in ps], dtype=np.float64),
        f=np.zeros((n, 3)),
        torque=np.zeros((n, 3)),
        radius=radius,
        mass=mass,
        inertia=inertia,
        inv_mass=1.0 / mass,
        inv_inertia=1.0 / inertia,
        material=np.array([names.index(p.material) for p in ps], dtype=np.int64),
        v_drift=np.full((n, 3), np.nan),
    )


def wall_arrays(scenario: Scenario, n_particles: int) -> Walls:
    names = list(scenario.materials)
    ws = scenario.walls
    count = len(ws)
    axis = np.array([w.normal for w in ws], dtype=np.float64).reshape(count, 3)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    point = np.array([w.point for w in ws], dtype=np.float64).reshape(count, 3)
    per_contact = np.zeros((n_particles, count, 3))
    per_contact_scalar = np.zeros((n_particles, count))
    return Walls(
        kind=np.array(
            [walls.CYLINDER if w.type == "cylinder" else walls.PLANE for w in ws], dtype=np.int64
        ),
        point=point,
        origin=point.copy(),
        axis=axis,
        radius=np.array([w.radius or 0.0 for w in ws], dtype=np.float64),
        velocity=np.array([w.velocity for w in ws], dtype=np.float64).reshape(count, 3),
        material=np.array([names.index(w.material) for w in ws], dtype=np.int64),
        history=per_contact.copy(),
        force=per_contact.copy(),
        torque=per_contact.copy(),
        normal=per_contact_scalar.copy(),
        energy=per_contact_scalar.copy(),
        slip=per_contact_scalar.copy(),
        lost=per_contact_scalar.copy(),
        pending=per_contact.copy(),
        normal_new=per_contact.copy(),
    )


_PAIR_VECTORS = ("history", "force", "torque_i", "torque_j", "pending", "normal_new", "new_history")
_PAIR_SCALARS = ("normal", "energy", "slip", "lost")
_PAIR_INDICES = ("i", "j", "new_i", "new_j")


def pair_capacity(n_particles: int, at_least: int = 0) -> int:
    """Room for the pairs of a new list: 8 per particle (a dense packing lists about 7 with
    the default skin), and at least `at_least`."""
    return max(8 * n_particles + 16, at_least)


def empty_pairs(n_particles: int, capacity: int) -> Pairs:
    arrays = {name: np.zeros((capacity, 3)) for name in _PAIR_VECTORS}
    arrays |= {name: np.zeros(capacity) for name in _PAIR_SCALARS}
    arrays |= {name: np.zeros(capacity, dtype=np.int64) for name in _PAIR_INDICES}
    return Pairs(
        count=np.zeros(2, dtype=np.int64),
        start=np.zeros(n_particles + 1, dtype=np.int64),
        slots=np.zeros(2 * capacity, dtype=np.int64),
        x_built=np.zeros((n_particles, 3)),
        **arrays,
    )


def grown(pairs: Pairs, capacity: int) -> Pairs:
    """A copy of `pairs` with room for `capacity` pairs; the listed pairs and history kept."""
    bigger = empty_pairs(pairs.start.shape[0] - 1, capacity)
    n = int(pairs.count[0])
    for name in _PAIR_VECTORS + _PAIR_SCALARS + _PAIR_INDICES:
        getattr(bigger, name)[:n] = getattr(pairs, name)[:n]
    bigger.count[:] = pairs.count
    bigger.start[:] = pairs.start
    bigger.slots[: 2 * n] = pairs.slots[: 2 * n]
    bigger.x_built[:] = pairs.x_built
    return bigger


def empty_events() -> np.ndarray:
    return np.zeros((len(KINDS), len(COLUMNS)))


@dataclass
class State:
    """Everything that evolves: particles, pair list with history, walls, step counter."""

    particles: Particles
    pairs: Pairs
    walls: Walls
    step: int

    def rebuild_pairs(self, skin: float) -> None:
        """Rebuild the pair list now, growing it until it fits."""
        while not rebuild_pairs(self.particles, self.pairs, skin):
            self.grow_pairs()

    def grow_pairs(self) -> None:
        needed = int(self.pairs.count[1])
        self.pairs = grown(self.pairs, max(2 * self.pairs.i.shape[0], needed + needed // 4 + 16))


def initial_state(scenario: Scenario) -> State:
    """The state at step 0 with its pair list and the forces at the initial positions."""
    p = particles(scenario)
    state = State(
        p, empty_pairs(len(p.x), pair_capacity(len(p.x))), wall_arrays(scenario, len(p.x)), step=0
    )
    state.rebuild_pairs(default_skin(scenario))
    compute_forces(
        state.particles,
        state.pairs,
        state.walls,
        contact_law(scenario),
        moduli(scenario),
        dynamics(scenario),
        contact.STATIC,
        scenario.integrator.dt,
    )
    return state


def default_skin(scenario: Scenario) -> float:
    """Neighbour skin: as given, else 10 % of the largest radius."""
    return scenario.neighbours.skin or 0.1 * max(p.radius for p in scenario.spheres)
