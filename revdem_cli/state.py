"""The simulation state: struct-of-arrays numpy bundles, built from a scenario or a restart."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from revdem_cli import laws, wall_shapes
from revdem_cli.config import Damping, Material, Scenario
from revdem_cli.errors import RunFailed
from revdem_cli.kernels import cell, contact, fixed, health
from revdem_cli.kernels.arrays import (
    Cell,
    ContactLaw,
    Dynamics,
    Fixed,
    Moduli,
    Pairs,
    Particles,
    Walls,
)
from revdem_cli.kernels.events import COLUMNS, KINDS
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.integrate import OK, PAIR_OVERFLOW, rebuild_pairs
from revdem_cli.kernels.neighbours import build_pairs
from revdem_cli.kernels.pairs import MISSED_COLUMNS, empty_balance, empty_blocks
from revdem_cli.kernels.sums import empty_partials
from revdem_cli.memory import release_freed_memory, untouched


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
    equals H^s = H^n sqrt(d) 3(1 - nu)/(2 - nu), Hanley 2020 Eq 10 with its factor outside the
    root, as `laws.mindlin` says)."""
    return 1.0 / (
        (2.0 - a.poisson_ratio) / a.shear_modulus + (2.0 - b.poisson_ratio) / b.shear_modulus
    )


def pair_moduli(scenario: Scenario, a: str, b: str) -> tuple[float, float]:
    """(E*, G*) of a contact between materials a and b (names). With contact.wall_moduli =
    'wall', a contact with a wall's material takes that material alone: E* = G/(1 - nu) and
    G* = G/(2(2 - nu)) of the wall, Hanley 2020 Eq 6 and 10 with the wall's G and nu."""
    if scenario.contact.wall_moduli == "wall":
        walls = {w.material for w in scenario.walls}
        a, b = (b, b) if b in walls else (a, a) if a in walls else (a, b)
    ma, mb = scenario.materials[a], scenario.materials[b]
    return effective_modulus(ma, mb), effective_shear_modulus(ma, mb)


def moduli(scenario: Scenario) -> Moduli:
    """E* and G* of every pair of materials, in the order of [materials]."""
    names = list(scenario.materials)
    table = np.array([[pair_moduli(scenario, a, b) for b in names] for a in names])
    return Moduli(
        estar=np.ascontiguousarray(table[:, :, 0]), gstar=np.ascontiguousarray(table[:, :, 1])
    )


def contact_law(scenario: Scenario) -> ContactLaw:
    """The compiled record of the scenario's contact: its laws by number, the Coulomb and
    viscous coefficients, the histories' and the forces' grids in fixed-point arithmetic,
    and every law's parameters."""
    spec = scenario.contact
    on_grid = scenario.integrator.arithmetic == "fixed"
    return ContactLaw(
        laws.number("normal", spec.model),
        laws.number("tangential", spec.tangential),
        laws.number("rolling", spec.rolling),
        math.inf if spec.friction is None else float(spec.friction),
        spec.normal_damping,
        spec.tangential_damping,
        2.0**-fixed.HISTORY_BITS if on_grid else 0.0,
        float(fixed_grid(scenario)[fixed.FORCE]) if on_grid else 0.0,
        *laws.parameters(spec),
    )


def dynamics(scenario: Scenario, damping: Damping | None = None) -> Dynamics:
    """Gravity and damping: `damping` if given (a stage's), else the scenario's."""
    damping = damping or scenario.damping
    return Dynamics(np.array(scenario.gravity, dtype=np.float64), damping.local, damping.drag)


def uses_drag(scenario: Scenario) -> bool:
    """Whether drag acts in some stage (then each particle keeps its last drift velocity)."""
    dampings = [scenario.damping] + [s.damping for s in scenario.stages if s.damping]
    return any(d.drag != 1.0 for d in dampings)


def cell_deforms(scenario: Scenario) -> bool:
    """Whether an edge of the periodic cell moves in some stage."""
    return any(stage.cell is not None and stage.cell.moving() for stage in scenario.stages)


