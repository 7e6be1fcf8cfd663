"""Critical time step of a packing as it is: the largest eigenvalue of M⁻¹K, with K the
linearised stiffness of every contact of one state and M its masses and moments of inertia
(Otsubo, O'Sullivan & Shire 2017, Peng 2020's ref 10: the eigenvalue analysis its §1 cites,
and its §4's reason for a factor of safety where a particle has several contacts), checked
on the engine's own stepping loop.

Each sphere has 6 degrees of freedom, q = (u, θ): a small displacement and a small rotation.
A contact of spheres a and b with normal n from a to b, lever arms l_a and l_b (r - δ/2, as
the engine's) and stiffnesses k_n = dF/dδ (Hanley 2020 Eq 6), k_s (Eq 10) and k_r (a rolling
law) stores

    U = ½ Δᵀ [k_n nnᵀ + k_s (I - nnᵀ)] Δ + ½ k_r |P_t (θ_b - θ_a)|²,
    Δ = u_b - u_a - (l_a θ_a + l_b θ_b) × n,   P_t = I - nnᵀ,

Δ the displacement of b's contact point relative to a's (`kernels.contact.relative_velocity`
integrated over a small motion); a wall is a body that does not move (u_b = θ_b = 0, l_b =
0), and a pair across a periodic boundary takes its nearest image. K = ∂²U/∂q² summed over
contacts is applied matrix-free (`StiffnessOperator`); the largest eigenvalue λ of the
mass-normalised M^-½ K M^-½ is ω_max², and velocity Verlet is stable below Δt = 2/ω_max
(Peng 2020 Eq 47). With viscous contact damping (c = 2β √(m* k), as the engine applies it)
the damped limit is that of the top mode with its own damping coefficient φᵀCφ (Eq 30
integrated by velocity Verlet, whose damping reads the half-step velocity or the velocity
predictor as the scenario's scheme has it, `criteria.dt_damped`).

Left out, and why the limit stays an upper bound on ω_max only to their order: the
geometric stiffness of the contact forces as the normals turn (f_n/d beside k_n, of order
δ/r), sliding contacts (taken as sticking, stiffer than they are), local damping and drag
(not linear in the velocity), the servo of a periodic cell (its edges held).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from revdem_cli import laws
from revdem_cli.contacts import touching_pairs, wall_touches
from revdem_cli.errors import InputError
from revdem_cli.io.tape import no_tape
from revdem_cli.kernels.arrays import Dynamics
from revdem_cli.kernels.cell import FIXED
from revdem_cli.kernels.contact import STATIC, lever_arm, reduced, viscous_coefficient
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.integrate import BLOWN_UP, OK, advance
from revdem_cli.kernels.stiffness import apply_stiffness, contact_stiffnesses
from revdem_cli.stage import Model, stepping_bundles
from revdem_cli.state import State, empty_events, fixed_arrays
from revdem_cli.timestep.criteria import bisected, dt_damped


@dataclass(frozen=True)
class Contacts:
    """Every contact of a state in overlap, sphere pairs then sphere-wall contacts."""

    a: np.ndarray  # the particle, (K,)
    b: np.ndarray  # its partner; N (one past the last particle) for a wall, (K,)
    n: np.ndarray  # unit normal from a to b, (K, 3)
    arm_a: np.ndarray  # lever arm of a, r - δ/2, m, (K,)
    arm_b: np.ndarray  # lever arm of b, 0 on a wall, m, (K,)
    overlap: np.ndarray  # m, (K,)
    kn: np.ndarray  # normal tangent stiffness dF/dδ, N/m, (K,)
    ks: np.ndarray  # shear stiffness, N/m, (K,)
    kr: np.ndarray  # rolling stiffness, N m/rad, (K,)
    cn: np.ndarray  # normal viscous coefficient 2 β_n √(m* k_n), N s/m, (K,)
    cs: np.ndarray  # shear viscous coefficient 2 β_t √(m* k_s), N s/m, (K,)
    walls: int  # how many of them (the last) are on walls

    def __len__(self) -> int:
        return len(self.a)


def contacts_of(state: State, model: Model) -> Contacts:
    """The contacts of `state` in overlap, with their stiffnesses from the scenario's laws."""
    p = state.particles
    t = touching_pairs(state)
    i, j, overlap = t.i, t.j, t.overlap
    q, w, n_walls = wall_touches(state)  # sphere q on wall w
    r_i, r_j, m_i, m_j = p.radius[i], p.radius[j], p.mass[i], p.mass[j]
    a = np.concatenate([i, q])
    b = np.concatenate([j, np.full(len(q), len(p.x))])
    n = np.concatenate([t.normal, n_walls])
    wall_overlap = state.walls.overlap[q, w]
    rstar = np.concatenate([reduced(r_i, r_j), p.radius[q]])  # on a wall R* = r
    mstar = np.concatenate([reduced(m_i, m_j), p.mass[q]])  # and m* = m
    arm_b = np.concatenate([lever_arm(r_j, overlap), np.zeros(len(q))])
    overlap = np.concatenate([overlap, wall_overlap])
    mat_a = p.material[a]
    mat_b = np.concatenate([p.material[j], state.walls.material[w]])
    estar = np.ascontiguousarray(model.moduli.estar[mat_a, mat_b])
    gstar = np.ascontiguousarray(model.moduli.gstar[mat_a, mat_b])
    kn, ks, kr = (np.zeros(len(a)) for _ in range(3))
    contact_stiffnesses(model.law, overlap, rstar, estar, gstar, kn, ks, kr)
    return Contacts(
        a=a,
        b=b,
        n=n,
        arm_a=lever_arm(p.radius[a], overlap),
        arm_b=arm_b,
        overlap=overlap,
        kn=kn,
        ks=ks,
        kr=kr,
        cn=viscous_coefficient(model.law.beta_n, mstar, kn),
        cs=viscous_coefficient(model.law.beta_t, mstar, ks),
        walls=len(q),
    )


