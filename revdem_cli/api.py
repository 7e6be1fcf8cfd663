"""revdem from Python: the engine the command line drives, with its checks, and the results
as numpy arrays.

    from revdem_cli import api as revdem

    experiment = revdem.load("configs/collision_shear.toml")
    experiment = experiment.changed({"contact.friction": 0.3, "stages.0.steps": 12000})
    result = revdem.run(experiment, "out/shear", force=True)
    result.comparison["reversible"]                    # False: friction destroyed information
    time, energy = result.observable("kinetic_energy")  # forward; run="reverse" for the other

Bad input raises `revdem_cli.errors.InputError` with the one line the command line prints;
a run that cannot go on raises `RunFailed`; SIGINT or SIGTERM stops a run with
`revdem_cli.checkpoint.Interrupted` once its checkpoint is written (`resume` goes on), or
after its last step with `Unfinished`, and stops a sweep with `SweepInterrupted` (an
Interrupted) once its table is written; these derive from BaseException, as
KeyboardInterrupt does, so that `except Exception:` does not take them for a failure. No
progress is shown unless asked for (`progress=True`). `read` gives the Result of a run
written before. A folder given as an empty text is refused, not taken for the working
folder, as `revdem run --out ''` is.
"""

from __future__ import annotations

import copy
import functools
import signal
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from revdem_cli.checkpoint import Interrupted
from revdem_cli.config import Scenario
from revdem_cli.engine import Outputs
from revdem_cli.errors import InputError, path_problem, whole_number
from revdem_cli.io.lock import sole_writer