def sphere_masses(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Each sphere's mass 4/3 pi r^3 rho and moment of inertia I = 2/5 m r^2 (a solid
    sphere, Hanley 2020 §2), kg and kg m^2."""
    spheres = scenario.spheres
    radius = np.asarray(spheres.radius, dtype=np.float64)
    densities = np.array([m.density for m in scenario.materials.values()])
    mass = 4.0 / 3.0 * np.pi * radius**3 * densities[spheres.material]
    return mass, 0.4 * mass * radius**2


def particles(scenario: Scenario) -> Particles:
    spheres = scenario.spheres
    n = len(spheres)
    # the constants are the scenario's own arrays (never written), not copies of them
    radius = np.ascontiguousarray(spheres.radius, dtype=np.float64)
    mass, inertia = sphere_masses(scenario)
    x = spheres.position.copy()
    in_cell = scenario.cell is not None and cell_deforms(scenario)
    v = spheres.velocity.copy()
    omega = spheres.angular_velocity.copy()
    k = scenario.integrator.predictor_order
    return Particles(
        x=x,
        s=x / np.array(scenario.cell.size) if in_cell else np.zeros((0, 3)),
        v=v,
        omega=omega,
        f=np.zeros((n, 3)),
        torque=np.zeros((n, 3)),
        radius=radius,
        mass=mass,
        inertia=inertia,
        inv_mass=1.0 / mass,
        inv_inertia=1.0 / inertia,
        material=np.ascontiguousarray(spheres.material, dtype=np.int64),
        v_drift=np.full((n if uses_drag(scenario) else 0, 3), np.nan),
        # the predictor's start: the k half steps before the first taken at the starting
        # velocities, as if the spheres had moved at them until then (v_P(0) = v(0))
        v_past=np.repeat(v[None, :, :], k, axis=0),
        omega_past=np.repeat(omega[None, :, :], k, axis=0),
        v_pred=v.copy() if k else np.zeros((0, 3)),
        omega_pred=omega.copy() if k else np.zeros((0, 3)),
    )


def wall_arrays(scenario: Scenario, n_particles: int, reversing: bool = False) -> Walls:
    names = list(scenario.materials)
    ws = scenario.walls
    count = len(ws)
    axis = np.array([w.normal for w in ws], dtype=np.float64).reshape(count, 3)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    point = np.array([w.point for w in ws], dtype=np.float64).reshape(count, 3)
    unwinding = reversing and scenario.contact.tangential != "none"
    rolling = count_if(rolls(scenario), n_particles)
    return Walls(
        kind=np.array([wall_shapes.number(w.type) for w in ws], dtype=np.int64),
        point=point,
        origin=point.copy(),
        axis=axis,
        radius=np.array([w.radius or 0.0 for w in ws], dtype=np.float64),
        velocity=np.array([w.velocity for w in ws], dtype=np.float64).reshape(count, 3),
        material=np.array([names.index(w.material) for w in ws], dtype=np.int64),
        force=np.zeros((n_particles, count, 3)),
        torque=np.zeros((n_particles, count, 3)),
        overlap=np.zeros((n_particles, count)),
        history=np.zeros((n_particles, count, 3)),
        destroyed=np.zeros((n_particles, count)),
        rolling=np.zeros((rolling, count, 3)),
        rolled=np.zeros((rolling, count)),
        normal_new=np.zeros((n_particles if unwinding else 0, count, 3)),
    )


_SERVO = {"proportional": cell.PROPORTIONAL, "inertial": cell.INERTIAL}


def cell_arrays(scenario: Scenario) -> Cell:
    """The periodic cell of the scenario, its edges fixed until a stage moves them; without
    a [cell], a cell with no periodic axis (edges of 1 m, never used)."""
    spec = scenario.cell
    length = np.array(spec.size if spec else (1.0, 1.0, 1.0), dtype=np.float64)
    return Cell(
        periodic=np.full(3, 1 if spec else 0, dtype=np.int64),
        length=length,
        start=length.copy(),
        rate=np.zeros(3),
        mid=length.copy(),
        force=np.zeros(3),
        control=np.full(3, cell.FIXED, dtype=np.int64),
        target=np.zeros(3),
        built=length.copy(),
        stress=np.zeros((3, 3)),
        servo=_SERVO[spec.servo] if spec else cell.PROPORTIONAL,
        mass=float(spec.servo_mass or 0.0) if spec else 0.0,
        gain=float(spec.servo_gain or 0.0) if spec else 0.0,
    )


PAIR_HISTORY = ("history", "moment", "overlap", "destroyed", "rolling", "rolled")
"""The per-pair arrays a growing list carries over besides the pairs and their forces (those
a run does not need are empty)."""


def count_if(needed: bool, count: int) -> int:
    """The length of an array a run has only if it needs it."""
    return count if needed else 0


def rolls(scenario: Scenario) -> bool:
    """Whether the scenario's contacts have rolling resistance."""
    return scenario.contact.rolling != "none"


def turns(scenario: Scenario) -> bool:
    """Whether the pairs' histories turn with their contact planes by a rotation
    (`contact.turn_onto`), keeping the normals they turn from: fixed-point arithmetic with a
    tangential law."""
    return scenario.integrator.arithmetic == "fixed" and scenario.contact.tangential != "none"