class StiffnessOperator:
    """q ↦ K q (or the damping matrix C q) of a set of contacts, for q of shape (N, 6)
    (`kernels.stiffness.apply_stiffness`), with the given normal, shear and rolling
    coefficients of each contact."""

    def __init__(self, contacts: Contacts, particles: int, normal, shear, rolling):
        self.c, self.particles = contacts, particles
        self.normal, self.shear, self.rolling = normal, shear, rolling  # (K,) each

    def __call__(self, q: np.ndarray) -> np.ndarray:
        c, rows = self.c, self.particles + 1  # the last row: the walls, which do not move
        u, theta = np.zeros((rows, 3)), np.zeros((rows, 3))
        u[:-1], theta[:-1] = q[:, :3], q[:, 3:]
        out_u, out_theta = np.empty((rows, 3)), np.empty((rows, 3))
        apply_stiffness(
            c.a, c.b, c.n, c.arm_a, c.arm_b, self.normal, self.shear, self.rolling, u, theta,
            out_u, out_theta,
        )  # fmt: skip
        return np.hstack([out_u[:-1], out_theta[:-1]])


@dataclass(frozen=True)
class Mode:
    """Where the fastest mode lives."""

    participation: float  # 1 / Σ p_i² of the spheres' shares p_i: how many spheres carry it
    rotation: float  # share of its kinetic energy in rotation
    spheres: list[tuple[int, float, int]]  # the largest shares: (sphere, share, its contacts)
    centre: tuple[float, float, float]  # share-weighted centre of those spheres, m


