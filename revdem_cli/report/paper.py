"""`revdem report`: a Markdown page setting what a paper reports (paper_numbers.toml) beside
what revdem's runs in a directory gave.

Each table of the paper file is a case: `config` names the scenario, whose run in the
directory is NAME.forward.h5 and NAME.compare.json (NAME: the table's name). Each number a
case reports is measured by the entry of MEASURES of the same name; how close counts as
agreeing is set by `<quantity>_absolute_tolerance`, else `<quantity>_relative_tolerance`, else
the case's `relative_tolerance` (`tolerance_of`). A number the run itself sets, not one it
reports (a stage that stops when it reaches the paper's value), is named by
`<quantity>_set_by`, saying what sets it: it is shown, not judged. A number of revdem's
standing for words of the paper (a tolerance for "the curves overlap", where the paper gives
none) says so by `<quantity>_stands_for`, the words.
"""

from __future__ import annotations

import errno
import os
import shutil
import tomllib
from collections.abc import Callable
from functools import cached_property
from pathlib import Path

import numpy as np

from revdem_cli.compare import read_verdict
from revdem_cli.errors import InputError
from revdem_cli.io.h5md import (
    frame_steps,
    from_stage_start,
    observable_steps,
    open_trajectory,
    read_frame,
    read_observable,
    rows_by_step,
)

HANLEY_2020 = Path(__file__).parents[2] / "scenarios" / "hanley2020" / "paper_numbers.toml"
"""Hanley 2020's numbers, `revdem report`'s paper file unless given another."""

WALLS = ("lower_wall", "upper_wall")
"""Entries of a case naming the walls (as its scenario names them) whose z force its
`<wall>_force_<moment>` numbers are."""

ABOUT = {"config", "section", "claim", "relative_tolerance", *WALLS}
"""Entries of a case that describe it rather than report a number."""

QUALIFIERS = ("_absolute_tolerance", "_relative_tolerance", "_set_by", "_stands_for")
"""Endings of a case's entries that say how to judge the number their start names."""


def _qualified(key: str) -> str | None:
    """The quantity an entry qualifies (`QUALIFIERS`), None where it qualifies none."""
    return next((key.removesuffix(end) for end in QUALIFIERS if key.endswith(end)), None)


def _verdict(key: str) -> Callable:
    return lambda run: run.verdict()[key]


class NotInRun(LookupError):
    """A value a measure reads that the run's file does not hold: an observable it did not
    record, no row of it where the measure reads (a reversal stopped short of the reversed
    stage's start has none there), or no event the value is measured at (a run cut short
    before its contact). Its row says which, 'no WHAT in FILE', in place of a number."""

    def __init__(self, what: str, path: Path):
        super().__init__(f"no {what} in {Path(path).name}")