def predicts(scenario: Scenario) -> bool:
    """Whether a forward pair loop may predict the histories its reversal would miss, for the
    information tape (`Pairs.earlier`): where the histories turn (`turns`), with a tape."""
    return turns(scenario) and scenario.reversal.tape


def pair_capacity(needed: int) -> int:
    """Room for a list of `needed` pairs: a sixteenth more, so that a few new contacts fit
    (a list that outgrows it grows by a quarter)."""
    return needed + needed // 16 + 16


def empty_pairs(
    n_particles: int,
    capacity: int,
    shear: bool,
    reversing: bool,
    rolling: bool,
    turning: bool,
    predicting: bool = False,
) -> Pairs:
    """A pair list with room for `capacity` pairs; shear state only with a tangential law,
    rolling state only with a rolling law, the unwinding normal only in a reversed run with a
    tangential law, the normals the histories turn from in place of the moments where they
    are `turning` (fixed point with a tangential law, `turns`), and the histories a tape's
    prediction finds only where it is `predicting` too (`predicts`)."""
    per_shear = count_if(shear, capacity)
    per_rolling = count_if(rolling, capacity)
    return Pairs(
        count=np.zeros(2, dtype=np.int64),
        i=np.zeros(capacity, dtype=np.int32),
        j=np.zeros(capacity, dtype=np.int32),
        force=np.zeros((capacity, 3)),
        history=np.zeros((per_shear, 3)),
        moment=np.zeros((0 if turning else per_shear, 3)),
        overlap=np.zeros(per_shear),
        destroyed=np.zeros(per_shear),
        rolling=np.zeros((per_rolling, 3)),
        rolled=np.zeros(per_rolling),
        normal_new=np.zeros((per_shear if reversing else 0, 3)),
        normal=np.zeros((per_shear if turning else 0, 3)),
        earlier=untouched((per_shear if predicting else 0, MISSED_COLUMNS)),
        first=np.zeros(n_particles + 1, dtype=np.int32),
        start=np.zeros(n_particles + 1, dtype=np.int32),
        slots=np.zeros(capacity, dtype=np.int32),
        x_built=np.zeros((n_particles, 3), dtype=np.float32),
        blocks=empty_blocks(numba.config.NUMBA_NUM_THREADS),
        foreign=np.zeros(n_particles, dtype=np.bool_),
        balance=empty_balance(numba.config.NUMBA_NUM_THREADS),
        partials=empty_partials(n_particles),
    )


def grown(pairs: Pairs, capacity: int) -> Pairs:
    """A copy of `pairs` with room for `capacity` pairs; the listed pairs, their histories,
    contact normals and the particle index kept. (A list always has room for some pairs, so
    its shear and rolling arrays are empty only without those laws.)"""
    bigger = empty_pairs(
        pairs.start.shape[0] - 1,
        capacity,
        shear=pairs.history.shape[0] > 0,
        reversing=pairs.normal_new.shape[0] > 0,
        rolling=pairs.rolling.shape[0] > 0,
        turning=pairs.normal.shape[0] > 0,
        predicting=pairs.earlier.shape[0] > 0,
    )
    n = int(pairs.count[0])
    for name in ("i", "j", "force", "normal") + PAIR_HISTORY:
        if getattr(pairs, name).shape[0] > 0:
            getattr(bigger, name)[:n] = getattr(pairs, name)[:n]
    bigger.count[:] = pairs.count
    bigger.first[:] = pairs.first
    bigger.start[:] = pairs.start
    bigger.slots[:n] = pairs.slots[:n]
    bigger.x_built[:] = pairs.x_built
    bigger.balance[:] = pairs.balance
    return bigger


def empty_events() -> np.ndarray:
    return np.zeros((len(KINDS), len(COLUMNS)))