@dataclass(frozen=True)
class PackingLimit:
    """The assembly's critical time step and where it comes from."""

    contacts: Contacts  # those of the state, whose stiffness the limit is of
    omega_max: float  # rad/s, √λ_max of M⁻¹K
    dt: float  # 2 / omega_max, s (Peng 2020 Eq 47)
    damped_dt: float  # with the top mode's own viscous damping, s
    mode_damping: float  # φᵀCφ of the mass-normalised top mode, 1/s
    mode: Mode
    vector: np.ndarray  # the top mode in mass-normalised coordinates, (N, 6), unit norm
    seconds: float  # time the eigenvalue took

    def to_dict(self, ids: np.ndarray) -> dict:
        """The limit as `revdem dt --restart --json` gives it, each sphere of the mode by its
        index in the arrays and its id (`ids`), which outputs carry."""
        return {
            "contacts": len(self.contacts),
            "wall_contacts": self.contacts.walls,
            "omega_max": self.omega_max,
            "dt": self.dt,
            "damped_dt": self.damped_dt,
            "mode_damping": self.mode_damping,
            "mode": {
                "participation": self.mode.participation,
                "rotation_share": self.mode.rotation,
                "spheres": [
                    {"index": i, "id": int(ids[i]), "share": s, "contacts": k}
                    for i, s, k in self.mode.spheres
                ],
                "centre": list(self.mode.centre),
            },
            "seconds": self.seconds,
        }


def _mass_scale(state: State) -> np.ndarray:
    """M^-½ of each degree of freedom, (N, 6)."""
    p = state.particles
    inverse = np.repeat(np.column_stack([p.inv_mass, p.inv_inertia]), 3, axis=1)
    return np.sqrt(inverse)


Status = Callable[[str], None]
"""status(what is being done now), for a display of work that takes a while."""


def _quiet(what: str) -> None:
    """A `Status` that shows nothing."""


def packing_limit(
    state: State, model: Model, tolerance: float = 1e-9, status: Status = _quiet
) -> PackingLimit:
    """The critical time step of `state` from the largest eigenvalue of M⁻¹K (scipy's
    Lanczos, `eigsh`, on the symmetric M^-½ K M^-½, matrix-free), telling `status` how many
    products it has taken."""
    import time

    from scipy.sparse.linalg import LinearOperator, eigsh

    started = time.perf_counter()
    contacts = contacts_of(state, model)
    n = len(state.particles.x)
    scale = _mass_scale(state)
    if len(contacts) == 0 or not contacts.kn.any():
        mode = Mode(0.0, 0.0, [], (math.nan,) * 3)
        return PackingLimit(contacts, 0.0, math.inf, math.inf, 0.0, mode, np.zeros((n, 6)), 0.0)
    stiffness = StiffnessOperator(contacts, n, contacts.kn, contacts.ks, contacts.kr)

    products = 0

    def matvec(y):
        nonlocal products
        products += 1
        if products % 10 == 0:
            status(f"the fastest mode of {n:,} spheres (Lanczos): {products} products M⁻½KM⁻½ y")
        return (scale * stiffness(scale * y.reshape(n, 6))).ravel()

    operator = LinearOperator((6 * n, 6 * n), matvec=matvec, dtype=np.float64)
    start = np.random.default_rng(0).standard_normal(6 * n)  # the same answer every time
    values, vectors = eigsh(operator, k=1, which="LA", tol=tolerance, v0=start)
    lam, y = float(values[0]), vectors[:, 0].reshape(n, 6)
    damping = StiffnessOperator(contacts, n, contacts.cn, contacts.cs, np.zeros(len(contacts)))
    c_mode = (
        float((y * scale * damping(scale * y)).sum())
        if contacts.cn.any() or contacts.cs.any()
        else 0.0
    )
    omega = math.sqrt(lam)
    return PackingLimit(
        contacts=contacts,
        omega_max=omega,
        dt=2.0 / omega,
        damped_dt=dt_damped(lam, c_mode, 1.0, model.scenario.integrator.predictor_order),
        mode_damping=c_mode,
        mode=_mode_of(y, contacts, state),
        vector=y,
        seconds=time.perf_counter() - started,
    )


def _mode_of(y: np.ndarray, contacts: Contacts, state: State, shown: int = 5) -> Mode:
    share = (y * y).sum(axis=1)
    share /= share.sum()
    order = np.argsort(share, kind="stable")[::-1][:shown]
    count = np.bincount(np.concatenate([contacts.a, contacts.b]), minlength=len(share) + 1)
    weights = share[order] / share[order].sum()
    centre = tuple(float(c) for c in weights @ state.particles.x[order])
    return Mode(
        participation=float(1.0 / (share * share).sum()),
        rotation=float((y[:, 3:] ** 2).sum() / (y * y).sum()),
        spheres=[(int(k), float(share[k]), int(count[k])) for k in order],
        centre=centre,
    )