def _series(path: Path, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(step, time, value) of the observable `name` of a run's trajectory at `path`, the one
    reader of observables every measure goes through; NotInRun where the trajectory holds
    no row of it."""
    with open_trajectory(path) as f:
        if f"observables/{name}/value" not in f:
            raise NotInRun(name, path)
        time, value = read_observable(f, name)
        step = observable_steps(f, name)
    if not len(value):
        raise NotInRun(name, path)
    return step, time, value


def _shear_forces(run) -> tuple[np.ndarray, np.ndarray]:
    """The largest shear and normal contact forces of the forward run, row by row."""
    return _series(run.forward, "max_shear_force")[2], _series(run.forward, "max_normal_force")[2]


def _max_shear_force(run) -> float:
    return float(_shear_forces(run)[0].max())


def _shear_force_at_separation(run) -> float:
    """The largest shear force at the last row in contact, before the contact opens;
    NotInRun where the run has no contact, or one still closed at its last row (a run cut
    short), whose shear force there is not the one lost at separation."""
    shear, normal = _shear_forces(run)
    touching = np.nonzero(normal)[0]
    if not len(touching):
        raise NotInRun("contact", run.forward)
    if touching[-1] == len(normal) - 1:
        raise NotInRun("separation", run.forward)
    return float(shear[touching[-1]])


def _velocity_before_contact(run) -> float:
    """Vertical velocity of particle 0 at the last frame before its first contact;
    NotInRun where the run has no contact (cut short before it), whose last frame's
    velocity is not the one it hits with, or no frame before it."""
    _, times, elastic = _series(run.forward, "elastic_energy")
    touching = np.nonzero(elastic > 0.0)[0]
    if not len(touching):
        raise NotInRun("contact", run.forward)
    first_contact = times[touching[0]]
    with open_trajectory(run.forward) as f:
        frame_times = f["particles/all/velocity/time"][: len(frame_steps(f))]
        before = np.nonzero(frame_times < first_contact)[0]
        if not len(before):
            raise NotInRun(f"frame before the first contact (at {first_contact:g} s)", run.forward)
        return float(read_frame(f, "velocity", int(before[-1]))[0, 2])


def _observable_at(run, moment: str, name: str) -> np.ndarray:
    """An observable of the reversed stage at `moment`: 'start' (forward run, where the
    stage began), 'end' (forward run, where the stage ended: the restart's step, not the
    last row of a trajectory cut short) or 'reversed' (the reversed run at the stage's
    start: its last row, or where every stage is reversed, its row there); NotInRun where
    the file has no such row. At the stage's start, its own row where it wrote one beside
    the end of the stage before (`io.h5md.rows_by_step`)."""
    path = run.reverse if moment == "reversed" else run.forward
    first, last = run.stage
    step = last if moment == "end" else first
    steps, _, values = _series(path, name)
    there = rows_by_step(steps, reverse=moment == "reversed").get(step)
    if not there:
        raise NotInRun(f"{name} at step {step}", path)
    return values[there[0] if moment == "end" else there[-1]]


def _stress_ratio(principal: np.ndarray) -> np.ndarray:
    """sigma_1 / sigma_3 of principal stresses, largest first."""
    return principal[..., 0] / principal[..., 2]


def _peak_stress_ratio(run) -> float:
    """Largest sigma_1 / sigma_3 of the forward run over the reversed stage (Hanley 2020
    Figure 4, the peak of Thornton's Eq 24); NotInRun where the run has no principal
    stresses (no periodic cell) or none from the stage's start on (`from_stage_start`: not
    the end of the stage before)."""
    first, _ = run.stage
    steps, _, principal = _series(run.forward, "principal_stress")
    during = principal[from_stage_start(steps, first)]
    if not len(during):
        raise NotInRun(f"principal_stress from step {first} on", run.forward)
    return float(_stress_ratio(during).max())


def _stage_measures() -> dict[str, tuple[str, Callable]]:
    """At the start and end of the reversed stage and at the end of its reversal: solid
    fraction and z force on the case's lower and upper walls (Hanley 2020 §3.2.2),
    coordination number and sigma_1 / sigma_3 (§3.2.3)."""
    measures = {}
    for moment in ("start", "end", "reversed"):
        measures[f"solid_fraction_{moment}"] = (
            "close",
            lambda run, m=moment: float(_observable_at(run, m, "solid_fraction")),
        )
        measures[f"coordination_number_{moment}"] = (
            "close",
            lambda run, m=moment: float(_observable_at(run, m, "coordination_number")),
        )
        measures[f"stress_ratio_{moment}"] = (
            "close",
            lambda run, m=moment: float(_stress_ratio(_observable_at(run, m, "principal_stress"))),
        )
        for wall in WALLS:
            measures[f"{wall}_force_{moment}"] = (
                "close",
                lambda run, m=moment, w=wall: float(
                    _observable_at(run, m, f"wall_force/{run.case[w]}")[2]
                ),
            )
    return measures


MEASURES: dict[str, tuple[str, Callable]] = {
    "max_position_error_rel": ("at most", _verdict("max_position_error_rel")),
    "max_velocity_error": ("at most", _verdict("max_velocity_error")),
    "reversible": ("equal", _verdict("reversible")),
    "max_shear_force": ("close", _max_shear_force),
    "shear_force_at_separation": ("close", _shear_force_at_separation),
    "terminal_velocity": ("close", _velocity_before_contact),
    "peak_stress_ratio": ("close", _peak_stress_ratio),
    **_stage_measures(),
}
"""quantity -> (how revdem's value is judged against the paper's, how it is measured)."""


class _Run:
    """A case's run in a directory: its files NAME.forward.h5, NAME.reverse.h5 and
    NAME.compare.json, each FileNotFoundError naming it where it is missing. The report
    makes one a case, which what it says of the run (`not_judged`) and its rows
    (`case_rows`) share."""

    def __init__(self, directory: Path, name: str, case: dict):
        self.directory, self.name, self.case = Path(directory), name, case

    def path(self, kind: str) -> Path:
        """Where the run's file of `kind` (forward.h5, compare.json, ...) is, there or not."""
        return self.directory / f"{self.name}.{kind}"

    def _file(self, kind: str) -> Path:
        path = self.path(kind)
        if not path.exists():
            raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), str(path))
        return path

    @property
    def forward(self) -> Path:
        return self._file("forward.h5")

    @property
    def reverse(self) -> Path:
        return self._file("reverse.h5")

    def verdict(self) -> dict:
        return read_verdict(self._file("compare.json"))

    @cached_property
    def stage(self) -> tuple[int, int]:
        """The first and the last step of the reversed stage, which its restart ends, read
        from it once for every measure of the case."""
        from revdem_cli.io.restart import restart_stage

        return restart_stage(self._file("restart.h5"))

    def short_reversal(self) -> str | None:
        """How far back the reversal went, in words, where it stopped short of the first step
        of the reversed stage (a `revdem reverse --steps` fewer than the stage's, or a
        reversal stopped before its end): its verdict then covers those steps alone, not the
        whole stage the paper reverses, and does not test its claim. None where
        it went back there (or on, through the stages before, with `[reversal] all_stages`)
        or where the case has no reversal (no NAME.compare.json); FileNotFoundError naming
        the reversed trajectory or the restart where one is missing, without which it
        cannot be told."""
        if not self.path("compare.json").exists():
            return None
        first, _ = self.stage
        with open_trajectory(self.reverse) as f:
            steps = frame_steps(f)
        if len(steps) and steps.min() <= first:
            return None
        if not len(steps):
            return "its reversed trajectory holds no frame"
        start, back = int(steps[0]), int(steps.min())
        return (
            f"it reversed {start - back} of the reversed stage's {start - first} steps, going "
            f"back from step {start} to step {back}, not to step {first}"
        )

    @property
    def ran(self) -> bool:
        """Whether the case has a run in the directory (its trajectory or its verdict)."""
        return self.path("forward.h5").exists() or self.path("compare.json").exists()