def _paths_checked(function):
    """`function` with an OSError over a path given that cannot be used (a file where a
    folder is needed, a folder that cannot be made) raised as InputError with the line the
    command line prints for it (`errors.path_problem`); other OSErrors, the machine's, as
    they are."""

    @functools.wraps(function)
    def checked(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        except OSError as exc:
            problem = path_problem(exc)
            if problem is None:
                raise
            raise InputError(problem) from None

    return checked


def _path(value, what: str) -> Path:
    """A path argument as a Path; InputError naming `what` for anything else."""
    if not isinstance(value, str | Path):
        raise InputError(f"{what}: a path (str or Path), not {type(value).__name__}")
    return Path(value)


def _check_switches(**switches) -> None:
    """InputError naming the first of the keyword arguments `switches` that is not True or
    False (numpy's bools too): a text such as "no" would pass for True."""
    for name, value in switches.items():
        if not isinstance(value, bool | np.bool_):
            raise InputError(f"{name}={value!r}: True or False, not {type(value).__name__}")


def use_threads(threads: int | None) -> None:
    """Compute with at most `threads` threads from here on (None: the cores this process may
    use), as `--threads` sets them; the progress display's first line says how many.
    InputError for a count that is not a whole number from 1 to numba's pool
    (`check_threads`)."""
    from revdem_cli import threads as pool

    check_threads(threads)
    pool.use(threads)


def check_threads(threads: int | None, here: bool = True) -> None:
    """InputError for a `--threads` count that is not a whole number from 1 to numba's pool
    (`threads.check`), or, where the pool is not this machine's (`here` False: the workers
    of a scheduler, each of which checks the count against its own, `sweep.run_variant`),
    not a whole number 1 or more: the count of a run, or of each variant of a sweep."""
    from revdem_cli import threads as pool

    if threads is None:
        return
    if not whole_number(threads):
        raise InputError(f"--threads {threads!r}: must be a whole number, 1 or more")
    if here:
        try:
            pool.check(threads)
        except ValueError as exc:
            raise InputError(f"--threads {threads}: {exc}") from None
    elif threads < 1:
        raise InputError(f"--threads {threads}: must be a whole number, 1 or more")


def _folder(value, what: str) -> Path:
    """A folder argument as a Path (`_path`); an empty text is refused, not taken for the
    working folder (which `Path("")` is), as `revdem run --out ''` refuses it."""
    if isinstance(value, str) and not value.strip():
        raise InputError(f"{what}: an empty path; give a folder ('.' for this one)")
    return _path(value, what)


@dataclass(frozen=True)
class Experiment:
    """A validated scenario, with the fields it was made from and where they came from."""

    scenario: Scenario
    fields: dict  # the scenario's fields as parsed, with every change made
    origin: str  # the file it was read from, or "<dict>"
    base: Path  # the folder files it names are relative to
    text: str  # kept in the outputs: the file's text, or the fields as YAML
    suffix: str  # the format of `text`

    @property
    def name(self) -> str:
        return self.scenario.name

    def changed(self, changes: Mapping[str, Any], host: bool = True) -> Experiment:
        """This experiment with the fields at dotted paths (as `--set` names them,
        `stages.0.steps`) set to Python values, checked again."""
        fields = _changed(self.fields, changes, self.origin)
        text, suffix = (self.text, self.suffix) if self.origin != "<dict>" else _yaml(fields)
        return _experiment(fields, self.origin, self.base, text, suffix, host)


def _changed(
    fields: dict, changes: Mapping[str, Any] | None, origin: str, overrides: Sequence[str] = ()
) -> dict:
    """A copy of `fields` with `changes` made, numpy's numbers and arrays anywhere in either
    as Python's (`_plain`); an InputError names `origin`, the fields' file or <dict>, or
    `changes` where they are not a mapping of dotted paths (text) to values. A field that
    `changes` names twice (`stages.0.steps` and `stages[0].steps`), or that one of
    `overrides` (the `--set` texts made before) sets too, is refused, as `--set` refuses
    it, not set to the last value given."""
    from revdem_cli.config import set_field
    from revdem_cli.config.loader import dotted, split_override

    changes = {} if changes is None else changes
    if not isinstance(changes, Mapping):
        raise InputError(
            "changes: a mapping of dotted paths to values, {'stages.0.steps': 100}, not "
            f"{type(changes).__name__}"
        )
    given = {split_override(item)[0]: f"overrides {item!r}" for item in overrides}
    fields = _plain(fields)
    for key, value in changes.items():
        if not isinstance(key, str):
            raise InputError(
                f"changes: the key {key!r}: a dotted path as text, 'stages.0.steps', not "
                f"{type(key).__name__}"
            )
        name = dotted(key)
        if name in given:
            raise InputError(f"changes[{key!r}]: {name} is given twice (also {given[name]})")
        given[name] = f"changes[{key!r}]"
        set_field(fields, name, _plain(value), f"{origin}: ")
    return fields


def _plain(value):
    """A copy of `value` as a scenario file holds it: numpy's numbers and arrays at any depth
    as Python's (floats, ints, bools, lists), every mapping as a dict, every tuple as a
    list; YAML, which keeps the fields of a dict as text, writes no other."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, Mapping):
        return {_plain(key): _plain(inner) for key, inner in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(inner) for inner in value]
    return copy.deepcopy(value)


def _experiment(fields: dict, origin: str, base: Path, text: str, suffix: str, host: bool):
    """The experiment of a scenario's fields, checked as a scenario file is (`revdem run`'s
    checks of this machine too, with `host`)."""
    from revdem_cli.config import scenario_from_data

    _check_switches(host=host)
    scenario = scenario_from_data(copy.deepcopy(fields), origin, base, host)
    return Experiment(scenario, fields, origin, base, text, suffix)


def _yaml(fields: dict) -> tuple[str, str]:
    import yaml

    return yaml.safe_dump(fields, sort_keys=False), ".yaml"


def load(
    path: str | Path,
    changes: Mapping[str, Any] | None = None,
    overrides: Sequence[str] = (),
    host: bool = True,
) -> Experiment:
    """The experiment of a scenario file (TOML or YAML), with `changes` (Python values at
    dotted paths) and `overrides` (`--set` texts, `key=value` with the value in TOML) made;
    a field that both set is refused, as a field given twice to `--set` is."""
    from revdem_cli.config import apply_overrides, parse_text
    from revdem_cli.config.loader import read_scenario_text

    path = _path(path, "path")
    if isinstance(overrides, str):
        raise InputError(
            f"overrides: a list of key=value texts, not one text; give [{overrides!r}]"
        )
    text, suffix, overrides = read_scenario_text(path), path.suffix.lower(), list(overrides)
    fields = apply_overrides(parse_text(text, suffix, str(path)), overrides, str(path))
    fields = _changed(fields, changes, str(path), overrides)
    return _experiment(fields, str(path), path.parent, text, suffix, host)


def from_dict(
    fields: Mapping,
    base: str | Path = ".",
    changes: Mapping[str, Any] | None = None,
    host: bool = True,
) -> Experiment:
    """The experiment of a scenario given as a dict of its fields (files it names are
    relative to `base`), with `changes` made."""
    if not isinstance(fields, Mapping):
        raise InputError(f"<dict>: the scenario's fields as a dict, not {type(fields).__name__}")
    fields = _changed(fields, changes, "<dict>")
    return _experiment(fields, "<dict>", Path(base), *_yaml(fields), host)


@dataclass(frozen=True)
class Result:
    """What a run wrote, and its numbers as arrays."""

    outputs: Outputs

    @property
    def comparison(self) -> dict | None:
        """The forward-versus-reversed comparison (`compare.json`), None without reversal."""
        return self.outputs.verdict

    def trajectory(self, run: str = "forward") -> Path:
        path = {"forward": self.outputs.forward, "reverse": self.outputs.reverse}.get(run)
        if path is None:
            raise InputError(f"no {run} trajectory (runs: forward, reverse where reversed)")
        return path

    def observable(self, name: str, run: str = "forward") -> tuple[np.ndarray, np.ndarray]:
        """(time in s, values) of an observable of the forward or the reversed run, a row a
        step, but two at a step where a stage began with its own row beside the end of the
        stage before (its law cut contact histories or changed the forces there,
        `stage.StageStart`): the forward run's earlier stage's first, the reversed run's
        later."""
        from revdem_cli.io.h5md import observable_names, open_trajectory, read_observable

        with open_trajectory(self.trajectory(run)) as f:
            known = observable_names(f)
            if name not in known:
                raise InputError(f"no observable '{name}' (the run has: {', '.join(known)})")
            return read_observable(f, name)

    def observables(self, run: str = "forward") -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Every observable of a run by name, as `observable` gives it, read from the
        trajectory opened (and checked) once."""
        from revdem_cli.io.h5md import observable_names, open_trajectory, read_observable

        with open_trajectory(self.trajectory(run)) as f:
            return {name: read_observable(f, name) for name in observable_names(f)}

    @property
    def ended(self) -> bool | None:
        """Whether the forward run reached its end: False for one that failed (a blow-up) or
        was stopped (`revdem info` calls it unfinished), None for a trajectory written
        before trajectories said."""
        from revdem_cli.io.h5md import ended, open_trajectory

        with open_trajectory(self.trajectory()) as f:
            return ended(f)

    def spheres(self, run: str = "forward") -> dict[str, np.ndarray]:
        """What each sphere keeps through a run, [N] in the frames' order: radius (m), mass
        (kg), id (the outputs' numbering) and material (its index in [materials])."""
        from revdem_cli.io.h5md import open_trajectory

        with open_trajectory(self.trajectory(run)) as f:
            group = f["particles/all"]
            names = {"radius": "radius", "mass": "mass", "id": "id", "material": "species"}
            return {name: group[stored][:] for name, stored in names.items()}

    def frames(self, field: str = "position", run: str = "forward") -> tuple[np.ndarray, ...]:
        """(steps, times in s, values [F, N, ...]) of a per-sphere field at every frame:
        position, velocity, angular_velocity or force [F, N, 3]; where the run keeps them,
        stress [F, N, 3, 3] (`[output] particle_stress`) and in fixed-point arithmetic the
        integer state, position_grid, velocity_grid and angular_velocity_grid."""
        from revdem_cli.io import FRAME_FIELDS, GRID_FIELDS
        from revdem_cli.io.h5md import open_trajectory

        with open_trajectory(self.trajectory(run)) as f:
            kept = [
                name
                for name in (*FRAME_FIELDS, "stress", *GRID_FIELDS)
                if f"particles/all/{name}" in f
            ]
            if field not in kept:
                raise InputError(f"no frame field '{field}' (fields: {', '.join(kept)})")
            group = f[f"particles/all/{field}"]
            steps = group["step"][:]
            frames = len(steps)
            return steps, group["time"][:frames], group["value"][:frames]

    def contacts(self, frame: int = -1, run: str = "forward") -> dict[str, np.ndarray] | None:
        """The contact list of a frame (`[output] contacts`), None if the run has none."""
        from revdem_cli.io.h5md import open_trajectory, read_contacts

        with open_trajectory(self.trajectory(run)) as f:
            return read_contacts(f, frame)


