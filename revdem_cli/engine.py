"""Runs scenarios: stages forward, the reversed stage backwards, outputs and comparison.

This is the one place that orchestrates a run: which stages run in which direction, into
which files, with which checkpoints and resumption; a stage itself runs in `stage.py`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from revdem_cli.checkpoint import Checkpoints, checkpoint_path, find_checkpoint
from revdem_cli.compare import compare_trajectories, forward_of, refuse_nothing_to_compare
from revdem_cli.config import Scenario
from revdem_cli.errors import InputError, RunFailed, whole_number
from revdem_cli.io import open_hdf5, write_text
from revdem_cli.io.h5md import TrajectoryWriter, open_trajectory
from revdem_cli.io.restart import Restart, Resumption, read_restart, write_restart
from revdem_cli.io.tape import Recorder, Replayer, recorded
from revdem_cli.kernels.events import COLUMNS, KINDS
from revdem_cli.kernels.tape import MECHANISMS
from revdem_cli.stage import (
    Model,
    Progress,
    StageClock,
    StageStart,
    reversal_history,
    run_stage,
    stage_time_step,
)
from revdem_cli.state import State, initial_state


@dataclass
class Outputs:
    forward: Path | None = None
    restart: Path | None = None
    reverse: Path | None = None
    comparison: Path | None = None
    figures: tuple[Path, ...] = ()
    verdict: dict | None = field(default=None, repr=False)  # compare.json's, every frame's
    chosen_dt: dict[str, float] = field(default_factory=dict)  # stages of dt = 'auto', s
    # stages a stop condition ended: (steps run, steps at most, steps between its checks)
    stopped: dict[str, tuple[int, int, int]] = field(default_factory=dict)
    # stages that ran all their steps with their stop condition never met: the condition
    unmet: dict[str, dict] = field(default_factory=dict)
    # stages whose servo ended off its target stress (`_stress_not_held`): axis -> (stress
    # at the stage's end, target), Pa
    unheld: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    # the kind of the cell's servo, 'inertial' or 'proportional', which says what made it
    # overshoot; None without a cell, or where a restart written before runs kept it lacks it
    servo: str | None = None
    # what else the forward run wrote: its stages' information tapes and, where every stage
    # is reversed, their restarts, each (what it is, path)
    stage_files: tuple[tuple[str, Path], ...] = ()
    # exports of its trajectories already there when it started: made from another run's
    stale_exports: tuple[Path, ...] = ()
    # a reversal with no forward trajectory to compare with: where it looked for one
    forward_sought: tuple[Path, ...] = ()
    # stages whose law cut contact histories at their start, where the stage before ended
    # (`stage.StageStart`, its fields)
    capped: dict[str, dict] = field(default_factory=dict)


def output_paths(out_dir: Path, name: str) -> dict[str, Path]:
    return {
        kind: out_dir / f"{name}.{kind}.{ext}"
        for kind, ext in (
            ("forward", "h5"),
            ("restart", "h5"),
            ("tape", "h5"),
            ("reverse", "h5"),
            ("compare", "json"),
        )
    }


def stage_paths(out_dir: Path, name: str, index: int, scenario: Scenario) -> dict[str, Path]:
    """Where the restart and the information tape of stage `index` go: those of the run for
    its last stage, `NAME.stage-K.restart.h5` and `NAME.stage-K.tape.h5` for an earlier one
    (written when `[reversal] all_stages` reverses every stage)."""
    if index == len(scenario.stages) - 1:
        paths = output_paths(out_dir, name)
        return {"restart": paths["restart"], "tape": paths["tape"]}
    return {kind: out_dir / f"{name}.stage-{index}.{kind}.h5" for kind in ("restart", "tape")}


def _writer(
    path: Path, state: State, model: Model, text: str, direction: str, source: str = ""
) -> TrajectoryWriter:
    scenario = model.scenario
    return TrajectoryWriter(
        path,
        state.particles.radius,
        state.particles.mass,
        state.ids,
        state.particles.material,
        scenario.cell is not None,
        scenario.output.particle_stress,
        scenario.integrator.arithmetic == "fixed",
        scenario.output.contacts,
        model.layout.series(),
        (len(KINDS), len(COLUMNS)),
        {
            "direction": direction,
            "dt": scenario.integrator.dt,
            "arithmetic": scenario.integrator.arithmetic,
            "fixed_grid": state.fixed.grid,
            "scenario": text,
            "scenario_json": scenario.model_dump_json(),
            "source_restart": source,
            "event_kinds": list(KINDS),
            "event_columns": list(COLUMNS),
        },
    )


def _continued_writer(
    path: Path, resumption: Resumption, state: State, model: Model, text: str, direction: str,
    source: str = "",
) -> TrajectoryWriter:  # fmt: skip
    """A writer of `path` holding the rows it had at a checkpoint: they are copied into a new
    file, which replaces `path` once complete (a file killed mid-write cannot be appended to
    in place, and one left longer than the checkpoint must be cut back)."""
    fresh = path.with_name(path.name + ".continued")
    writer = _writer(fresh, state, model, text, direction, source)
    try:
        with open_hdf5(path) as old:
            writer.copy_rows(old, resumption.frames, resumption.observables)
    except BaseException:
        writer.close()
        fresh.unlink(missing_ok=True)
        raise
    fresh.replace(path)
    writer.path = path
    return writer


@dataclass(frozen=True)
class Run:
    """One `revdem run` or `revdem reverse`: its scenario and where its files go."""

    model: Model
    text: str  # the scenario file as written
    suffix: str
    out_dir: Path
    checkpoints: Checkpoints

    @classmethod
    def into(cls, out_dir: Path, scenario: Scenario, text: str, suffix: str) -> Run:
        """A run of `scenario` writing into `out_dir`, which is made if need be."""
        out_dir.mkdir(parents=True, exist_ok=True)
        name, interval = scenario.name, scenario.output.checkpoint_interval
        checkpoints = Checkpoints(checkpoint_path(out_dir, name), interval)
        return cls(Model.of(scenario), text, suffix, out_dir, checkpoints)

    @property
    def scenario(self) -> Scenario:
        return self.model.scenario

    @property
    def paths(self) -> dict[str, Path]:
        return output_paths(self.out_dir, self.scenario.name)

    def checkpoint(
        self, state, clock, events, writer, trajectory, place: dict, tape=None, files=("", "")
    ) -> None:
        """Save a checkpoint if one is due: the trajectory (and the information tape being
        recorded, `tape`) written out first, so that they hold every row the checkpoint
        counts. `place`: the rest of its `Resumption`; `files`: as `restart`'s."""
        if not self.checkpoints.due():
            return
        writer.flush()
        if isinstance(tape, Recorder):
            tape.flush(wait=True)
        frames, observables = writer.rows()
        resumption = Resumption(
            events=events.copy(), frames=frames, observables=observables, **place
        )
        self.checkpoints.save(self.restart(state, clock, trajectory, resumption, files))

    def restart(
        self, state, clock, trajectory, resumption=None, files=("", ""), summary: str = "{}"
    ) -> Restart:
        """A restart of the state at the end of (or, with `resumption`, part-way through) the
        stage of `clock`; `files`: the names of the stage's information tape and of the
        restart of the stage before it, which a reversal of every stage goes on from;
        `summary`: what the run says of its stages, where the restart ends it; with what the
        stage's law did at its start (`StageClock.start`), which its reversal writes its
        rows by."""
        tape, previous = files
        return Restart(
            state,
            self.scenario.model_dump_json(),
            self.text,
            self.suffix,
            clock.stage.name,
            str(Path(trajectory).resolve()),
            clock.first_step,
            clock.first_time,
            clock.dt,
            resumption,
            tape,
            previous,
            summary,
            "{}" if clock.start is None else clock.start.to_json(),
        )


