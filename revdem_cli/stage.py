"""One stage of a run, forward or reversed: the constant parts of a run (`Model`), a
stage's clock, and `run_stage`, which drives the compiled stage loop
(`kernels.integrate.advance`) from frame to frame, touching Python once per output frame,
and writes the frames, at the same step numbers in both directions."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from functools import cached_property

import numpy as np

from revdem_cli.config import Scenario, Stage
from revdem_cli.config.checks import tape_needs
from revdem_cli.contacts import contact_list
from revdem_cli.errors import RunFailed
from revdem_cli.io.h5md import TrajectoryWriter
from revdem_cli.io.tape import Recorder, Replayer, no_tape
from revdem_cli.kernels.arrays import Cell, ContactLaw, Dynamics, Fixed, Moduli, Stepping
from revdem_cli.kernels.cell import FIXED, STRAIN_RATE, STRESS
from revdem_cli.kernels.contact import STATIC
from revdem_cli.kernels.fixed import EDGE, EDGE_RATE, onto_grid
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.integrate import (
    BLOWN_UP,
    CELL_TOO_SMALL,
    FIXED_OVERFLOW,
    HALTED,
    OK,
    PAIR_OVERFLOW,
    TAPE_EMPTY,
    TAPE_FULL,
    TAPE_MISMATCH,
    advance,
)
from revdem_cli.kernels.observables import Layout, observe
from revdem_cli.kernels.stress import particle_stress
from revdem_cli.kernels.tape import MECHANISMS, RECORD, Tape
from revdem_cli.report.info import servo_overshoot
from revdem_cli.state import (
    BlownUp,
    CellTooSmall,
    OffGrid,
    State,
    contact_law,
    default_skin,
    dynamics,
    empty_events,
    moduli,
)
from revdem_cli.threads import Stepper
from revdem_cli.timestep.guard import CROWDED, critical_time_step, times_above

Progress = Callable[[str, int, int, int], None]
"""Called as progress(label, steps done, steps in total, particles) once per output frame."""


@dataclass(frozen=True)
class Model:
    """The constant parts of a run, derived once from the scenario."""

    scenario: Scenario
    law: ContactLaw
    moduli: Moduli
    dynamics: Dynamics
    skin: float
    solid_volume: float  # of all the spheres, m^3

    @classmethod
    def of(cls, scenario: Scenario) -> Model:
        return cls(
            scenario,
            contact_law(scenario),
            moduli(scenario),
            dynamics(scenario),
            default_skin(scenario),
            float((4.0 / 3.0 * np.pi * scenario.spheres.radius**3).sum()),
        )

    def stepping(
        self, dt: float, first_step: int, last_step: int, every: int, halt: np.ndarray | None = None
    ) -> Stepping:
        """How the compiled loop steps a stage of time step dt from first_step to last_step,
        observables every `every` steps; it stops at a whole step once `halt` (int64 [1],
        `threads.Stepper`) is set."""
        limit = self.scenario.integrator.overlap_limit
        halt = np.zeros(1, dtype=np.int64) if halt is None else halt
        return Stepping(dt, self.skin, int(first_step), int(last_step), int(every), limit, halt)

    def stage_dynamics(self, stage: Stage) -> Dynamics:
        """Gravity and the damping of a stage: its own, else the scenario's."""
        return self.dynamics if stage.damping is None else dynamics(self.scenario, stage.damping)

    def stage_law(self, stage: Stage) -> ContactLaw:
        """The contact record of a stage: the scenario's, with the stage's own friction and
        viscous damping where it gives them (`stages[].contact`)."""
        own = stage.contact
        if own is None:
            return self.law
        given = {
            field: float(value)
            for field, value in (
                ("mu", own.friction),
                ("beta_n", own.normal_damping),
                ("beta_t", own.tangential_damping),
            )
            if value is not None
        }
        return self.law._replace(**given)

    def during(self, stage: Stage) -> Model:
        """This model with the stage's contact record as its law (`stage_law`): for what
        reads the law from the model, the critical time step of a packing at that stage."""
        return replace(self, law=self.stage_law(stage))

    def stage_wall_velocities(self, stage: Stage) -> np.ndarray:
        """Velocity of each wall during a stage, m/s, (W, 3)."""
        return np.array(
            [stage.wall_velocity(w) for w in self.scenario.walls],
            dtype=np.float64,
        ).reshape(-1, 3)

    @cached_property
    def layout(self) -> Layout:
        """The columns of the scenario's observables rows."""
        walls = tuple(wall.name for wall in self.scenario.walls)
        scenario = self.scenario
        return Layout(
            walls,
            scenario.cell is not None,
            scenario.solid_fraction is not None,
            scenario.reversal.tape,
        )

    def wall_index(self, name: str) -> int:
        return [wall.name for wall in self.scenario.walls].index(name)

    def observe(self, state: State, dyn: Dynamics) -> np.ndarray:
        """An observables row of the state as it is."""
        row = np.zeros((1, self.layout.width))
        observe(
            state.particles,
            state.pairs,
            state.walls,
            state.cell,
            self.law,
            self.moduli,
            dyn,
            row[0],
        )
        return self.complete(row)[0]

    def buffers(self, rows: int) -> tuple[np.ndarray, np.ndarray]:
        """Room for `rows` observables rows and their steps, for the compiled stage loop."""
        return np.zeros((rows, self.layout.width)), np.zeros(rows, dtype=np.int64)

    def complete(self, rows: np.ndarray) -> np.ndarray:
        """Fill the derived columns of observables rows from the others: the deviatoric
        invariant of the contacts' fabric; in a periodic cell the principal stresses
        (eigenvalues of the stress's symmetric part, largest first), the void ratio, the mean
        stress p and the deviator q; and the solid fraction, spheres' volume / (pi R^2 x
        distance between the planes along the cylinder axis)."""
        at = self.layout.column("fabric")
        fabric = rows[:, at : at + 9].reshape(-1, 3, 3)
        rows[:, self.layout.column("fabric_deviator")] = _deviatoric_invariant(fabric)
        if self.scenario.cell is not None:
            at = self.layout.column("stress")
            sigma = rows[:, at : at + 9].reshape(-1, 3, 3)
            sigma = 0.5 * (sigma + sigma.transpose(0, 2, 1))
            principal = np.linalg.eigvalsh(sigma)[:, ::-1]
            at = self.layout.column("principal_stress")
            rows[:, at : at + 3] = principal
            at = self.layout.column("cell_length")
            volume = rows[:, at : at + 3].prod(axis=1)
            rows[:, self.layout.column("void_ratio")] = volume / self.solid_volume - 1.0
            rows[:, self.layout.column("mean_stress")] = np.trace(sigma, axis1=1, axis2=2) / 3.0
            rows[:, self.layout.column("deviator_stress")] = _deviatoric_invariant(sigma)
        container = self.scenario.solid_fraction
        if container is None:
            return rows
        walls = {wall.name: wall for wall in self.scenario.walls}
        cylinder = walls[container.cylinder]
        axis = np.asarray(cylinder.normal) / np.linalg.norm(cylinder.normal)
        a, b = (self.layout.column(f"wall_position/{name}") for name in container.planes)
        height = np.abs((rows[:, a : a + 3] - rows[:, b : b + 3]) @ axis)
        area = np.pi * cylinder.radius**2
        rows[:, self.layout.column("solid_fraction")] = self.solid_volume / (area * height)
        return rows