def output_paths_of(spec: Scenario, out: Path, reverse: bool) -> list[Path]:
    """Every file a run of the scenario `spec` into `out` writes."""
    from revdem_cli.engine import output_paths

    paths = output_paths(out, spec.name)
    written = [paths["forward"], paths["restart"]]
    if spec.reversal.tape:
        written.append(paths["tape"])
    if spec.reversal.all_stages:
        from revdem_cli.engine import stage_paths

        for index in range(len(spec.stages) - 1):
            written += stage_paths(out, spec.name, index, spec).values()
    if reverse and spec.reversed_stage is not None:
        written += [paths["reverse"], paths["compare"]]
    return written + figure_paths(out, spec)


def earlier_outputs(out: Path, name: str) -> list[Path]:
    """Every output that some run named `name` may have written into `out`, whatever its
    settings (`output_paths_of`): a run refuses to start beside any of them unless forced,
    and forced removes them all, so that a reversal, its verdict, a stage's restart or a
    figure of an earlier run does not pass for its own (`revdem run --no-reverse --force`
    kept the earlier verdict, which `revdem info` and `report` then read as the new run's)."""
    import re
    from glob import escape

    from revdem_cli.config.schema import FIGURE_KINDS
    from revdem_cli.engine import output_paths

    stage = re.compile(rf"{re.escape(name)}\.stage-\d+\.(restart|tape)\.h5")
    stages = [path for path in out.glob(f"{escape(name)}.stage-*.h5") if stage.fullmatch(path.name)]
    figures = [out / f"{name}.{kind}.png" for kind in FIGURE_KINDS]
    return [*output_paths(out, name).values(), *sorted(stages), *figures]