def single_contact_limits(contacts: Contacts, state: State) -> dict[str, float]:
    """The two-body limit 2/√(k A) (Peng 2020 Eq 47) of every contact of the state on its
    own, smallest over contacts, per direction: normal A = 1/m_a + 1/m_b, shear A = Σ 1/m +
    l²/I (Eq 26), rolling A = Σ 1/I (a wall: its terms 0)."""
    p = state.particles
    inv_m = np.append(p.inv_mass, 0.0)
    inv_i = np.append(p.inv_inertia, 0.0)
    a, b = contacts.a, contacts.b
    normal = inv_m[a] + inv_m[b]
    shear = normal + contacts.arm_a**2 * inv_i[a] + contacts.arm_b**2 * inv_i[b]
    rolling = inv_i[a] + inv_i[b]

    def smallest(k, inverse_mass):  # the least 2 / sqrt(k A) of them (Peng 2020 Eq 47)
        product = k * inverse_mass
        return float(2.0 / np.sqrt(product.max())) if product.any() else math.inf

    return {
        "normal": smallest(contacts.kn, normal),
        "shear": smallest(contacts.ks, shear),
        "rolling": smallest(contacts.kr, rolling),
    }


def automatic_dt(state: State, model: Model) -> float:
    """dt = 'auto': integrator.dt_safety times the smallest of the packing's limit in `state`
    (with its viscous damping), the start-up estimate `guard.critical_time_step`, which
    bounds the contacts still to form (a pour starts with none), and the kinematic limit
    `guard.kinematic_dt`."""
    from revdem_cli.timestep.guard import critical_time_step, kinematic_dt

    scenario = model.scenario
    limit = min(
        packing_limit(state, model).damped_dt,
        critical_time_step(scenario)[0],
        kinematic_dt(scenario)[0],
    )
    if not math.isfinite(limit):
        raise InputError(
            "integrator.dt = 'auto': this scenario has no contact and none can form, so no "
            "critical time step bounds it; give dt in seconds"
        )
    return scenario.integrator.dt_safety * limit


# ---------------------------------------------------------------- checked by the engine


def float_model(model: Model) -> Model:
    """`model` in floating-point arithmetic, whatever the scenario's (its time step may then
    change: fixed-point grids are made for one), with the contact record it has (a stage's,
    `Model.during`)."""
    scenario = model.scenario
    integrator = scenario.integrator.model_copy(update={"arithmetic": "float"})
    return replace(model, scenario=scenario.model_copy(update={"integrator": integrator}))


def _at_rest_copy(state: State, model: Model) -> State:
    """A copy of `state` that steps forward in floating point, at rest, walls and the cell's
    edges held where they are."""

    def copied(bundle):
        return bundle._make(np.copy(v) if isinstance(v, np.ndarray) else v for v in bundle)

    p, pairs, walls, cell = (
        copied(b) for b in (state.particles, state.pairs, state.walls, state.cell)
    )
    nothing = np.zeros((0, 3))  # a forward step in floating point: no unwinding nor tape
    pairs = pairs._replace(normal_new=nothing, earlier=nothing)
    walls = walls._replace(normal_new=np.zeros((0,) + walls.normal_new.shape[1:]))
    for at_rest in (p.v, p.omega, p.v_past, p.omega_past, p.v_pred, p.omega_pred):
        at_rest[...] = 0.0  # with a velocity predictor's history
    walls.velocity[:] = 0.0
    walls.origin[:] = walls.point
    cell.control[:] = FIXED
    cell.rate[:] = 0.0
    fixed = fixed_arrays(model.scenario, p, cell)
    return State(p, pairs, walls, cell, fixed, state.ids, state.step)


GROWTH = 1e3
"""A perturbation grown this many times (times the packing's own divergence, `PARTED`) is
unstable: below the limit a mode's velocity amplitude grows at most 1/√(1 - (ωΔt/2)²) times
(10 at 0.5 % below), above it by (1 + √(8ε))^steps at (1 + ε) times the limit."""

