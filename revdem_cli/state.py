"""The simulation state: struct-of-arrays numpy bundles, built from a scenario or a restart."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from revdem_cli.config import Material, Scenario
from revdem_cli.kernels import contact
from revdem_cli.kernels.arrays import ContactLaw, Pairs, Particles
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


def contact_law(scenario: Scenario) -> ContactLaw:
    materials = list(scenario.materials.values())
    estar = np.array([[effective_modulus(a, b) for b in materials] for a in materials])
    law = scenario.contact
    model = contact.LINEAR if law.model == "linear" else contact.HERTZ
    return ContactLaw(model, float(law.kn or 0.0), estar)


def particles(scenario: Scenario) -> Particles:
    names = list(scenario.materials)
    ps = scenario.particles
    radius = np.array([p.radius for p in ps], dtype=np.float64)
    density = np.array([scenario.materials[p.material].density for p in ps])
    mass = 4.0 / 3.0 * np.pi * radius**3 * density
    inertia = 0.4 * mass * radius**2  # solid sphere, I = 2/5 m r^2 (Hanley 2020 §2)
    return Particles(
        x=np.array([p.position for p in ps], dtype=np.float64),
        v=np.array([p.velocity for p in ps], dtype=np.float64),
        omega=np.array([p.angular_velocity for p in ps], dtype=np.float64),
        f=np.zeros((len(ps), 3)),
        torque=np.zeros((len(ps), 3)),
        radius=radius,
        mass=mass,
        inertia=inertia,
        inv_mass=1.0 / mass,
        inv_inertia=1.0 / inertia,
        material=np.array([names.index(p.material) for p in ps], dtype=np.int64),
    )


def empty_pairs(n_particles: int, capacity: int) -> Pairs:
    return Pairs(
        count=np.zeros(2, dtype=np.int64),
        i=np.zeros(capacity, dtype=np.int64),
        j=np.zeros(capacity, dtype=np.int64),
        history=np.zeros((capacity, 3)),
        force=np.zeros((capacity, 3)),
        energy=np.zeros(capacity),
        start=np.zeros(n_particles + 1, dtype=np.int64),
        slots=np.zeros(2 * capacity, dtype=np.int64),
        x_built=np.zeros((n_particles, 3)),
        new_i=np.zeros(capacity, dtype=np.int64),
        new_j=np.zeros(capacity, dtype=np.int64),
        new_history=np.zeros((capacity, 3)),
    )


def grown(pairs: Pairs, capacity: int) -> Pairs:
    """A copy of `pairs` with room for `capacity` pairs; the listed pairs and history kept."""
    bigger = empty_pairs(pairs.start.shape[0] - 1, capacity)
    n = int(pairs.count[0])
    bigger.count[:] = pairs.count
    for name in ("i", "j", "history", "force", "energy"):
        getattr(bigger, name)[:n] = getattr(pairs, name)[:n]
    bigger.start[:] = pairs.start
    bigger.slots[: 2 * n] = pairs.slots[: 2 * n]
    bigger.x_built[:] = pairs.x_built
    return bigger


@dataclass
class State:
    """Everything that evolves: particles, pair list with history, step counter."""

    particles: Particles
    pairs: Pairs
    step: int

    def rebuild_pairs(self, skin: float) -> None:
        """Rebuild the pair list now, growing it until it fits."""
        while not rebuild_pairs(self.particles, self.pairs, skin):
            self.grow_pairs()

    def grow_pairs(self) -> None:
        needed = int(self.pairs.count[1])
        self.pairs = grown(self.pairs, max(2 * self.pairs.i.shape[0], needed + needed // 4 + 16))


def initial_state(scenario: Scenario, law: ContactLaw, gravity: np.ndarray, skin: float) -> State:
    """The state at step 0 with its pair list and the forces at the initial positions."""
    p = particles(scenario)
    state = State(p, empty_pairs(len(p.x), 8 * len(p.x) + 16), step=0)
    state.rebuild_pairs(skin)
    compute_forces(state.particles, state.pairs, law, gravity)
    return state


def default_skin(scenario: Scenario) -> float:
    """Neighbour skin: as given, else 10 % of the largest radius."""
    return scenario.neighbours.skin or 0.1 * max(p.radius for p in scenario.particles)