def figure_paths(out: Path, spec: Scenario) -> list[Path]:
    """The figures a run of `spec` writes into `out`."""
    return [out / f"{spec.name}.{kind}.png" for kind in spec.output.figures]


def keep_outputs(
    paths: list[Path], force: bool, of: str = "run", replaced: list[Path] | tuple = ()
) -> None:
    """Refuse to overwrite outputs of an earlier run unless forced, naming the first one;
    forced, remove them all before the run starts, so that a run that fails leaves none of
    the earlier run's files beside its own (a verdict, a restart of another run). A symbolic
    link at an output's place (dangling or not) counts as an output: it is removed, not
    written through. `replaced`: outputs removed unasked where none of `paths` is there (a
    forward run's figures, drawn again with its reversal beside it), and counted among the
    earlier run's where one is, the refusal saying how many it would replace."""
    existing = [path for path in paths if path.exists() or path.is_symlink()]
    also = [path for path in replaced if path.exists() or path.is_symlink()]
    if existing and not force:
        more = len(existing) - 1 + len(also)
        others = f" (and {more} more output{'s' * (more > 1)} of the earlier {of})" if more else ""
        link = " (a symbolic link)" if existing[0].is_symlink() else ""
        raise InputError(f"{existing[0]}: exists{link}{others}; use --force to overwrite")
    for path in existing + also:
        path.unlink()


def stale_exports(written: list[Path], out: Path, name: str) -> tuple[Path, ...]:
    """The exports (`revdem export`'s default targets) of the trajectories among `written`
    that are there before a run writes those trajectories: made from an earlier run's.

    They are kept, and the run's summary lists them. An export is not an output of the run:
    the run never writes one, and the user made it, perhaps for a ParaView or OVITO session
    that still opens it; removed by --force, which names only the run's outputs, it would be
    lost unasked. Kept unmentioned, carrying the run's name, it would pass for an export of
    the new trajectory."""
    from revdem_cli.engine import output_paths
    from revdem_cli.io import exports_of

    paths = output_paths(out, name)
    trajectories = [paths[kind] for kind in ("forward", "reverse") if paths[kind] in written]
    return tuple(export for path in trajectories for export in exports_of(path))


def keep_checkpoint(out: Path, name: str, force: bool) -> None:
    """Refuse to start over an unfinished run unless forced: its checkpoint names it."""
    from revdem_cli.checkpoint import checkpoint_path, find_checkpoints

    path = checkpoint_path(out, name)
    others = [p for p in find_checkpoints(out) if p != path]
    if others:
        raise InputError(
            f"{others[0]}: the checkpoint of another unfinished run is in {out}; continue it "
            f"with revdem run --resume {out}, or give this run another --out"
        )
    if not path.exists():
        return
    if not force:
        raise InputError(
            f"{path}: an unfinished run; continue it with revdem run --resume {out}, or start "
            "again with --force"
        )
    path.unlink()