UNJUDGED = ("description", "output.")
"""Fields of a scenario that change no number a run reports."""


def differences(run_path: Path, config: str) -> list[str] | None:
    """Where the scenario a run stores differs from the case's config (read from the working
    folder, else from the project's root, as `config` names it): 'field: run's (config's)'
    for each field, [] where none does, None where the config is not there to say. What
    changes no number of the run is left out: its description and [output] (figures,
    checkpoint interval, what frames carry)."""
    from revdem_cli.config import Scenario, fields_apart, load_scenario

    path = next(
        (p for p in (Path(config), Path(__file__).parents[2] / config) if p.is_file()), None
    )
    if path is None:
        return None
    with open_trajectory(run_path) as f:
        stored = Scenario.model_validate_json(str(f["parameters/revdem"].attrs["scenario_json"]))
    return [
        f"{key} = {ran} ({given} in {config})"
        for key, ran, given in fields_apart(stored, load_scenario(path)[0])
        if not key.startswith(UNJUDGED)
    ]


def tolerance_of(case: dict, key: str) -> tuple[float, bool]:
    """(tolerance, whether it is absolute) within which revdem's `key` agrees with the
    case's: `<key>_absolute_tolerance` where the case gives one, for a number that changes
    over the run by a small part of itself (a solid fraction, 0.606 to 0.625: at 10 % the
    start would agree with the end), else `<key>_relative_tolerance`, else the case's
    `relative_tolerance`, else none (relative 0)."""
    if f"{key}_absolute_tolerance" in case:
        return case[f"{key}_absolute_tolerance"], True
    return case.get(f"{key}_relative_tolerance", case.get("relative_tolerance", 0.0)), False


def _judge(how: str, paper, ours, tolerance: tuple[float, bool]) -> bool:
    if how == "at most":
        return ours <= paper
    if how == "equal":
        return ours == paper
    within, absolute = tolerance
    return abs(ours - paper) <= within * (1.0 if absolute else abs(paper))