def _deviatoric_invariant(tensor: np.ndarray) -> np.ndarray:
    """sqrt(3/2 t':t') of each symmetric (3, 3) tensor t, t' its deviator: q of a stress
    (Schofield & Wroth 1968, q = sqrt(3 J_2)), sigma_1 - sigma_3 under axial symmetry."""
    mean = np.trace(tensor, axis1=1, axis2=2) / 3.0
    deviator = tensor - mean[:, None, None] * np.eye(3)
    return np.sqrt(1.5 * (deviator * deviator).sum(axis=(1, 2)))


@dataclass(frozen=True)
class StageStart:
    """What a stage's own contact law did at its start to the contacts the stage before left
    under another (`stages[].contact`), where the forces under the new law are not those
    (`run_stage`: STATIC caps each shear history at the new mu |f_n| and each rolling one
    at its limit, and the viscous damping is the new stage's): the stage then writes its
    own observables row beside the one the stage before ended with at that step, the state
    its reversal returns to. `slid` and `rolled` count the contacts (sphere and wall) whose
    shear and rolling histories the new limits cut, `energy_gone` the elastic energy that
    took, J (`report.info.capped_words` says it in one line)."""

    step: int
    friction: float  # the stage's mu
    slid: int
    rolled: int
    energy_gone: float

    @property
    def capped(self) -> bool:
        """Whether the new law cut any history (else only its damping changed the forces)."""
        return self.slid + self.rolled > 0

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> StageStart | None:
        """A start as `to_json` wrote it; None for '{}', a stage without one."""
        fields = json.loads(text)
        return cls(**fields) if fields else None