PARTED = 10.0
"""Two copies of a packing at rest in a stable equilibrium, a kick along its top mode apart,
part at most 1/√(1 - (ωΔt/4)²) times at half a stable step (1.15 at the limit). Ten times is
a packing that still moves (a stage ended on its step limit) or has motions unstable of
themselves: they part at a rate per second that no step changes, and a kick grown GROWTH
times that leaves the linear range (it is 1e-6 of the overlap), so the engine's limit cannot
be told from them."""


def _advance(state: State, model: Model, dyn: Dynamics, dt: float, steps: int) -> bool:
    """Step `state` `steps` steps at dt; False if it blew up."""
    compute_forces(
        *stepping_bundles(state, model, dyn, model.law),
        STATIC,
        dt,
        0.0,
        empty_events(),
        state.step,
        True,
    )
    stepping = model.stepping(dt, state.step, state.step + steps, steps)
    buffer, buffer_steps = model.buffers(2)
    events, stop = empty_events(), state.step + steps
    while state.step != stop:
        status, state.step, _, _ = advance(
            *stepping_bundles(state, model, dyn, model.law), events, no_tape(), stepping,
            state.step, stop, stop,
            buffer, buffer_steps,
        )  # fmt: skip
        if status == BLOWN_UP:
            return False
        if status != OK:
            state.grow_pairs()
    return True


MOVES = 20
"""How many times the bracket moves, down 0.9 or up 1.1 times, looking for a step that keeps
the kick and one that grows it (0.97 × 0.9^20 = 0.12 to 1.03 × 1.1^20 = 6.9 times the damped
assembly limit); past them the engine's limit is reported not measured."""


@dataclass(frozen=True)
class EngineCheck:
    """The bracket [stable, unstable] of the stepping loop's own limit (NaN, not measured,
    where the packing parts copies of itself more than PARTED times or no bracket was found
    within MOVES moves), `divergence`, how many times two copies a kick apart parted over the
    first trial's time at half its step, and `searched`, the smallest and largest Δt tried
    (NaN where none was)."""

    stable: float
    unstable: float
    steps: int
    trials: int
    divergence: float
    seconds: float  # the time over which `divergence` was measured, s
    searched: tuple[float, float]

    @property
    def measured(self) -> bool:
        return math.isfinite(self.stable)

    @property
    def dt(self) -> float:
        return 0.5 * (self.stable + self.unstable)