def _show(value) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def not_judged(run: _Run) -> tuple[list[str], str]:
    """What the page says of a case's run before its numbers, and the word its rows carry in
    place of yes or no ('' where they are judged). A run is not the paper's case where its
    stored scenario differs from the case's config (made with --set, say: `differences`) or
    where its reversal stopped short of the start of the reversed stage
    (`_Run.short_reversal`): either way its numbers answer another question than the
    paper's, and agreeing with them or not would be misread as revdem's answer to it. Where
    its reversed trajectory or restart is missing, how far back its reversal went cannot be
    told, and it is not judged either."""
    lines, why = [], []
    case, forward = run.case, run.path("forward.h5")
    changed = differences(forward, case["config"]) if "config" in case and forward.exists() else []
    if changed is None:
        lines.append(f"(`{case['config']}` is not there to check the run against.)")
    elif changed:
        why.append(
            f"the run differs from `{case['config']}` in "
            + "; ".join(f"`{change}`" for change in changed)
        )
    unknown = ""
    try:
        short = run.short_reversal()
    except FileNotFoundError as exc:
        short, unknown = None, Path(exc.filename).name
    if short:
        why.append(short)
    if why:
        sentence = "**Not the paper's case**: " + "; ".join(why) + "."
        return lines + [sentence + " Its numbers are shown, not judged."], "not the case"
    if unknown:
        sentence = f"**Not judged**: no {unknown}, without which how far back its reversal went"
        return lines + [sentence + " cannot be told. Its numbers are shown."], "not judged"
    return lines, ""


def case_rows(run: _Run, unjudged: str = "") -> list[tuple[str, str, str, str]]:
    """(quantity, paper, revdem, agrees) for each number a case reports, measured in its
    run, agrees being `unjudged` in place of yes or no where it is given (`not_judged`);
    InputError naming a file of its run that is damaged."""
    case, rows = run.case, []
    for key, paper in case.items():
        if key in ABOUT or _qualified(key):
            continue
        if key not in MEASURES:
            rows.append((key, _show(paper), "not measured", ""))
            continue
        how, measure = MEASURES[key]
        shown = _paper_cell(case, key, how)
        try:
            ours = measure(run)
        except FileNotFoundError as exc:  # no run, or a run without its reversal
            rows.append((key, shown, f"no {Path(exc.filename).name}", ""))
            continue
        except NotInRun as exc:
            rows.append((key, shown, str(exc), ""))
            continue
        if f"{key}_set_by" in case:  # an input of the run: its agreeing would test nothing
            rows.append((key, shown, _show(ours), f"not judged: set by {case[key + '_set_by']}"))
            continue
        agrees = _judge(how, paper, ours, tolerance_of(case, key))
        rows.append((key, shown, _show(ours), unjudged or ("yes" if agrees else "**no**")))
    return rows


def _paper_cell(case: dict, key: str, how: str) -> str:
    """The paper column of a row: the case's number as it is judged (≤ a bound, ± a
    tolerance; bare where the run sets it), and where it stands for words of the paper
    (`<quantity>_stands_for`), those words first, the number marked revdem's: a tolerance
    revdem judges a claim the paper makes in words by, which a reader would otherwise take
    for a number the paper gives."""
    shown = f"≤ {_show(case[key])}" if how == "at most" else _show(case[key])
    if how == "close" and f"{key}_set_by" not in case:
        within, absolute = tolerance_of(case, key)
        shown += f" ± {within:g}" if absolute else f" ± {100 * within:g}%"
    words = case.get(f"{key}_stands_for")
    return f'"{words}": revdem\'s {shown}' if words else shown