def _progress(progress, unit: str = "steps", here: bool = True):
    """A rich progress display of `unit` done when asked for (True), or none; it says that
    the kernels compile first where they will, on this machine (`here`: not a remote
    scheduler's workers, which keep caches of their own)."""
    from contextlib import nullcontext

    if progress:
        from revdem_cli.report.progress import RunProgress, kernels_compiled

        return RunProgress(unit=unit, compiling=here and not kernels_compiled())
    return nullcontext()


@_paths_checked
def run(
    experiment: Experiment | str | Path,
    out: str | Path = "out",
    reverse: bool = True,
    force: bool = False,
    allow_unstable_dt: bool = False,
    progress: bool = False,
    threads: int | None = None,
) -> Result:
    """Run every stage forward, and the reversed stage backwards with the comparison unless
    `reverse` is False, into the folder `out`, as `revdem run` does: earlier outputs are
    kept unless `force`, and a time step above the critical estimate is refused unless
    `allow_unstable_dt`; on at most `threads` threads (`use_threads`). A scenario file's
    path is loaded as it is (`load`)."""
    from revdem_cli.engine import check_time_step, run_scenario

    _check_switches(
        reverse=reverse, force=force, allow_unstable_dt=allow_unstable_dt, progress=progress
    )
    if isinstance(experiment, str | Path):
        experiment = load(experiment)
    elif not isinstance(experiment, Experiment):
        raise InputError(
            "experiment: an Experiment (load, from_dict) or a scenario file's path (str or "
            f"Path), not {type(experiment).__name__}"
        )
    out = _folder(out, "out")
    use_threads(threads)
    with sole_writer(out):
        keep_checkpoint(out, experiment.name, force)
        if not allow_unstable_dt:  # refused input keeps the earlier outputs, forced or not
            check_time_step(experiment.scenario, experiment.origin)
        written = output_paths_of(experiment.scenario, out, reverse)
        earlier = [path for path in earlier_outputs(out, experiment.name) if path not in written]
        keep_outputs([*written, *earlier], force)  # not left to pass for this run's
        stale = stale_exports(written, out, experiment.name)
        with _progress(progress) as shown:
            outputs = run_scenario(experiment.scenario, experiment.text, experiment.suffix, out,
                                   reverse, shown, allow_unstable_dt)  # fmt: skip
    outputs.stale_exports = stale
    return Result(outputs)


@_paths_checked
def reverse(
    restart: str | Path,
    out: str | Path | None = None,
    steps: int | None = None,
    force: bool = False,
    progress: bool = False,
    threads: int | None = None,
) -> Result:
    """Run the stage that ended at a restart backwards and compare it with its forward
    trajectory, as `revdem reverse` does, on at most `threads` threads (`use_threads`)."""
    from revdem_cli.compare import forward_of
    from revdem_cli.engine import output_paths, reverse_run
    from revdem_cli.io.restart import read_restart, restart_scenario

    _check_switches(force=force, progress=progress)
    use_threads(threads)
    restart = _path(restart, "restart")
    spec = restart_scenario(restart)[0]
    read_restart(restart)  # every dataset checked before earlier outputs are replaced
    folder = _folder(out, "out") if out is not None else restart.parent
    paths = output_paths(folder, spec.name)
    written, figures = [paths["reverse"]], []
    if forward_of(restart)[0] is not None:  # compared with, and drawn beside, the reversed
        written.append(paths["compare"])  # run: checked before the reversal, not after it
        figures = figure_paths(folder, spec)
    where = f"--out {folder}" if out is not None else f"{folder} (beside the restart)"
    with sole_writer(folder, where):
        keep_checkpoint(folder, spec.name, force)
        # with no earlier reversal, the figures are the forward run's (`run --no-reverse`),
        # drawn again with the reversed run beside it
        keep_outputs(written, force, "reversal", figures)
        stale = stale_exports(written, folder, spec.name)
        with _progress(progress) as shown:
            outputs = reverse_run(restart, out, steps, shown)
    outputs.stale_exports = stale
    if outputs.restart is None:  # what it ran from, as `read` of its folder gives it
        outputs.restart = restart
    return Result(outputs)