def run_scenario(
    scenario: Scenario,
    text: str,
    suffix: str,
    out_dir: Path,
    reverse: bool = True,
    progress: Progress | None = None,
    allow_unstable_dt: bool = False,
    stop_file: Path | None = None,
) -> Outputs:
    """Run every stage forward, save the restart, then reverse the marked stage if asked.

    A time step above the scenario's critical estimate is refused unless allowed. Off the
    main thread, `stop_file` stops the run as a signal would (`Checkpoints.on_signals`).
    """
    if not allow_unstable_dt:
        check_time_step(scenario)
    run = Run.into(out_dir, scenario, text, suffix)
    state = initial_state(scenario)
    reverse = reverse and scenario.reversed_stage is not None
    with run.checkpoints.on_signals(stop_file):
        writer = _writer(run.paths["forward"], state, run.model, text, "forward")
        return _forward(run, state, writer, reverse, progress)


def _forward(
    run: Run,
    state: State,
    writer: TrajectoryWriter,
    reverse: bool,
    progress: Progress | None,
    resume: Restart | None = None,
) -> Outputs:
    """The stages from the first (or from the checkpoint `resume`) into `writer`, then the
    restart, then the reversal if asked."""
    scenario, paths = run.scenario, run.paths
    first = 0 if resume is None else resume.resumption.stage_index
    time = 0.0
    so_far = "{}" if resume is None else resume.resumption.so_far
    chosen, stopped, unmet, unheld, stage_files, _, capped = carried_summary(run.out_dir, so_far)
    servo = scenario.servo  # the run's own: a checkpoint written before may not say it
    with writer:
        for index in range(first, len(scenario.stages)):  # a stage starts where the last ended
            stage = scenario.stages[index]
            events = None
            if resume is not None and index == first:  # carry on part-way through it
                start = resume.stage_first_step, resume.stage_first_time, resume.stage_dt
                clock = StageClock(stage, *start, start=StageStart.from_json(resume.stage_start))
                events = resume.resumption.events
            else:
                clock = StageClock(
                    stage, state.step, time, stage_time_step(run.model, stage, state)
                )
            if scenario.stage_dt(stage) == "auto":
                chosen[stage.name] = clock.dt
            files = _stage_files(run, index)
            tape = None  # the stages a reversal reverses: the last, or with all_stages every one
            if files[0]:
                resumed_at = state.step if events is not None else None
                if ("information tape", run.out_dir / files[0]) not in stage_files:
                    stage_files.append(("information tape", run.out_dir / files[0]))
                tape = Recorder(
                    run.out_dir / files[0], stage.name,
                    (clock.first_step, clock.first_time, clock.dt), state, resumed_at,
                )  # fmt: skip

            place = dict(
                phase="forward", stage_index=index, reverse=reverse, source_restart="",
                stop_step=-1, end_step=-1,
                so_far=summary_so_far(chosen, stopped, unmet, unheld, stage_files, servo, capped),
            )  # fmt: skip

            def checkpoint(state, clock, events, place=place, tape=tape, files=files):
                run.checkpoint(state, clock, events, writer, paths["forward"], place, tape, files)

            before = run.model.stage_law(scenario.stages[index - 1]) if index else None
            clock = run_stage(
                state, run.model, clock, +1, writer, progress, None, checkpoint, events,
                run.checkpoints.stepper, tape, before,
            )  # fmt: skip
            if clock.start is not None and clock.start.capped:
                capped[stage.name] = asdict(clock.start)
            if state.step != clock.last_step:  # its stop condition ended it
                ran = state.step - clock.first_step
                stopped[stage.name] = (ran, stage.steps, stage.observable_interval)
            elif stage.stop_when is not None:
                condition = stage.stop_when.model_dump(exclude_none=True)
                unmet[stage.name] = condition | _motion_left(state, stage.stop_when)
            if off := _stress_not_held(state, run.model, stage):  # however the stage ended
                unheld[stage.name] = off
            time = float(clock.time(state.step))
            if index < len(scenario.stages) - 1 and scenario.reversal.all_stages:
                stage_restart = stage_paths(run.out_dir, scenario.name, index, scenario)
                restart = run.restart(state, clock, paths["forward"], files=files)
                write_restart(stage_restart["restart"], restart)
                stage_files.append((f"restart of {stage.name}", stage_restart["restart"]))
        writer.end()
    reversal_history(state, run.model, clock)  # a velocity predictor's, for the reversal
    last = _stage_files(run, len(scenario.stages) - 1)
    said = summary_so_far(chosen, stopped, unmet, unheld, stage_files, servo, capped)
    write_restart(
        paths["restart"], run.restart(state, clock, paths["forward"], files=last, summary=said)
    )
    told = (chosen, stopped, unmet, unheld, stage_files, servo, capped)
    if reverse:
        restart = read_restart(paths["restart"])
        source = str(paths["restart"].resolve())
        outputs = _reverse(run, restart, source, None, progress, said)
        outputs.forward, outputs.restart = paths["forward"], paths["restart"]
        return _stages_said(outputs, *told)
    outputs = Outputs(forward=paths["forward"], restart=paths["restart"])
    _stages_said(outputs, *told)
    run.checkpoints.discard()
    run.checkpoints.finish("its figures were drawn; its trajectory and restart are whole")
    outputs.figures = _figures(scenario, paths["forward"], None, run.out_dir)
    return outputs