def engine_bracket(
    state: State,
    model: Model,
    limit: PackingLimit,
    steps: int = 400,
    width: float = 1e-4,
    status: Status = _quiet,
) -> EngineCheck:
    """Bisect the engine's stability limit from `state`: a copy at rest and one kicked along
    the top mode, each stepped `steps` steps at a trial Δt by the real stepping loop (viscous
    contact damping as the model's law has it; local damping and drag off, walls and cell
    held); Δt is unstable where their difference grows GROWTH times more than the copies
    part by themselves, measured first over the first trial's time at half its step (the
    packing's own divergence, `PARTED`; none is bracketed above it). The bracket starts at 3 %
    either side of the damped assembly limit and narrows to a relative `width`; `status` is
    told of each trial."""
    model = float_model(model)
    dyn = Dynamics(np.array(model.scenario.gravity, dtype=float), 0.0, 1.0)
    scale = _mass_scale(state)
    shape = scale * limit.vector  # velocities along the mode
    size = 1e-6 * float(np.median(limit.contacts.overlap)) * limit.omega_max / np.abs(shape).max()
    kick = size * shape
    weight = 1.0 / scale**2  # M, so that the difference is measured in kinetic energy's norm
    spheres = len(state.particles.x)

    def parted(dt: float, steps: int) -> float:
        """How many times the copies' difference has grown after `steps` steps at dt."""
        base, kicked = _at_rest_copy(state, model), _at_rest_copy(state, model)
        kicked.particles.v[:] += kick[:, :3]
        kicked.particles.omega[:] += kick[:, 3:]
        if not (_advance(base, model, dyn, dt, steps) and _advance(kicked, model, dyn, dt, steps)):
            return math.inf
        dv = np.hstack(
            [kicked.particles.v - base.particles.v, kicked.particles.omega - base.particles.omega]
        )
        grown = math.sqrt((weight * dv * dv).sum() / (weight * kick * kick).sum())
        return grown if math.isfinite(grown) else math.inf

    stable, unstable = 0.97 * limit.damped_dt, 1.03 * limit.damped_dt
    status(f"the packing's own motion: {4 * steps} steps of {spheres:,} spheres at Δt/2")
    divergence, seconds = parted(0.5 * stable, 2 * steps), steps * stable
    if divergence > PARTED:
        return EngineCheck(math.nan, math.nan, steps, 0, divergence, seconds, (math.nan,) * 2)
    threshold = GROWTH * max(1.0, divergence)
    tried = []

    def grows(dt: float) -> bool:
        tried.append(dt)
        status(
            f"the engine's limit: trial {len(tried)} at Δt = {dt:.6g} s, {2 * steps} steps of "
            f"{spheres:,} spheres"
        )
        return parted(dt, steps) > threshold

    low, high = grows(stable), grows(unstable)
    for move in range(MOVES + 1):
        if high and not low:
            break
        if move == MOVES:
            searched = (min(tried), max(tried))
            return EngineCheck(math.nan, math.nan, steps, len(tried), divergence, seconds, searched)
        if low:  # the bracket moves down a tenth: its lower end grew, so is the new upper end
            stable, unstable, high = 0.9 * stable, stable, True
            low = grows(stable)
        else:  # up a tenth: its upper end did not grow, so is the new lower end
            stable, unstable, low = unstable, 1.1 * unstable, False
            high = grows(unstable)
    stable, unstable = bisected(lambda dt: not grows(dt), stable, unstable, width)
    searched = (min(tried), max(tried))
    return EngineCheck(stable, unstable, steps, len(tried), divergence, seconds, searched)


# ---------------------------------------------------------------- `revdem dt --restart`