@_paths_checked
def resume(out: str | Path, progress: bool = False, threads: int | None = None) -> Result:
    """Continue the run whose checkpoint is in `out` to its end, as `revdem run --resume`,
    on at most `threads` threads (`use_threads`)."""
    from revdem_cli.checkpoint import SUFFIX, find_checkpoint
    from revdem_cli.engine import output_paths, resume_run
    from revdem_cli.io.restart import checkpoint_phase

    _check_switches(progress=progress)
    use_threads(threads)
    out = _folder(out, "out")
    find_checkpoint(out)  # a folder that is none, or holds none, is refused as it is
    with sole_writer(out, f"--resume {out}"):
        checkpoint = find_checkpoint(out)  # another run may have finished it meanwhile
        name = checkpoint.name.removesuffix(SUFFIX)
        # the trajectories it goes on writing: their exports were made before they ended
        phase = checkpoint_phase(checkpoint)
        kinds = ("forward", "reverse") if phase == "forward" else ("reverse",)
        paths = output_paths(out, name)
        stale = stale_exports([paths[kind] for kind in kinds], out, name)
        with _progress(progress) as shown:
            outputs = resume_run(out, shown)
    outputs.stale_exports = stale
    return Result(outputs)


@_paths_checked
def read(out: str | Path, name: str | None = None) -> Result:
    """The Result of a run written earlier into the folder `out` (by `revdem run`, a sweep's
    variant, this module): its forward trajectory, and its restart, reversed trajectory,
    comparison and figures where they are there; `name`, the scenario's, where `out` holds
    several runs. A folder that holds a reversal alone (`revdem reverse RESTART --out
    FOLDER`) gives it with the forward run its restart ends, where that is still there.
    What the run said of its stages (which stopped on their condition, the dt each 'auto'
    one took, the stages' tapes and restarts) comes from its restart. The trajectories are
    checked as every command checks them."""
    from revdem_cli.compare import read_verdict
    from revdem_cli.engine import carried_summary, output_paths
    from revdem_cli.io.h5md import open_trajectory
    from revdem_cli.io.restart import restart_summary

    out = _folder(out, "out")
    if not out.is_dir():
        raise InputError(f"{out}: {'a file, not' if out.exists() else 'no'} folder of a run")
    if name is None:
        runs = [*out.glob("*.forward.h5"), *out.glob("*.reverse.h5")]
        names = sorted({path.name.rsplit(".", 2)[0] for path in runs})
        if len(names) != 1:
            found = f"the runs {', '.join(names)}; give name=" if names else "no run"
            raise InputError(f"{out}: {found} (NAME.forward.h5, or NAME.reverse.h5)")
        name = names[0]
    paths = {
        kind: path if path.exists() else None for kind, path in output_paths(out, name).items()
    }
    if paths["forward"] is None and paths["reverse"] is not None:
        paths["restart"], paths["forward"] = _reversed_from(paths["reverse"])
    if paths["forward"] is None:
        alone = f"; {name}.reverse.h5's restart or forward run is not there"
        alone *= paths["reverse"] is not None
        raise InputError(f"{out}: no run {name} ({name}.forward.h5{alone})")
    for path in (paths["forward"], paths["reverse"]):
        if path is not None:
            open_trajectory(path).close()
    verdict = read_verdict(paths["compare"]) if paths["compare"] else None
    figures = tuple(sorted(out.glob(f"{name}.*.png")))
    outputs = Outputs(
        paths["forward"], paths["restart"], paths["reverse"], paths["compare"], figures, verdict
    )
    if paths["restart"] is not None:  # what the run said of its stages, which it keeps
        said = carried_summary(paths["restart"].parent, restart_summary(paths["restart"]))
        outputs.chosen_dt, outputs.stopped, outputs.unmet, outputs.unheld = said[:4]
        outputs.stage_files, outputs.servo, outputs.capped = tuple(said[4]), said[5], said[6]
    return Result(outputs)


def _reversed_from(reverse: Path) -> tuple[Path | None, Path | None]:
    """(the restart, the forward trajectory) a reversed trajectory was run from, where they
    are still there (`compare.restart_places`, `compare.forward_of`); None for what is
    not."""
    from revdem_cli.compare import forward_of, restart_places
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(reverse) as f:
        places = restart_places(f, reverse)
    if not places:
        return None, None
    return places[0], forward_of(places[0])[0]