@dataclass(frozen=True)
class StageClock:
    """Step and time bounds of a stage; time = first_time + (step - first_step) dt."""

    stage: Stage
    first_step: int
    first_time: float
    dt: float
    end_step: int | None = None  # where the stage ended, if a stop condition ended it early
    start: StageStart | None = None  # where the stage wrote its own row at its first step

    @property
    def last_step(self) -> int:
        return self.end_step if self.end_step is not None else self.first_step + self.stage.steps

    def time(self, step) -> np.ndarray | float:
        return self.first_time + (np.asarray(step) - self.first_step) * self.dt

    def frame_steps(self) -> list[int]:
        """Steps with a trajectory frame: every output_every from the start, and the end."""
        steps = list(range(self.first_step, self.last_step, self.stage.output_every))
        return steps + [self.last_step]


def stage_time_step(model: Model, stage: Stage, state: State) -> float:
    """The time step of a stage starting from `state`: as given, or for 'auto' chosen from
    the state (`timestep.packing.automatic_dt`, with the stage's viscous damping)."""
    dt = model.scenario.stage_dt(stage)
    if dt != "auto":
        return dt
    from revdem_cli.timestep.packing import automatic_dt

    return automatic_dt(state, model.during(stage))


Checkpoint = Callable[[State, StageClock, np.ndarray], None]
"""Called as checkpoint(state, clock, events) after every frame but a stage's last, and where
a signal stopped the stage loop (it then writes the checkpoint and raises)."""