def _stages_said(
    outputs: Outputs, chosen, stopped, unmet, unheld, stage_files, servo: str | None, capped
) -> Outputs:
    """`outputs` told what the run says of its stages (`summary_so_far`'s, in its order)."""
    outputs.chosen_dt, outputs.stopped, outputs.unmet = chosen, stopped, unmet
    outputs.unheld, outputs.stage_files, outputs.servo = unheld, tuple(stage_files), servo
    outputs.capped = capped
    return outputs


def _motion_left(state: State, stop) -> dict:
    """Where a stage ran all its steps short of kinetic_energy_below: the spheres' kinetic
    energy at its end, Σ ½ m v² + ½ I ω², and the share of it in their rotation, which says
    why: a sphere spinning about its contact normal meets no moment (no law
    resists twisting) and local damping leaves a spin no moment drives."""
    if stop.kinetic_energy_below is None:
        return {}
    p = state.particles
    moving = 0.5 * float((p.mass[:, None] * p.v**2).sum())
    spinning = 0.5 * float((p.inertia[:, None] * p.omega**2).sum())
    total = moving + spinning
    return {"kinetic_energy_at_end": total, "rotation_share": spinning / total if total else 0.0}


HELD = 0.05
"""How far from its target, as a fraction of it, a servo may leave a stress at its stage's
end before the run's summary says the stage did not hold it."""