def _number(name: str, value, optional: bool = True):
    """A number argument as a float (None where `optional` and not given); InputError naming
    `name` for anything else (a text, a list, a bool)."""
    if value is None and optional:
        return None
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        raise InputError(f"{name}={value!r}: a number, not {type(value).__name__}")
    return float(value)


def _particle(name: str, given: dict | None) -> dict:
    """A particle's description for `critical_time_step`, its values checked for their kind:
    `name`, what the argument is called."""
    from revdem_cli.timestep.command import PARTICLE_FIELDS

    if given is None:
        return {}
    if not isinstance(given, dict):
        raise InputError(
            f"{name}: a dict of {', '.join(PARTICLE_FIELDS)}, not {type(given).__name__}"
        )
    described = {}
    for key, value in given.items():
        if key not in PARTICLE_FIELDS:
            raise InputError(f"{name}[{key!r}]: not one of {', '.join(PARTICLE_FIELDS)}")
        if key == "shape":
            if not isinstance(value, str):
                raise InputError(
                    f"{name}['shape']={value!r}: a shape's name, not {type(value).__name__}"
                )
            described[key] = value
        elif key == "vertices":
            described[key] = _path(value, f"{name}['vertices']")
        elif key in ("semi_axes", "exponents"):
            count = 3 if key == "semi_axes" else 2
            if isinstance(value, str) or not hasattr(value, "__len__") or len(value) != count:
                raise InputError(f"{name}[{key!r}]={value!r}: {count} numbers")
            described[key] = tuple(_number(f"{name}[{key!r}]", v, False) for v in value)
        else:
            described[key] = _number(f"{name}[{key!r}]", value)
    return described


def critical_time_step(
    particle: dict,
    other: dict | None = None,
    *,
    kn: float,
    ks: float | None = None,
    damping: float = 0.0,
    omega_max: float | None = None,
    trvp_order: int = 0,
    verify: bool = False,
) -> dict:
    """The critical time steps of two convex, centrally symmetric particles in contact, as
    `revdem dt --json` gives them (Peng 2020): `particle` a dict of shape, its size (radius;
    semi_axes, with exponents for a superquadric; vertices, a file) and density, `other`
    the second particle's where it differs; `verify` integrates the pair as `--verify`.
    Example: critical_time_step({"shape": "ellipsoid", "semi_axes": (3, 2, 1),
    "density": 1000}, kn=1e10)["recommended_dt"]."""
    from revdem_cli.timestep.command import assess_pair

    _check_switches(verify=verify)
    if not whole_number(trvp_order):
        raise InputError(f"trvp_order={trvp_order!r}: a whole number, 0 to 4")
    numbers = {
        "kn": _number("kn", kn, False),
        "ks": _number("ks", ks),
        "damping": _number("damping", damping, False),
        "omega_max": _number("omega_max", omega_max),
    }
    return assess_pair(
        _particle("particle", particle), _particle("other", other), **numbers,
        trvp_order=int(trvp_order), verify=verify,
    )  # fmt: skip


def packing_time_step(restart: str | Path, verify: bool = False) -> dict:
    """The critical time step of the packing a restart or checkpoint holds, as `revdem dt
    --restart FILE --json` gives it: the largest eigenvalue of M⁻¹K beside every estimate,
    and with `verify` the engine's own bracket."""
    from revdem_cli.timestep.packing import assess_restart

    _check_switches(verify=verify)
    return assess_restart(_path(restart, "restart"), verify)


def _set_text(value) -> str:
    """A Python value as `--set` writes it, which the sweep reads back as that value (TOML:
    true, 1e-07, inf, [0.9, 0.1, 0.0], hertz, "a, b", a dict as an inline table,
    {kinetic_energy_below = 1e-09}, as `--set` takes a table)."""
    import json
    import re

    from revdem_cli.config import read_value

    value = _plain(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, list):
        return "[" + ", ".join(_set_text(inner) for inner in value) + "]"
    if isinstance(value, dict):
        bare = re.compile(r"[A-Za-z0-9_-]+")  # a key that is not a bare TOML key, quoted
        fields = [
            f"{key if bare.fullmatch(str(key)) else json.dumps(str(key))} = {_set_text(inner)}"
            for key, inner in value.items()
        ]
        return "{" + ", ".join(fields) + "}"
    if isinstance(value, str):  # as it is where `--set` would read it back as this text
        plain = read_value(value, "values") == value and not set(value) & set(",[]{}\"'")
        return value if plain else json.dumps(value)
    raise InputError(
        f"values: {value!r}: a number, a bool, a text, a list or a dict, not {type(value).__name__}"
    )