@dataclass
class State:
    """Everything that evolves: particles, pair list with history, walls, cell, the integer
    state of fixed-point arithmetic, step; and each sphere's id, which outputs carry
    (`Spheres.id`)."""

    particles: Particles
    pairs: Pairs
    walls: Walls
    cell: Cell
    fixed: Fixed
    ids: np.ndarray
    step: int

    def rebuild_pairs(self, skin: float) -> None:
        """Rebuild the pair list now, growing it until it fits."""
        while (status := rebuild_pairs(self.particles, self.pairs, self.cell, skin)) != OK:
            if status != PAIR_OVERFLOW:
                raise CellTooSmall(self.step, self.cell.length)
            self.grow_pairs()

    def grow_pairs(self) -> None:
        needed = int(self.pairs.count[1])
        self.pairs = grown(self.pairs, max(self.pairs.i.shape[0] + 16, needed + needed // 4 + 16))


class CellTooSmall(RunFailed):
    """A periodic edge shrank to twice the contact reach or less: spheres could then touch
    through two images."""

    def __init__(self, step: int, length: np.ndarray, servo: str = "", time_step: str = ""):
        """`servo`: the stage's servo that may swing an edge in (`stage._servo_held`);
        `time_step`: the time step above the critical one, named first where it is
        (`stage._dt_above_critical`), as a blow-up's line names it."""
        edges = ", ".join(f"{edge:.4g}" for edge in length)
        first = f"; {time_step}" if time_step else ""
        held = f"; or {servo}, swinging an edge further at each step" if servo else ""
        super().__init__(
            f"step {step}: the periodic cell ({edges} m) is no longer more than twice the "
            f"contact reach 2 r_max + skin on every axis{first}; compress it less or start "
            f"bigger{held}"
        )


def particle_named(k: int, ids: np.ndarray) -> str:
    """A sphere as messages name it: its index in the arrays (the contacts' and the event
    log's) and its id (the trajectory's, a data file's atom id)."""
    return f"particle {k} (id {int(ids[k])})"


def partner_named(partner: int, ids: np.ndarray, walls: list[str]) -> str:
    """A contact's partner as messages name it: a sphere (`particle_named`), or for partner
    -1 - w wall w by its name ('a wall' where the names are not known)."""
    if partner >= 0:
        return particle_named(partner, ids)
    return f"wall {walls[-1 - partner]}" if -1 - partner < len(walls) else "a wall"


class BlownUp(RunFailed):
    """The state stopped being physical (kernels/health.py): a non-finite value, or an
    overlap deeper than integrator.overlap_limit allows."""

    def __init__(
        self, step: int, finding, limit: float, walls: list[str], ids, cause: str, kept: str
    ):
        what, particle, partner, value = finding
        if what == health.NOT_FINITE:
            quantity = ("position", "velocity", "angular velocity")[int(value)]
            found = f"{particle_named(particle, ids)} has a non-finite {quantity}"
        else:
            other = partner_named(partner, ids, walls)
            found = (
                f"{particle_named(particle, ids)} and {other} overlap by {value:.3g} of the "
                f"smaller radius (integrator.overlap_limit = {limit:g})"
            )
        super().__init__(f"blown up at step {step}: {found}; {cause}; {kept}")
        self.step = step


GRID_BITS = 52
"""A fixed-point grid step is 2^-52 of the scale of its quantity, rounded up to a power of
two: the resolution of a float64 at that scale. The range, 2^62 steps, is then 1024 times
the scale."""


def power_of_two_above(value: float) -> float:
    return 2.0 ** math.ceil(math.log2(value))


def fixed_grid(scenario: Scenario) -> np.ndarray:
    """The grid steps of fixed-point arithmetic (kernels.fixed: X, Y, Z, VELOCITY, ...,
    EDGE_RATE), 2^-52 of each quantity's scale:

    - position: the extent E of the scenario (the largest |coordinate| + radius, or cell
      edge); in a deforming cell the cell coordinate, whose scale is 1;
    - velocity: the largest of the starting speeds, the free-fall speed sqrt(2 |g| E), E
      over the duration of the run, and the walls' speeds in any stage (a wall driven into a
      sphere at rest, left out, overflowed the grid); angular velocity: that over the
      smallest radius, or
      the largest starting angular velocity;
    - force: the largest weight, or the normal force of the largest sphere at an overlap of
      1 % of its radius; moment: that times the largest radius;
    - cell edge: the longest edge; edge rate: as velocity.
    """
    spheres = scenario.spheres
    r_max, r_min = float(spheres.radius.max()), float(spheres.radius.min())
    extent = float((np.abs(spheres.position) + spheres.radius[:, None]).max())
    if scenario.cell is not None:
        extent = max(extent, max(scenario.cell.size))
    duration = sum(stage.steps * (stage.dt or scenario.integrator.dt) for stage in scenario.stages)
    gravity = float(np.linalg.norm(scenario.gravity))
    walls = [
        float(np.linalg.norm(stage.wall_velocity(wall)))
        for stage in scenario.stages
        for wall in scenario.walls
    ]
    speed = max(
        float(np.linalg.norm(spheres.velocity, axis=1).max()),
        math.sqrt(2.0 * gravity * extent),
        extent / duration,
        max(walls, default=0.0),
    )
    spin = max(float(np.linalg.norm(spheres.angular_velocity, axis=1).max()), speed / r_min)
    masses = sphere_masses(scenario)[0]
    estar = float(moduli(scenario).estar.max())
    overlap = 0.01 * r_max
    contact = laws.evaluate(scenario.contact, "normal", "force", overlap, r_max, estar)[0]
    force = max(float(masses.max()) * gravity, contact)
    edge = max(scenario.cell.size) if scenario.cell is not None else 1.0
    position = 1.0 if scenario.cell is not None and cell_deforms(scenario) else extent
    scales = [position] * 3 + [speed, spin, force, force * r_max, edge, speed]
    return np.array([power_of_two_above(s) * 2.0**-GRID_BITS for s in scales])


def fixed_arrays(scenario: Scenario, p: Particles, cell_now: Cell) -> Fixed:
    """The integer state of fixed-point arithmetic, the scenario's state rounded onto its
    grids, and the floating-point state moved onto the grid points (empty arrays in
    floating-point arithmetic)."""
    if scenario.integrator.arithmetic != "fixed":
        return Fixed(
            x=np.zeros((0, 3), dtype=np.int64),
            v=np.zeros((0, 3), dtype=np.int64),
            omega=np.zeros((0, 3), dtype=np.int64),
            length=np.zeros(3, dtype=np.int64),
            rate=np.zeros(3, dtype=np.int64),
            grid=np.zeros(9),
            overflow=np.zeros(2, dtype=np.int64),
        )
    grid = fixed_grid(scenario)
    position = grid[fixed.X : fixed.Z + 1]
    in_cell = p.s.shape[0] > 0
    coordinates = p.s if in_cell else p.x

    state = Fixed(
        x=fixed.onto_grid(coordinates, position),
        v=fixed.onto_grid(p.v, grid[fixed.VELOCITY]),
        omega=fixed.onto_grid(p.omega, grid[fixed.ANGULAR_VELOCITY]),
        length=fixed.onto_grid(cell_now.length, grid[fixed.EDGE]),
        rate=fixed.onto_grid(cell_now.rate, grid[fixed.EDGE_RATE]),
        grid=grid,
        overflow=np.zeros(2, dtype=np.int64),
    )
    if in_cell:
        p.x[...] = p.s * cell_now.length
    cell_now.start[:] = cell_now.built[:] = cell_now.mid[:] = cell_now.length
    return state


class OffGrid(RunFailed):
    """A value of fixed-point arithmetic left the range of its grid."""

    def __init__(self, step: int, state: Fixed, ids: np.ndarray):
        quantity = fixed.QUANTITIES[int(state.overflow[0]) - 1]
        k = int(state.overflow[1])
        who = f" of {particle_named(k, ids)}" if k >= 0 else ""
        super().__init__(
            f"step {step}: the {quantity}{who} left the range of its fixed-point grid "
            f"(2^62 steps, 1024 times the scale the grid was made for); nothing wraps "
            "around: run it in floating point, or start from a larger extent"
        )


def initial_state(scenario: Scenario) -> State:
    """The state at step 0 with its pair list and the forces at the initial positions."""
    p = particles(scenario)
    shear = scenario.contact.tangential != "none"
    cell_now = cell_arrays(scenario)
    integers = fixed_arrays(scenario, p, cell_now)
    skin = default_skin(scenario)
    taped = scenario.reversal.tape  # a forward step then takes a reversed one in its shadow
    nothing = np.zeros(0, dtype=np.int32)
    needed = build_pairs(p.x, p.radius, skin, cell_now.periodic, cell_now.length, nothing, nothing)
    state = State(
        p,
        empty_pairs(
            len(p.x),
            pair_capacity(needed),
            shear,
            taped,
            rolls(scenario),
            turns(scenario),
            predicts(scenario),
        ),
        wall_arrays(scenario, len(p.x), taped),
        cell_now,
        integers,
        scenario.spheres.id,
        step=0,
    )
    state.rebuild_pairs(skin)
    compute_forces(
        state.particles,
        state.pairs,
        state.walls,
        state.cell,
        state.fixed,
        contact_law(scenario),
        moduli(scenario),
        dynamics(scenario),
        contact.STATIC,
        0.0,  # a static evaluation takes no step
        0.0,
        empty_events(),
        0,
        True,  # the pair arrays: read by the first frame
    )
    scenario.forget_spheres()  # the state's now
    release_freed_memory()
    return state


def default_skin(scenario: Scenario) -> float:
    """Neighbour skin: as given, else 10 % of the largest radius."""
    return scenario.neighbours.skin or 0.1 * float(scenario.spheres.radius.max())