def _stress_not_held(state: State, model, stage) -> dict[str, tuple[float, float]]:
    """Where `stage` holds a stress on an axis of the cell with its servo and ends off that
    target by more than HELD, after all its steps or where its stop condition ended it
    (one met before the servo got there, a kinetic energy low at once or a solid fraction
    reached on the way: the next stage would start from a sample its user believes held):
    each such axis's (stress, target), Pa. A servo that overshoots (an inertial servo_mass
    too small, a proportional servo_gain too large) or a stage too short for it ends so;
    the run goes on, and its summary says so."""
    targets = stage.held_stresses()
    if not targets:
        return {}
    row = model.observe(state, model.stage_dynamics(stage))
    at = model.layout.column("stress")
    sigma = row[at : at + 9].reshape(3, 3)
    reached = {axis: float(sigma["xyz".index(axis), "xyz".index(axis)]) for axis in targets}
    return {
        axis: (reached[axis], target)
        for axis, target in targets.items()
        if not abs(reached[axis] - target) <= HELD * target
    }


def summary_so_far(
    chosen: dict, stopped: dict, unmet: dict, unheld: dict, stage_files: list,
    servo: str | None, capped: dict,
) -> str:  # fmt: skip
    """What a run's summary says of the stages run so far (`Outputs`' chosen_dt, stopped,
    unmet, unheld, stage_files, the files by name, servo and capped), as JSON, which a
    checkpoint keeps so that the run resumed says it too."""
    files = [[label, Path(path).name] for label, path in stage_files]
    said = {"chosen_dt": chosen, "stopped": stopped, "unmet": unmet, "unheld": unheld}
    return json.dumps(said | {"stage_files": files, "servo": servo, "capped": capped})