def sweep(
    scenario: str | Path,
    values: Mapping[str, Sequence],
    out: str | Path = "out/sweep",
    *,
    workers: int | None = None,
    threads: int | None = None,
    scheduler: str | None = None,
    force: bool = False,
    resume: bool = False,
    allow_unstable_dt: bool = False,
    progress: bool = False,
) -> list[dict]:
    """Run every combination of `values` ({dotted path: [value, ...]}, Python values) of a
    scenario file (or every variant of a sweep file, with `values` added), each forward and
    reversed, on a dask cluster (a local one of `workers` processes, default 2, or the
    scheduler at `scheduler` with its own workers: not both), as `revdem sweep` does: its
    table (sweep.csv, sweep.h5) in `out`, whose rows it returns (`sweep_table`). SIGINT or
    SIGTERM stops it as it stops the command: the table is written (the variants not done
    say so in their status; `resume=True` goes on), then `SweepInterrupted` is raised with
    its rows, as `run` raises `Interrupted`, so that a script stops there rather than go on
    to its next sweep."""
    from revdem_cli.sweep import read_sweep, run_sweep

    _check_switches(force=force, resume=resume, allow_unstable_dt=allow_unstable_dt,
                    progress=progress)  # fmt: skip
    if not isinstance(values, Mapping):
        raise InputError(f"values: a mapping of dotted paths to lists, not {type(values).__name__}")
    sets = []
    for key, listed in values.items():
        if (
            not isinstance(key, str)
            or isinstance(listed, str)
            or not isinstance(listed, Sequence | np.ndarray)
        ):
            raise InputError(f"values[{key!r}]: a list of the values to take, not {listed!r}")
        if len(listed) == 0:
            raise InputError(f"values[{key!r}]: no values; give a list of one or more")
        sets.append(f"{key}=" + ",".join(_set_text(value) for value in listed))
    if workers is not None and (not whole_number(workers) or workers < 1):
        raise InputError(f"workers={workers!r}: a whole number, 1 or more")
    out = _folder(out, "out")
    plan = read_sweep(_path(scenario, "scenario"), sets)
    with _progress(progress, "variants", scheduler is None) as shown:
        count = None if workers is None else int(workers)  # a numpy integer a plain one
        _, tables, signum = run_sweep(plan, out, scheduler, count, shown, threads,
                                      allow_unstable_dt, force, resume)  # fmt: skip
    rows = sweep_table(out)
    if signum:
        raise SweepInterrupted(signum, rows, tables)
    return rows


class SweepInterrupted(Interrupted):
    """A sweep (`sweep`) stopped on a signal, its table written: `rows` as `sweep_table`
    gives them (each variant's status: done, stopped with a checkpoint, not started),
    `tables` the files written, `path` its sweep.h5; `step` is None, the variants' own
    steps being in their rows' errors. `resume=True` goes on with it."""

    def __init__(self, signum: int, rows: list[dict], tables: list[Path]):
        from revdem_cli.sweep import stop_summary

        self.exit_code = 128 + signum
        self.rows, self.tables = rows, tables
        self.step, self.path = None, Path(tables[-1])
        BaseException.__init__(
            self, f"{signal.Signals(signum).name}: {stop_summary(rows)}; the table "
            f"{self.path} written; go on with resume=True"
        )  # fmt: skip


def sweep_table(out: str | Path) -> list[dict]:
    """The rows of the sweep table in the folder `out` (sweep.h5), as `revdem sweep` wrote
    it: each variant's folder, the values it set (`values`, as Python values: True, [0.9,
    0.1, 0.0], not their text) and its results (status,
    reversible, max_position_error_rel, first_divergence_step, kinetic_energy, total_energy,
    seconds, error); a variant's run is `read(out / row["folder"])`."""
    from revdem_cli.sweep import table_rows

    table = _folder(out, "out") / "sweep.h5"
    if not table.is_file():
        raise InputError(f"{table.parent}: no sweep table there (sweep.h5)")
    return table_rows(table)