def run_stage(
    state: State,
    model: Model,
    clock: StageClock,
    direction: int,
    writer: TrajectoryWriter,
    progress: Progress | None = None,
    stop_step: int | None = None,
    checkpoint: Checkpoint | None = None,
    events: np.ndarray | None = None,
    stepper: Stepper | None = None,
    tape: Recorder | Replayer | None = None,
    law_before: ContactLaw | None = None,
    end_row_apart: bool = False,
) -> StageClock:
    """Advance `state` through one stage (direction +1) or back through it (direction -1).

    With `events`, the stage's log so far, the state is part-way through the stage at the
    step of a checkpoint, and the stage carries on from there. `stepper` calls the compiled
    loop, and its flag stops it (default: called here, never stopped). `tape`: the
    information tape the stage records going forward, or replays going backward
    (`io.tape`); `checkpoint` writes out what it holds before the state. Returns the clock
    of the stage as it ran: going forward, with what its law did at its start
    (`StageStart`) to the contacts the stage before left under `law_before`, its law, which
    its restart keeps. `end_row_apart`, reversed: the stage after this one began with its
    own row (its `StageStart`) at the step this one ended at, where the row of this stage's
    end is written beside it, as the forward run wrote it."""
    frames = clock.frame_steps()
    if direction < 0:
        frames = frames[::-1]
    if stop_step is not None:
        frames = [s for s in frames if (s - stop_step) * direction <= 0]
        if frames[-1] != stop_step:
            frames.append(stop_step)
    resuming = events is not None
    if frames[0] != state.step and not resuming:
        raise ValueError(
            f"stage {clock.stage.name} starts at step {frames[0]}, state is at {state.step}"
        )
    state.walls.velocity[:] = model.stage_wall_velocities(clock.stage)
    dyn = model.stage_dynamics(clock.stage)
    law = model.stage_law(clock.stage)
    set_cell_motion(state.cell, state.fixed, clock.stage, forward=direction > 0 and not resuming)
    if direction > 0 and not resuming:
        state.walls.origin[:] = state.walls.point  # walls move from where the stage finds them
        clock = _forces_at_start(state, model, clock, dyn, law, law_before)
    every = clock.stage.observable_interval
    buffer, buffer_steps = model.buffers(clock.stage.output_every // every + 2)
    stepper = stepper or Stepper()
    stepper.new_stage()
    stepping = model.stepping(clock.dt, clock.first_step, clock.last_step, every, stepper.halt)
    if events is None:
        events = empty_events()
        apart = clock.start is not None if direction > 0 else end_row_apart
        _record_now(state, model, dyn, clock, writer, events, tape, apart)
    label = f"{clock.stage.name} ({'forward' if direction > 0 else 'reversed'})"
    total = abs(frames[-1] - frames[0])
    if progress is not None:  # shown from the stage's start, the time elapsed counting
        progress(label, abs(state.step - frames[0]), total, len(state.particles.x))
    stop = clock.stage.stop_when if direction > 0 else None
    pauses = frames  # a stop condition is checked at every observables row, and ends the
    if stop is not None:  # stage there with a frame
        pauses = sorted(set(frames) | set(range(frames[0], frames[-1], every)))
    frame_steps = set(frames)
    for target in [s for s in pauses if (s - state.step) * direction > 0]:
        while state.step != target or isinstance(tape, Recorder) and tape.retaking:
            logs = (events, tape.bundle(state, events, law, dyn) if tape else no_tape())
            status, state.step, rows, finding = stepper.advance(
                advance, (*stepping_bundles(state, model, dyn, law, logs[1]), *logs), stepping,
                state.step, target, buffer, buffer_steps,
            )  # fmt: skip
            _write_observables(writer, model, clock, buffer_steps[:rows], buffer[:rows], tape)
            if status == TAPE_FULL:
                tape.flush()
                continue
            if status == TAPE_EMPTY:
                tape.load(state.step)
                continue
            if status == TAPE_MISMATCH:
                raise RunFailed(
                    f"{tape.path}: step {state.step}: an entry for pair ({finding.particle}, "
                    f"{finding.partner}) finds no such pair in the list: the tape is not of "
                    "this run"
                )
            if status == HALTED:  # a signal: the checkpoint is written, and raises Interrupted
                checkpoint(state, clock, events)
                raise RuntimeError(f"the stage loop was halted at step {state.step} for nothing")
            if status == CELL_TOO_SMALL:
                raise CellTooSmall(
                    state.step,
                    state.cell.length,
                    _servo_held(model, clock),
                    _dt_above_critical(clock.dt, critical_time_step(model.scenario)),
                )
            if status == FIXED_OVERFLOW:
                raise OffGrid(state.step, state.fixed, state.ids)
            if status == BLOWN_UP:
                raise BlownUp(
                    state.step,
                    finding,
                    stepping.overlap_limit,
                    [wall.name for wall in model.scenario.walls],
                    state.ids,
                    _likely_cause(
                        model.scenario,
                        clock.dt,
                        _reversed_damping(
                            dyn, law, direction < 0 and not isinstance(tape, Replayer)
                        ),
                        _servo_held(model, clock),
                    ),
                    _frames_held(writer, frames[0], direction),
                )
            if status != OK:
                state.grow_pairs()
        stopped = _stop_reached(state, model, dyn, stop, state.step - clock.first_step)
        if target in frame_steps or stopped:
            _write_frame(writer, state, model, clock, events)
            if progress is not None:  # a stop condition ends the stage: its bar ends there
                done = abs(state.step - frames[0])
                progress(label, done, done if stopped else total, len(state.particles.x))
        if stopped:
            break
        if checkpoint is not None and target in frame_steps and target != frames[-1]:
            checkpoint(state, clock, events)
    if isinstance(tape, Recorder):
        tape.finish(state)
    return clock


def _forces_at_start(
    state: State, model: Model, clock: StageClock, dyn: Dynamics, law: ContactLaw,
    law_before: ContactLaw | None,
) -> StageClock:  # fmt: skip
    """The forces of a stage's start under its own law (STATIC: each history capped at its
    new limit), the pair arrays filled for the stage's first row; `clock` with what that did
    (`StageStart`) where the stage that ended at this step, and wrote its row there, ran
    under another law (`law_before`: its friction or viscous damping) and the contact forces
    or histories are not those it left, else `clock` as it is. Under the same law the row
    of the stage before stands for the start (in fixed point a history at its limit may be
    capped again a grid step lower: a change of the order of round-off)."""
    changing = law_before is not None and law_before != law
    left = _contact_arrays(state) if changing else ()
    elastic = model.layout.column("elastic_energy")
    energy = model.observe(state, dyn)[elastic] if changing else 0.0
    compute_forces(
        *stepping_bundles(state, model, dyn, law),
        STATIC,
        clock.dt,
        0.0,
        empty_events(),
        state.step,
        True,  # the pair arrays: read by the stage's first row
    )
    if not changing:
        return clock
    now = _contact_arrays(state)
    if not any(_changed_contacts(left[kind], now[kind]) for kind in now):
        return clock
    start = StageStart(
        state.step,
        float(law.mu),
        _changed_contacts(left["shear"], now["shear"]),
        _changed_contacts(left["rolling"], now["rolling"]),
        float(energy - model.observe(state, dyn)[elastic]),
    )
    return replace(clock, start=start)


def _contact_arrays(state: State) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Copies of what a stage's law sets at its start, each of the listed pairs and of the
    wall contacts: 'force', 'shear' (the shear histories) and 'rolling' (the rolling ones;
    empty where the law has none)."""
    pairs, walls, n = state.pairs, state.walls, int(state.pairs.count[0])
    return {
        kind: (getattr(pairs, name)[:n].copy(), getattr(walls, name).copy())
        for kind, name in (("force", "force"), ("shear", "history"), ("rolling", "rolling"))
    }


def _changed_contacts(before: tuple[np.ndarray, ...], after: tuple[np.ndarray, ...]) -> int:
    """Contacts (rows of a pair array, a sphere's slots on each wall) whose vector differs
    between two copies of their arrays."""
    return sum(
        int((a != b).reshape(-1, a.shape[-1]).any(axis=1).sum())
        for a, b in zip(before, after, strict=True)
        if a.size
    )


def reversal_history(state: State, model: Model, clock: StageClock) -> None:
    """Give a velocity predictor's history the half-step velocities its reversal predicts
    from: those of the k steps after the state, in the order the reversed run would have
    met them (nearest first). They come from a copy of the state stepped k steps on in the
    stage that ended there, so the reversed run starts with the history a run reversed from
    later would have, and its first step is the forward step with dt -> -dt like every
    other. Velocity Verlet (k = 0) has no history."""
    k = state.particles.v_past.shape[0]
    if k == 0:
        return
    ahead = copy.deepcopy(state)
    dyn = model.stage_dynamics(clock.stage)
    end = ahead.step + k
    stepping = model.stepping(clock.dt, clock.first_step, end, k)
    buffer, buffer_steps = model.buffers(k + 2)
    events = empty_events()
    while ahead.step != end:
        status, ahead.step, _, finding = advance(
            *stepping_bundles(ahead, model, dyn, model.stage_law(clock.stage)), events,
            no_tape(), stepping, ahead.step, end, end, buffer, buffer_steps,
        )  # fmt: skip
        if status not in (OK, PAIR_OVERFLOW):
            raise RunFailed(
                f"step {ahead.step}: the {k} steps after the restart that the velocity "
                f"predictor's reversal history needs failed (status {status})"
            )
        if status == PAIR_OVERFLOW:
            ahead.grow_pairs()
    state.particles.v_past[...] = ahead.particles.v_past[::-1]
    state.particles.omega_past[...] = ahead.particles.omega_past[::-1]


def _servo_held(model: Model, clock: StageClock) -> str:
    """The axes on which a stage holds a stress with the cell's servo, and what makes that
    servo overshoot, in words ("" where none): "the inertial servo of stage isotropic holds
    a stress on x, y and overshoots with a servo_mass too small for the packing's
    stiffness"."""
    axes = list(clock.stage.held_stresses())
    if not axes:
        return ""
    servo = model.scenario.cell.servo
    return (
        f"the {servo} servo of stage {clock.stage.name} holds a stress on {', '.join(axes)} "
        f"and overshoots with {servo_overshoot(servo)} for the packing's stiffness"
    )


def _frames_held(writer: TrajectoryWriter, start: int, direction: int) -> str:
    """What a trajectory holds when its stage, begun at step `start`, fails: forward, the
    frames up to the last written; reversed, those from `start` down to it (the reversal's
    frames go down from its restart's step)."""
    if direction > 0:
        return f"{writer.path} holds the frames up to step {writer.last_step}"
    if writer.last_step == start:
        return f"{writer.path} holds only the frame the reversal started from, step {start}"
    return f"{writer.path} holds the reversed frames from step {start} down to {writer.last_step}"


def _reversed_damping(dyn: Dynamics, law: ContactLaw, backwards: bool) -> str:
    """The damping of a stage run `backwards` without an information tape, which puts
    energy in at each step as it took it out going forward (Hanley 2020 §5.2), in words;
    "" where there is none, or the stage runs forward."""
    kinds = [
        (dyn.local_damping > 0.0, f"local damping {dyn.local_damping:g}"),
        (dyn.drag != 1.0, f"drag {dyn.drag:g}"),
        (law.beta_n > 0.0, f"viscous normal damping {law.beta_n:g}"),
        (law.beta_t > 0.0, f"viscous tangential damping {law.beta_t:g}"),
    ]
    return " and ".join(words for present, words in kinds if present and backwards)


def _dt_above_critical(dt: float, critical: tuple[float, str]) -> str:
    """ "likely cause: dt = ... times the critical time step" where the time step is above
    the `critical` estimate (a run let go on with `--allow-unstable-dt`); "" where not.
    `critical`: (limit in s, where it comes from), as `guard.critical_time_step` gives it."""
    limit, reason = critical
    ratio = abs(dt) / limit
    if not ratio > 1.0:
        return ""
    return (
        f"likely cause: dt = {dt:.3g} s is {times_above(ratio)} times the critical time step "
        f"{limit:.3g} s ({reason})"
    )


def _likely_cause(scenario: Scenario, dt: float, damping: str = "", servo: str = "") -> str:
    """What the time step says about a blow-up: above the critical estimate, the likely
    cause; above the least a sphere in many contacts may need (`guard.CROWDED`), a possible
    one; below that, unlikely to be, and where the stage's `damping` ran backwards
    (`_reversed_damping`), that is; where the stage's `servo` holds a stress
    (`_servo_held`), it is among what may drive the spheres together. The estimate is
    found once, and each sentence quotes the one that decided it."""
    critical = critical_time_step(scenario)
    if above := _dt_above_critical(dt, critical):
        return above
    limit, reason = critical
    ratio = abs(dt) / limit
    of_dt = f"dt = {dt:.3g} s is {ratio:.2g} of the critical time step {limit:.3g} s ({reason})"
    if damping:
        lacking = tape_needs(scenario.integrator)
        tape = f"reversal.tape with {lacking}" if lacking else "reversal.tape"
        return (
            f"likely cause: the stage's {damping}, reversed, puts energy in at each step as it "
            f"took it out going forward (Hanley 2020 §5.2; an information tape, {tape}, "
            f"reverses it exactly); {of_dt}"
        )
    cell = f"the cell ({servo})"
    causes = f"walls, {cell if servo else 'the cell'}, overlaps at the start, velocities"
    drives = f"what drives the spheres together ({causes})"
    crowded = limit / math.sqrt(CROWDED)
    if abs(dt) > crowded:
        return (
            f"{of_dt}, the limit of one contact: a sphere in several contacts has a lower one, "
            f"down to 1/√{CROWDED} of it among {CROWDED} (half in an fcc lattice; `revdem dt "
            f"--restart` gives a packing's own), so the time step may be the cause: try dt "
            f"below {crowded:.3g} s, or look at {drives}"
        )
    return f"{of_dt}, so the time step is an unlikely cause: look at {drives}"


def _stop_reached(state: State, model: Model, dyn: Dynamics, stop, ran: int) -> bool:
    """Whether a stage's stop condition holds in the state as it is, `ran` steps into the
    stage (none before its `after_steps`)."""
    if stop is None or ran < (stop.after_steps or 0):
        return False
    row = model.observe(state, dyn)

    def vector(name: str) -> np.ndarray:
        return row[model.layout.column(name) : model.layout.column(name) + 3]

    if stop.kinetic_energy_below is not None:
        return row[model.layout.column("kinetic_energy")] < stop.kinetic_energy_below
    if stop.solid_fraction_above is not None:  # a container's, or a cell's 1 / (1 + e)
        if model.scenario.solid_fraction is not None:
            return row[model.layout.column("solid_fraction")] > stop.solid_fraction_above
        return 1.0 / (1.0 + row[model.layout.column("void_ratio")]) > stop.solid_fraction_above
    if stop.wall_force_above is not None:
        force = vector(f"wall_force/{stop.wall}")
        return float(np.linalg.norm(force)) > stop.wall_force_above.force
    travel = vector(f"wall_position/{stop.wall}") - state.walls.origin[model.wall_index(stop.wall)]
    return float(np.linalg.norm(travel)) > stop.wall_travel_above.distance


def stepping_bundles(
    state: State, model: Model, dyn: Dynamics, law: ContactLaw, tape: Tape | None = None
) -> tuple:
    """The bundles the kernels step: particles, pairs, walls, cell, the fixed-point state,
    contact law (a stage's, `Model.stage_law`), moduli, dynamics. The pairs hold their list
    of the histories a reversal would miss (`Pairs.earlier`) only where `tape` records by
    prediction (`kernels.tape.predict`): no other pair loop predicts them."""
    pairs = state.pairs
    if not (tape is not None and tape.mode == RECORD and tape.predicting):
        pairs = pairs._replace(earlier=pairs.earlier[:0])
    return (
        state.particles,
        pairs,
        state.walls,
        state.cell,
        state.fixed,
        law,
        model.moduli,
        dyn,
    )


def set_cell_motion(cell: Cell, fixed: Fixed, stage: Stage, forward: bool) -> None:
    """How the cell's edges move during a stage. Going forward, each edge starts from where
    the stage finds it: a strain-rate edge at rate x its length, a servo edge with the rate
    it has, a fixed edge at rest (in fixed-point arithmetic all on their grids). Reversed,
    lengths and rates come from the restart."""
    motions = stage.cell.axes() if stage.cell else [None, None, None]
    for a, motion in enumerate(motions):
        if motion is None:
            cell.control[a], cell.target[a] = FIXED, 0.0
        elif motion.stress is not None:
            cell.control[a], cell.target[a] = STRESS, motion.stress
        else:
            cell.control[a], cell.target[a] = STRAIN_RATE, 0.0
        if forward:
            cell.start[a] = cell.length[a]
            if motion is None:
                cell.rate[a] = 0.0
            elif motion.strain_rate is not None:
                cell.rate[a] = motion.strain_rate * cell.length[a]
    if forward and fixed.v.shape[0] > 0:
        fixed.length[:] = onto_grid(cell.length, fixed.grid[EDGE])
        fixed.rate[:] = onto_grid(cell.rate, fixed.grid[EDGE_RATE])
        cell.start[:] = cell.length


def _write_frame(writer, state: State, model: Model, clock: StageClock, events) -> None:
    """A trajectory frame of the state as it is: the periodic cell's edges as its box, and
    each sphere's stress and the contact list when the scenario asks for them."""
    stress = None
    if model.scenario.output.particle_stress:
        stress = np.zeros((len(state.particles.x), 3, 3))
        particle_stress(state.particles, state.pairs, state.walls, state.cell, stress)
    box = state.cell.length.copy() if state.cell.periodic.any() else None
    time = float(clock.time(state.step))
    contacts = contact_list(state) if model.scenario.output.contacts else None
    writer.frame(state.step, time, state.particles, events, box, stress, state.fixed, contacts)


def _record_now(state, model, dyn, clock, writer, events, tape, apart: bool) -> None:
    """Write the frame and observables of the state as it is (the start of a stage), the
    row unless the run wrote one at this step already (the stage before ended here), which
    stands for this state too, or `apart`, it does not: this stage's law changed the
    contacts at its start (`StageStart`), or reversed, the stage after this one did, whose
    start the row there is. The frame at a step already written is not written again."""
    _write_frame(writer, state, model, clock, events)
    if apart or writer.last_observable_step() != state.step:
        rows = model.observe(state, dyn)[None, :]
        _write_observables(writer, model, clock, np.array([state.step]), rows, tape)


def _write_observables(
    writer: TrajectoryWriter,
    model: Model,
    clock: StageClock,
    steps: np.ndarray,
    rows: np.ndarray,
    tape: Recorder | Replayer | None = None,
) -> None:
    """Complete observables rows and write them; with a tape, the bits it recorded from the
    stage's start to each row's step: going forward those recorded so far, going backward
    those the forward run recorded there (the bits the reversal has yet to give back), so
    that a reversed row is the forward row of its step to the last digit. NaN in a stage
    without a tape."""
    model.complete(rows)
    if model.layout.taped:
        at = model.layout.column("bits_destroyed")
        bits = tape.destroyed_by(steps) if tape is not None else np.nan
        rows[:, at : at + len(MECHANISMS)] = bits
    writer.observables(steps, clock.time(steps), rows)