def carried_summary(
    out_dir: Path, so_far: str
) -> tuple[dict, dict, dict, dict, list, str | None, dict]:
    """`summary_so_far` read back: (chosen_dt, stopped, unmet, unheld, stage_files, servo,
    capped), the files in the run's folder `out_dir` as it is named now; servo None where
    the run did not keep it (a checkpoint or restart written before runs did)."""
    said = json.loads(so_far)
    stopped = {name: tuple(counts) for name, counts in said.get("stopped", {}).items()}
    unheld = {
        name: {axis: tuple(pair) for axis, pair in axes.items()}
        for name, axes in said.get("unheld", {}).items()
    }
    files = [(label, out_dir / name) for label, name in said.get("stage_files", [])]
    chosen, unmet = dict(said.get("chosen_dt", {})), dict(said.get("unmet", {}))
    return chosen, stopped, unmet, unheld, files, said.get("servo"), dict(said.get("capped", {}))


def _stage_files(run: Run, index: int) -> tuple[str, str]:
    """The names of the information tape of stage `index` ("" where it has none) and of the
    restart of the stage before it ("" unless every stage is reversed)."""
    scenario = run.scenario
    last = index == len(scenario.stages) - 1
    reversal = scenario.reversal
    tape = stage_paths(run.out_dir, scenario.name, index, scenario)["tape"].name
    previous = ""
    if reversal.all_stages and index > 0:
        previous = stage_paths(run.out_dir, scenario.name, index - 1, scenario)["restart"].name
    return (tape if reversal.tape and (last or reversal.all_stages) else ""), previous


def check_time_step(scenario: Scenario, origin: str = "") -> None:
    """Refuse a time step above the critical estimate of `timestep.guard`, or above its
    kinematic limit, saying by how much; the message starts with `origin`, the file the
    scenario was read from, where given."""
    from revdem_cli.timestep.guard import time_step_excess

    excess = time_step_excess(scenario)
    if excess is not None:
        where = f"{origin}: " if origin else ""
        raise InputError(f"{where}{excess}; use a smaller dt, or --allow-unstable-dt to run anyway")


def reverse_run(
    restart_path: Path,
    out_dir: Path | None = None,
    steps: int | None = None,
    progress: Progress | None = None,
) -> Outputs:
    """Run the stage that ended at a restart backwards, then compare with the forward run."""
    restart = read_restart(restart_path)
    scenario = Scenario.model_validate_json(restart.scenario_json)
    out_dir = Path(out_dir) if out_dir is not None else Path(restart_path).parent
    run = Run.into(out_dir, scenario, restart.scenario_text, restart.scenario_suffix)
    with run.checkpoints.on_signals():
        return _reverse(run, restart, str(Path(restart_path).resolve()), steps, progress)


def _reverse_clock(scenario: Scenario, restart: Restart, end_step: int) -> StageClock:
    """The clock of the stage a restart ended, which ended at `end_step`."""
    stage = next(s for s in scenario.stages if s.name == restart.stage)
    return StageClock(
        stage,
        restart.stage_first_step,
        restart.stage_first_time,
        restart.stage_dt,
        end_step,
        StageStart.from_json(restart.stage_start),
    )