def read_paper(paper_path: Path) -> dict[str, dict]:
    """The cases of a paper file (its tables), each number it reports checked to be one;
    InputError naming the file and the entry otherwise, or where no table reports a number
    revdem measures (a scenario file given for it, say)."""
    try:
        paper = tomllib.loads(Path(paper_path).read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{paper_path}: cannot read the paper's numbers ({exc})") from None
    cases = {name: case for name, case in paper.items() if isinstance(case, dict)}
    if not any(key in MEASURES for case in cases.values() for key in case):
        raise InputError(
            f"{paper_path}: not a paper's numbers: no table reports a number revdem measures "
            "(see scenarios/hanley2020/paper_numbers.toml)"
        )
    for name, case in cases.items():
        for key, value in case.items():
            _check_qualifier(paper_path, name, case, key)
            if key not in MEASURES:
                continue
            _check_wall(paper_path, name, case, key)
            if MEASURES[key][0] == "equal" and not isinstance(value, bool):
                raise InputError(f"{paper_path}: {name}.{key} = {value!r}: give true or false")
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if MEASURES[key][0] != "equal" and not number:
                raise InputError(f"{paper_path}: {name}.{key} = {value!r}: give a number")
    return cases


def _check_wall(paper_path: Path, name: str, case: dict, key: str) -> None:
    """InputError naming the paper file and the entry where `key` of the case is the force
    on one of its `WALLS` and the case does not name that wall."""
    wall = next((wall for wall in WALLS if key.startswith(f"{wall}_force_")), None)
    if wall is None:
        return
    if wall not in case:
        raise InputError(
            f"{paper_path}: {name}.{key}: give {name}.{wall}, the name of that wall in the "
            "case's scenario"
        )
    if not isinstance(case[wall], str) or not case[wall]:
        raise InputError(
            f"{paper_path}: {name}.{wall} = {case[wall]!r}: give the name of a wall of the "
            "case's scenario"
        )


def _check_qualifier(paper_path: Path, name: str, case: dict, key: str) -> None:
    """InputError naming the paper file and the entry where `key` of the case is a
    tolerance that is not a number at least 0, a `_set_by` or `_stands_for` that is not
    words, or any of them of a number the case does not report."""
    value, quantity = case[key], _qualified(key)
    if quantity is None and key != "relative_tolerance":
        return
    words = {"_set_by": "say what sets it", "_stands_for": "give the paper's words"}
    ending = next((end for end in words if key.endswith(end)), None)
    if ending:
        if not isinstance(value, str) or not value:
            raise InputError(f"{paper_path}: {name}.{key} = {value!r}: {words[ending]}")
    elif isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
        raise InputError(f"{paper_path}: {name}.{key} = {value!r}: give a number, 0 or more")
    if quantity is not None and quantity not in case:
        raise InputError(f"{paper_path}: {name}.{key}: {name} reports no {quantity}")


def from_here(path: Path) -> Path:
    """`path` as the page names it: relative to the working folder where it lies below it
    (the project's own paper file, `HANLEY_2020`, found wherever revdem runs from), else as
    it was given."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return Path(path)


def write_report(directory: Path, paper_path: Path, out: Path, keep: bool = False) -> Path:
    """Write the Markdown page to `out` (its folder made if need be), the runs' figures
    copied beside it where they live elsewhere; InputError for a paper file that cannot be
    read, a directory that holds no run of its cases, a run's file that is damaged, or a
    figure's copy that would write over a folder, or over a file where `keep` (an --out
    given without --force, as `io.refuse_overwriting` keeps the page's)."""
    paper = read_paper(paper_path)
    if not Path(directory).is_dir():
        raise InputError(f"{directory}: no such folder of runs")
    runs = [_Run(directory, name, case) for name, case in paper.items()]
    if not any(run.ran for run in runs):
        raise InputError(
            f"{directory}: no run of a case of {from_here(paper_path)} (NAME.forward.h5 or "
            f"NAME.compare.json, NAME one of {', '.join(paper)})"
        )
    lines = [
        f"# {from_here(paper_path)} against the runs in {directory}",
        "",
        "Run a case with `revdem run CONFIG --out DIR`; its files are NAME.forward.h5 and "
        "NAME.compare.json.",
    ]
    copies = []
    for run in runs:
        name, case = run.name, run.case
        title = f"## {name}" + (f" ({case['section']})" if "section" in case else "")
        lines += ["", title, ""]
        if "config" in case:
            lines += [f"`{case['config']}`" + (f": {case['claim']}" if "claim" in case else ""), ""]
        said, unjudged = not_judged(run)
        lines += [line for sentence in said for line in (sentence, "")]
        rows = case_rows(run, unjudged)
        lines += ["| quantity | paper | revdem | agrees |", "|---|---|---|---|"]
        lines += [f"| {' | '.join(row)} |" for row in rows]
        figures = sorted(Path(directory).glob(f"{name}.*.png"))
        lines += [f"\n![{figure.stem}]({figure.name})" for figure in figures]
        copies += [(figure, Path(out).parent / figure.name) for figure in figures]
    copies = [(figure, target) for figure, target in copies if target.resolve() != figure.resolve()]
    for figure, target in copies:
        if target.is_dir() or (keep and target.exists()):
            kept = "a folder" if target.is_dir() else "exists"
            force = "" if target.is_dir() else "; use --force to overwrite"
            raise InputError(f"report: {target}: {kept}, where it would copy {figure}{force}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for figure, target in copies:
        shutil.copyfile(figure, target)
    out.write_text("\n".join(lines) + "\n")
    return out