def assess_restart(path, verify: bool, status: Status = _quiet) -> dict:
    """The critical time step of the state a restart or checkpoint holds: the assembly's
    limit, every single-contact estimate revdem has beside it with its ratio to it, the time
    step the stage ran at, and with `verify` the engine's own bracket; `status` told of the
    work as it goes."""
    from pathlib import Path

    from revdem_cli.config import Scenario
    from revdem_cli.io.restart import read_restart
    from revdem_cli.timestep.guard import critical_time_step, head_on_limit, rayleigh_limit

    restart = read_restart(path, checkpoint=None)
    scenario = Scenario.model_validate_json(restart.scenario_json)
    stage = next(s for s in scenario.stages if s.name == restart.stage)
    model, state = Model.of(scenario).during(stage), restart.state  # its damping, its mu
    limit = packing_limit(state, model, status=status)
    if not len(limit.contacts):
        raise InputError(
            f"{path}: no sphere touches another or a wall at step {state.step}: a packing's "
            "critical time step is its contacts', and it has none"
        )
    single = single_contact_limits(limit.contacts, state)
    guard, why = critical_time_step(scenario)
    estimates = {
        "single_contact_normal": (
            "stiffest normal contact of this state, alone (Peng 2020 Eq 47)",
            single["normal"],
        ),
        "single_contact_shear": (
            "stiffest shear contact of this state, alone (Peng 2020 Eq 26, 47)",
            single["shear"],
        ),
        "single_contact_rolling": (
            "stiffest rolling spring of this state, alone",
            single["rolling"],
        ),
        "head_on": (
            "head-on impact at the scenario's largest approach speed (guard)",
            head_on_limit(scenario),
        ),
        "rayleigh": ("Rayleigh time step of the smallest sphere (guard)", rayleigh_limit(scenario)),
        "guard": ("the run's start-up check: " + why, guard),
        "in_use": (f"the time step of stage {stage.name!r}", restart.stage_dt),
    }
    if not laws.chosen(scenario.contact, "normal").FROM_MATERIALS:
        del estimates["rayleigh"]  # a given stiffness: no wave speed bounds it
    unbounded = _why_unbounded(scenario, why)
    reference = limit.damped_dt
    report = {
        "restart": str(Path(path)),
        "scenario": scenario.name,
        "stage": restart.stage,
        "step": state.step,
        "spheres": len(state.particles.x),
        "predictor_order": scenario.integrator.predictor_order,  # 0: velocity Verlet
        "assembly": limit.to_dict(state.ids),
        "estimates": {
            key: _estimate(key, label, dt, reference, unbounded)
            for key, (label, dt) in estimates.items()
        },
    }
    if verify and math.isfinite(reference):
        check = engine_bracket(state, model, limit, status=status)
        engine = {
            "measured": check.measured,
            "divergence": check.divergence,
            "divergence_seconds": check.seconds,
            "steps": check.steps,
            "trials": check.trials,
        }
        if check.measured:
            engine |= {
                "stable": check.stable,
                "unstable": check.unstable,
                "dt": check.dt,
                "ratio": check.dt / reference,
            }
        elif check.divergence > PARTED:
            engine["reason"] = (
                f"the engine's limit was not measured: two copies of this state a kick apart "
                f"parted {check.divergence:.3g} times in {check.seconds:.3g} s at half the step "
                "(at rest: about 1). The packing still moves, or has motions unstable of "
                "themselves, and their parting, the same at any step, hides the integrator's. "
                "Let the stage come to rest (stop_when.kinetic_energy_below) and check again; "
                "where it parts even at rest, the assembly's limit is the estimate."
            )
        else:
            low, high = check.searched
            grown = GROWTH * max(1.0, check.divergence)
            engine["reason"] = (
                f"the engine's limit was not measured: trial steps from {low:.3g} to "
                f"{high:.3g} s ({low / reference:.3g} to {high / reference:.3g} times the "
                "assembly's limit) found no step that keeps a kick along the top mode below "
                f"{grown:.4g} times its size in {check.steps} steps next to one that grows it "
                "past that. Set at rest, this state need not stay in its contacts (spheres "
                "caught mid-collision spring apart), so the stepping loop may never meet the "
                "stiffness the assembly's limit is of; the assembly's limit is the estimate."
            )
        report["engine_integrated"] = engine
    return report


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _estimate(key: str, label: str, dt: float, reference: float, unbounded: dict) -> dict:
    """The estimate `key` as `revdem dt --restart --json` gives it: its label, its Δt and its
    ratio to the assembly's limit, both null where there is no limit (∞), and then `reason`,
    why it has none (`unbounded[key]`, `_why_unbounded`)."""
    found = {"label": label, "dt": _finite(dt), "ratio": _finite(dt / reference)}
    if found["dt"] is None:
        found["reason"] = f"no limit: {unbounded[key]}"
    return found


def _why_unbounded(scenario, guard_why: str) -> dict[str, str]:
    """Why each estimate that can be ∞ is, where it is: a stiffest contact alone, where no
    contact of the state has a stiffness in its direction (2/√(kA) with k = 0); the head-on
    impact, where none of the scenario's kinds of contact stiffens at the overlap of a
    head-on impact at its approach speed (a Hertz contact at rest has none); the start-up
    check, for the reason it gives (`guard_why`)."""
    from revdem_cli.timestep.guard import contact_kinds

    speed = max((kind.speed for kind in contact_kinds(scenario)), default=0.0)
    alone = "no contact of this state has a {} stiffness ({} = 0 in each)"
    return {
        "single_contact_normal": alone.format("normal", "k_n"),
        "single_contact_shear": alone.format("shear", "k_s"),
        "single_contact_rolling": alone.format("rolling", "k_r"),
        "head_on": (
            "no kind of contact the scenario forms has a stiffness at the overlap of a head-on "
            f"impact at its approach speed (at most {speed:.3g} m/s; a Hertz contact at zero "
            "overlap has none)"
        ),
        "guard": guard_why,
    }