def _reverse(
    run: Run,
    start: Restart,
    source: str,
    steps: int | None,
    progress: Progress | None,
    so_far: str = "{}",
) -> Outputs:
    """The stage that ended at the restart `start` backwards, or on from `start` when it is
    a checkpoint of this reversal; on through the stages before it where the restart names
    the one before (`[reversal] all_stages`); then the comparison with the forward run and
    the figures. `source`: the restart file's path; `so_far`: what the summary says of the
    forward run, which its checkpoints keep (`summary_so_far`)."""
    scenario, paths = run.scenario, run.paths
    resumption = start.resumption
    text = start.scenario_text
    if resumption is None:
        clock = _reverse_clock(scenario, start, start.state.step)
        length = clock.last_step - clock.first_step
        if steps is not None and not (whole_number(steps) and 0 < steps <= length):
            raise InputError(
                f"--steps {steps!r}: must be a whole number between 1 and the stage's {length} "
                "steps"
            )
        stop = clock.first_step if steps is None else start.state.step - steps
        forward, sought = forward_of(Path(source))  # of another run: refused before stepping
        if forward is not None:
            refuse_nothing_to_compare(forward, start.state.step, stop)
        events, began = None, None
        tapes = _replayers(scenario, start, source, clock, stop)  # refused before the file
        writer = _writer(paths["reverse"], start.state, run.model, text, "reverse", source)
    else:
        stop, events = resumption.stop_step, resumption.events
        sought = (Path(start.trajectory),)  # where it was found when the reversal began
        forward = sought[0] if sought[0].is_file() else None
        clock = _reverse_clock(scenario, start, resumption.end_step)
        began = _source_restart(paths["reverse"])  # where the reversal began; `source` is
        tapes = _replayers(scenario, start, source, clock, stop)  # that of the stage it is in
        writer = _continued_writer(
            paths["reverse"], resumption, start.state, run.model, text, "reverse", began
        )
    with writer:
        for stage, tape in enumerate(tapes):
            apart = False  # the stage reversed before this one began with its own row
            if stage:
                apart = clock.start is not None
                start, source = _stage_before(start, source)
                clock = _reverse_clock(scenario, start, start.state.step)
                stop, events = clock.first_step, None
            _reverse_stage(
                run, start, source, clock, stop, events, writer, tape, progress, so_far,
                forward or Path(start.trajectory), apart,
            )  # fmt: skip
        writer.end()
    # resumed, the restart the reversal began from (`resume_run` reports it)
    outputs = Outputs(reverse=paths["reverse"], restart=Path(began) if began else None)
    outputs.forward_sought = () if forward is not None else sought
    run.checkpoints.finish(
        "its comparison and figures were written; its trajectories and restart are whole "
        "(revdem compare FORWARD REVERSE gives the verdict)"
    )
    if forward is not None:
        outputs.forward = forward
        read = {tape.path.resolve(): tape.summary for tape in tapes if tape is not None}
        verdict = compare_trajectories(forward, paths["reverse"], scenario.reversal, read)
        write_text(paths["compare"], json.dumps(verdict, indent=2) + "\n")
        outputs.comparison, outputs.verdict = paths["compare"], verdict
        run.checkpoints.finish(
            f"its figures were drawn; its trajectories, restart and comparison "
            f"{paths['compare'].name} are whole"
        )
        outputs.figures = _figures(scenario, forward, paths["reverse"], run.out_dir)
    run.checkpoints.discard()
    return outputs


def _source_restart(reversed_trajectory: Path) -> str:
    """The restart a reversed run began from (its trajectory's `source_restart`), which a
    reversal of every stage, resumed in an earlier stage, keeps naming."""
    with open_trajectory(reversed_trajectory) as f:
        return str(f["parameters/revdem"].attrs["source_restart"])


def _replayers(
    scenario: Scenario, start: Restart, source: str, clock: StageClock, stop: int
) -> list[Replayer | None]:
    """The information tapes a reversal from the restart `start` (the file `source`, of the
    stage of `clock`) back to step `stop` replays, one a stage it reverses, its own stage's
    first (None where it has none): where every stage is reversed and it goes back to its
    stage's start, on through the stages before, each found from the restart at the end of
    the one before (`previous`). Every tape is checked here (`Replayer`), and the restarts
    before read, so that a missing or damaged one is refused before the first step, not
    once the stages after it have been reversed. A stage's bits at its first step, where
    the forward run's row there is the end of the stage before (`_replayer`), are that
    stage's tape's."""
    tapes = [_replayer(scenario, start, source, clock)]
    while start.previous:  # every stage reversed: the stage before has a tape
        if stop != clock.first_step:  # the reversal stops within this stage
            if tapes[-1].before is not None:
                index = _stage_index(scenario, clock) - 1
                earlier = stage_paths(Path(source).parent, scenario.name, index, scenario)
                tapes[-1].before = recorded(earlier["tape"])
            break
        source = str(Path(source).parent / start.previous)
        start = read_restart(source)
        clock = _reverse_clock(scenario, start, start.state.step)
        stop = clock.first_step
        tapes.append(_replayer(scenario, start, source, clock))
        if tapes[-2].before is not None:
            tapes[-2].before = tapes[-1].recorded
    return tapes


def _replayer(
    scenario: Scenario, start: Restart, source: str, clock: StageClock
) -> Replayer | None:
    """The information tape a restart names, to replay, or None. Its bits at the stage's
    first step are NaN after a stage whose row there is the forward run's only one (those of
    the stage before where its tape is read, `_replayers`); the tape's own, zero, at the
    first stage's and where the stage wrote its own row beside the stage before's
    (`StageClock.start`)."""
    if not start.tape:
        return None
    after = _stage_index(scenario, clock) > 0 and clock.start is None
    before = np.full(len(MECHANISMS), np.nan) if after else None
    path = Path(source).parent / start.tape
    particles = len(start.state.particles.x)
    end = start.state.fixed if start.resumption is None else None  # a checkpoint: part-way
    span = (clock.first_step, clock.last_step)
    return Replayer(path, clock.stage.name, span, particles, source, end, before)


def _stage_index(scenario: Scenario, clock: StageClock) -> int:
    """The place of the stage of `clock` among the scenario's stages."""
    return [stage.name for stage in scenario.stages].index(clock.stage.name)


def _reverse_stage(
    run, start, source, clock, stop, events, writer, tape, progress, so_far, forward: Path,
    end_row_apart: bool = False,
) -> None:  # fmt: skip
    """One stage of a reversal, from the state of `start` back to `stop`, into `writer`;
    its checkpoints name `forward`, the forward trajectory found when the reversal began
    (beside the restart, where the one the restart names is not there). `end_row_apart`:
    the stage after it began with its own row where this one ended (`run_stage`)."""
    place = dict(
        phase="reverse", stage_index=-1, reverse=False, source_restart=source, stop_step=stop,
        end_step=clock.last_step, so_far=so_far,
    )  # fmt: skip
    files = (start.tape, start.previous)

    def checkpoint(state, clock, events):
        run.checkpoint(state, clock, events, writer, forward, place, tape, files)

    run_stage(
        start.state, run.model, clock, -1, writer, progress, stop, checkpoint, events,
        run.checkpoints.stepper, tape, end_row_apart=end_row_apart,
    )  # fmt: skip


def _stage_before(after: Restart, source: str) -> tuple[Restart, str]:
    """The restart at the end of the stage before the one `after` ended, which a reversal of
    every stage goes on from: its state is where the reversal has arrived, but for what the
    next stage's start set (its forces under the next stage's law, the cell's and walls'
    motion), which the restart gives back. RunFailed if the spheres' integers differ."""
    path = Path(source).parent / after.previous
    before = read_restart(path)
    for name in ("x", "v", "omega"):
        if not np.array_equal(getattr(before.state.fixed, name), getattr(after.state.fixed, name)):
            raise RunFailed(
                f"{path}: the reversal reached step {after.state.step} with other integers "
                f"({name}) than the forward run had at the end of stage {before.stage}"
            )
    return before, str(path)


def resume_run(
    out_dir: Path, progress: Progress | None = None, stop_file: Path | None = None
) -> Outputs:
    """Continue the run whose checkpoint is in `out_dir` to its end, as if it had never
    stopped: the trajectory it writes is the one the whole run would have written
    (`stop_file`: as `run_scenario`'s)."""
    path = find_checkpoint(out_dir)
    resume = read_restart(path, checkpoint=True)
    scenario = Scenario.model_validate_json(resume.scenario_json)
    run = Run.into(Path(out_dir), scenario, resume.scenario_text, resume.scenario_suffix)
    place = resume.resumption
    _check_continued(run.paths[place.phase], path, resume, scenario)  # its phase's trajectory
    with run.checkpoints.on_signals(stop_file):
        if place.phase == "forward":
            text = resume.scenario_text
            writer = _continued_writer(
                run.paths["forward"], place, resume.state, run.model, text, "forward"
            )
            return _forward(run, resume.state, writer, place.reverse, progress, resume)
        outputs = _reverse(run, resume, place.source_restart, None, progress, place.so_far)
    *carried, _, capped = carried_summary(run.out_dir, place.so_far)
    _stages_said(outputs, *carried, run.scenario.servo, capped)
    for kind in ("forward", "restart"):  # named as the run's folder is named now
        path = getattr(outputs, kind)
        if path is not None and path.resolve() == run.paths[kind].resolve():
            setattr(outputs, kind, run.paths[kind])
    return outputs


def _check_continued(
    trajectory: Path, checkpoint: Path, resume: Restart, scenario: Scenario
) -> None:
    """InputError unless `trajectory` is the one the run of the checkpoint `resume` (the
    file `checkpoint`, of `scenario`) was writing: a resumed run copies the rows the
    checkpoint counts by their number (`_continued_writer`), and would splice another run's
    into its own. It is where it stores the checkpoint's scenario (`compare.runs_apart`)
    and the frames the checkpoint counts are those up to its step: the last of them at or
    before that step, the next, if there is one, at or after it, in the direction the run
    went."""
    from revdem_cli.compare import runs_apart
    from revdem_cli.io import stored_scenario
    from revdem_cli.io.h5md import frame_steps

    with open_trajectory(trajectory) as f:
        stored = stored_scenario(f["parameters/revdem"].attrs["scenario_json"], trajectory)
        steps = frame_steps(f)
    step, frames = resume.state.step, resume.resumption.frames
    ahead = (steps - step) * (1 if resume.resumption.phase == "forward" else -1)
    why = runs_apart(scenario, stored)
    if not why and len(steps) < frames:
        why = f"that run had written {frames} frames by step {step}, and it holds {len(steps)}"
    elif not why:
        last_before = frames == 0 or ahead[frames - 1] <= 0
        next_after = len(steps) == frames or ahead[frames] >= 0
        if not (last_before and next_after):
            here = [
                f"frame {k + 1} at step {steps[k]}"
                for k in (frames - 1, frames)
                if 0 <= k < len(steps)
            ]
            why = (
                f"that run had written frames 1 to {frames} by step {step}; it has "
                + " and ".join(here)
            )
    if why:
        raise InputError(
            f"{trajectory}: not the trajectory the run of {checkpoint} was writing: {why}"
        )


def _figures(
    scenario: Scenario, forward: Path, reverse: Path | None, out_dir: Path
) -> tuple[Path, ...]:
    from revdem_cli.report.figures import FIGURES

    return tuple(
        FIGURES[kind](forward, reverse, out_dir / f"{scenario.name}.{kind}.png")
        for kind in scenario.output.figures
    )
