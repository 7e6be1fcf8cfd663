"""Forward against reversed trajectories: frames aligned by step, error metrics, verdict."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from revdem_cli.config import Reversal, Scenario
from revdem_cli.errors import InputError, check_regular
from revdem_cli.io import GRID_FIELDS
from revdem_cli.io.h5md import frame_steps, frames_per_block, open_trajectory, read_frames
from revdem_cli.kernels.events import (
    AMOUNT,
    COUNT,
    KINDS,
    LAST,
    MOTION_LOST,
    PARTICLE,
    PARTNER,
)
from revdem_cli.state import particle_named, partner_named

VERDICT_KEYS = (
    "reversible",
    "bitwise_identical",
    "max_position_error_rel",
    "max_velocity_error",
    "first_divergence_step",
)
"""What every NAME.compare.json holds (`compare_trajectories`), which its readers rely on."""


PAIRED = "{reverse} reverses {restart}, the restart that ends {forward}"
"""The pairing a comparison records where it found the reversal's restart (`check_pairing`):
the files it compared, by name, which its readers tell its trajectories by
(`compared_files`)."""


def compared_files(verdict: dict) -> tuple[str, ...]:
    """The names of the forward and the reversed trajectory a comparison's pairing names;
    none where it names no trajectory (its reversal's restart was gone: it checked that the
    runs were of one scenario, not which)."""
    import re

    pattern = PAIRED.format(reverse="(?P<reverse>.+)", restart=".+", forward="(?P<forward>.+)")
    found = re.fullmatch(pattern, str(verdict.get("pairing", "")))
    return (found["forward"], found["reverse"]) if found else ()


def read_verdict(path: Path) -> dict:
    """A run's NAME.compare.json, as `compare_trajectories` wrote it; InputError naming the
    file where it is not one (FileNotFoundError where it is missing)."""
    check_regular(path, "a comparison")
    try:
        verdict = json.loads(Path(path).read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a revdem comparison ({exc})") from None
    if not isinstance(verdict, dict):
        raise InputError(f"{path}: not a revdem comparison (not a JSON object)")
    missing = [key for key in VERDICT_KEYS if key not in verdict]
    if missing:
        raise InputError(f"{path}: not a revdem comparison (no {', '.join(missing)})")
    return verdict


def _max_norms(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The largest |a - b| over the particles of each frame of two (frames, particles, 3)
    blocks."""
    if a.shape[1] == 0:
        return np.zeros(len(a))
    return np.sqrt(((a - b) ** 2).sum(axis=2)).max(axis=1)


def tolerances_of(trajectory) -> Reversal:
    """The reversal tolerances of the scenario a trajectory was run from."""
    scenario = _scenario_of(trajectory)
    return scenario.reversal if scenario else Reversal()


def compare_trajectories(
    first: str | Path,
    second: str | Path,
    tolerance: Reversal | None = None,
    known: dict[Path, dict] | None = None,
):
    """Compare two trajectories frame by frame at their common steps.

    `first_divergence_step` is the first step, in the order the second run went through
    them, at which an error exceeds its tolerance (None if none does). `bitwise_identical`:
    every common frame holds the same bits, in fixed-point arithmetic the same integer
    state, and the same box (a periodic cell's edges, which positions in it are fractions
    of), so the round trip returned exactly the state it started from. With the
    information tapes the reversal replayed (`tapes_replayed`), their summary
    (`with_tapes`; `known`: those of tapes already read, as `with_tapes` takes them).
    """
    with open_trajectory(first) as a, open_trajectory(second) as b:
        pairing = check_pairing(a, b, Path(first), Path(second))
        tolerance = tolerance or tolerances_of(a)
        steps_a, steps_b = frame_steps(a), frame_steps(b)
        common, index_a, index_b = np.intersect1d(steps_a, steps_b, return_indices=True)
        if len(common) == 0:
            raise InputError(f"{first} and {second} have no frame at a common step")
        if len(common) == 1 and common[0] == steps_b[0]:
            raise InputError(
                f"{first} and {second} share only the frame the reversal starts from (step "
                f"{common[0]}), which its restart makes the same: nothing to compare"
            )
        radius = a["particles/all/radius"][:]
        if len(radius) != len(b["particles/all/radius"]):
            raise InputError(f"{first} and {second} hold different numbers of particles")
        diameter = 2.0 * float(radius.min())
        order = np.argsort(common)
        if b["parameters/revdem"].attrs.get("direction") == "reverse":
            order = order[::-1]
        rows = []
        identical = True
        on_grids = all(f"particles/all/{name}" in run for run in (a, b) for name in GRID_FIELDS)
        per_block = frames_per_block(len(radius))
        for start in range(0, len(order), per_block):
            ks = order[start : start + per_block]
            errors = []
            for field in ("position", "velocity", "angular_velocity"):
                va = read_frames(a, field, index_a[ks])
                vb = read_frames(b, field, index_b[ks])
                if not on_grids:
                    identical &= bool(np.array_equal(va, vb))
                errors.append(_max_norms(va, vb))
            for field in (*GRID_FIELDS, "box/edges") if on_grids else ("box/edges",):
                identical &= bool(
                    np.array_equal(
                        read_frames(a, field, index_a[ks]), read_frames(b, field, index_b[ks])
                    )
                )
            rows += [
                (int(common[k]), float(e) / diameter, float(e), float(v), float(w))
                for k, e, v, w in zip(ks, *errors, strict=True)
            ]
        first_divergence = first_divergence_of(rows, tolerance)
        causes = divergence_causes(a, first_divergence)
        energy = _energy_back(a, b)
        tapes = tapes_replayed(b, Path(second))
        unfinished = _reversal_unfinished(b, Path(second), steps_b)
    table = np.array([r[1:] for r in rows])
    verdict = {
        "frames_compared": len(rows),
        "max_position_error": float(table[:, 1].max()),
        "max_position_error_rel": float(table[:, 0].max()),
        "max_velocity_error": float(table[:, 2].max()),
        "max_angular_velocity_error": float(table[:, 3].max()),
        "first_divergence_step": first_divergence,
        "bitwise_identical": identical,
        "reversible": first_divergence is None,
        "reversal_finished": unfinished is None,
        "reversal_unfinished": unfinished,
        "divergence_causes": causes,
        "total_energy_back": energy,
        "pairing": pairing,
        "tolerance": tolerance.model_dump(),
        "smallest_diameter": diameter,
        "frames": {
            "step": [r[0] for r in rows],
            "position_error_rel": table[:, 0].tolist(),
            "velocity_error": table[:, 2].tolist(),
        },
    }
    return with_tapes(verdict, tapes, known)


def _reversal_unfinished(reverse, second: Path, steps: np.ndarray) -> str | None:
    """Where the reversed run (the open file `second`) has not reached its end, as `revdem
    info` finds it (`checkpoint.stopped_run`): how far back it went, and why, in words; None
    where it ended. Its verdict covers those steps alone, not a whole reversal. A reversed
    trajectory marked whole is (the checkpoint of its run, there until the comparison and
    figures are written, does not make it unfinished)."""
    from revdem_cli.checkpoint import stopped_run, unfinished_words
    from revdem_cli.io.h5md import ended

    left, checkpoint = stopped_run(second, reverse)
    if not left or ended(reverse):
        return None
    went = f"go back from step {steps[0]} to step {steps[-1]} only" if len(steps) else "are none"
    return f"its frames {went}; {unfinished_words(second, checkpoint)}"


def refuse_nothing_to_compare(forward: Path, start: int, stop: int) -> None:
    """InputError where a reversal from step `start` back to step `stop` would meet no frame
    of the forward trajectory `forward` but the one it starts from, which its restart makes
    the same: a comparison of it would prove nothing (`revdem reverse --steps`)."""
    with open_trajectory(forward) as f:
        steps = frame_steps(f)
    earlier = steps[steps < start]
    if len(earlier) and earlier.max() >= stop:
        return
    enough = f"; give --steps {start - int(earlier.max())} or more" if len(earlier) else ""
    raise InputError(
        f"--steps {start - stop}: the reversed run would end at step {stop}, and {forward} has "
        f"no frame from there to step {start}, where it starts: nothing could be compared"
        f"{enough}"
    )


def _energy_back(forward, reverse) -> dict | None:
    """The total energy (J) the reversed run ends with, at the step it returns to, beside the
    forward run's row of that state (`paired_rows`: where a stage began with its own row, the
    stage's start, not the end of the stage before): equal for a reversal that retraces its
    run, and where it parts, whether it took energy out or put it in (a damped run reversed
    gains it, Hanley 2020 §5.2). None where the forward run has no observables row at that
    step."""
    names = "observables/total_energy/step", "observables/total_energy/value"
    if not all(name in run for run in (forward, reverse) for name in names):
        return None
    back = reverse[names[0]][:]
    end = len(back) - 1  # the reversed run's last row: where it returned to
    pairs = paired_rows(forward[names[0]][:], back)
    there = {reversed_row: row for row, reversed_row in pairs}.get(end)
    if there is None:
        return None
    return {
        "step": int(back[end]),
        "forward": float(forward[names[1]][there]),
        "reversed": float(reverse[names[1]][end]),
    }


def paired_rows(forward: np.ndarray, reverse: np.ndarray) -> list[tuple[int, int]]:
    """The observables rows of a forward run and of its reversal that hold one state, as
    (forward row, reversed row), from the steps of their rows (`observable_steps`): at each
    step both have, their rows in the forward run's order (`rows_by_step`), the reversal's
    last with the forward run's last, and so on back; at the step the reversal began from,
    the end of its stage, first with first. Where a stage began with its own row beside the
    end of the stage before (`stage.StageStart`), a reversal that stops at that stage's
    start holds its start alone, the forward run's second row there."""
    from revdem_cli.io.h5md import rows_by_step

    rows, back = rows_by_step(forward), rows_by_step(reverse, reverse=True)
    began = int(reverse[0]) if len(reverse) else None
    paired = []
    for step, there in back.items():
        here = rows.get(step, [])
        ends = (here, there) if step == began else (here[::-1], there[::-1])
        paired += zip(*ends, strict=False)  # the forward run may hold one more
    return paired


def restart_places(reverse, second: Path) -> list[Path]:
    """Where the restart the reversed trajectory `reverse` (the open file `second`) began
    from is, of the places it may be: beside the reversal first (a run's folder copied or
    moved keeps the paths it was written with), then where it was written."""
    written = Path(str(reverse["parameters/revdem"].attrs.get("source_restart", "")))
    if not written.name:
        return []
    return [path for path in (second.parent / written.name, written) if path.is_file()]


def tapes_replayed(reverse, second: Path) -> list[Path]:
    """The information tapes the reversed trajectory `reverse` (the open file `second`)
    replayed, the later stage's first, where its restart is still there (`restart_places`):
    that restart's, and where every stage was reversed, on through the restarts before
    (`previous`) while the reversal reached each one's stage start, as `engine` went."""
    from revdem_cli.io.restart import restart_links

    places = restart_places(reverse, second)
    steps = frame_steps(reverse)
    if not places or not len(steps):
        return []
    reached, restart, tapes = int(steps[-1]), places[0], []
    while True:
        tape, previous, first_step = restart_links(restart)
        if tape:
            tapes.append(restart.parent / tape)
        if not previous or reached > first_step:
            return tapes
        restart = restart.parent / previous


def with_tapes(verdict: dict, tapes: list[Path], known: dict[Path, dict] | None = None) -> dict:
    """`verdict` with the summary of the information tapes a reversal replayed (`io.tape`):
    `information_tape`, all of them together, and with several `information_tapes`, each;
    as it is where none is. `known`: the summaries of tapes already read and checked, by
    resolved path (a reversal's own, `Replayer.summary`, made from the read that checked
    every block before its first step), taken as they are, where `summary` would read the
    whole tape again."""
    from revdem_cli.io.tape import combined, summary

    known = known or {}
    summaries = [known.get(tape.resolve()) or summary(tape) for tape in tapes]
    if summaries:
        verdict["information_tape"] = combined(summaries)
    if len(summaries) > 1:
        verdict["information_tapes"] = summaries
    return verdict


def check_pairing(forward, reverse, first: Path, second: Path) -> str:
    """That `second` reverses `first`: a forward trajectory and a reversed one, in that order,
    of one scenario, the reversal from a restart that ends `first` (when that restart is
    still there: else said so). The restart is looked for beside `second` first, then where
    it was written, a restart of another scenario there not taken for it, and it ends
    `first` where it names it or where `restart_ends` finds it does (a run's folder copied
    or moved keeps the paths it was written with).
    InputError naming what does not fit; returns one line on what was checked."""
    from revdem_cli.io.restart import restart_scenario

    if first.resolve() == second.resolve():
        raise InputError(f"{first}: compared with itself; give its reversed trajectory second")
    directions = tuple(
        str(run["parameters/revdem"].attrs.get("direction", "?")) for run in (forward, reverse)
    )
    if directions != ("forward", "reverse"):
        raise InputError(
            f"{first} and {second}: a comparison takes a forward trajectory and its reversal, "
            f"in that order; these are {directions[0]} and {directions[1]}"
        )
    scenarios = [_scenario_of(run) for run in (forward, reverse)]
    if apart := runs_apart(*scenarios):
        raise InputError(f"{first} and {second}: {apart}")
    written = Path(str(reverse["parameters/revdem"].attrs.get("source_restart", "")))
    source = ends = None
    for path in restart_places(reverse, second):
        stored, trajectory = restart_scenario(path)
        if not runs_apart(stored, scenarios[1]):
            source, ends = path, trajectory
            break
    if source is None:  # names only: the same words wherever the runs were made
        return f"one scenario; the reversal's restart {written.name} is not there to say more"
    if ends.resolve() != first.resolve() and (why := restart_ends(source, forward, first)):
        raise InputError(
            f"{first}: not the forward run that {second} reverses: its restart {source} ends "
            f"the forward run {ends}; {why}"
        )
    return PAIRED.format(reverse=second.name, restart=source.name, forward=first.name)


def restart_ends(restart: Path, forward, first: Path) -> str:
    """'' where the restart file `restart` ends the forward run whose trajectory `forward`
    (the open file `first`) holds; else why not, in words. It does where both store one
    scenario (`runs_apart`) and `first` has a frame at the restart's step holding its
    positions: the run's own trajectory, copied or moved with it or not, or that of the run
    made again (revdem is deterministic), whatever the path the restart names; a stage's
    restart (`[reversal] all_stages`) holds the frame at its stage's end."""
    from revdem_cli.io.restart import restart_positions, restart_scenario

    if apart := runs_apart(restart_scenario(restart)[0], _scenario_of(forward)):
        return apart
    step, positions = restart_positions(restart)
    at = np.flatnonzero(frame_steps(forward) == step)[-1:]
    if not len(at) or not np.array_equal(read_frames(forward, "position", at)[0], positions):
        return f"{first} holds no frame at step {step} with the restart's state"
    return ""


def forward_of(restart: Path) -> tuple[Path | None, tuple[Path, ...]]:
    """(the forward trajectory of the run the restart file `restart` ends, the places looked
    for it at): where the restart names it, then the file of that name beside the restart
    (a run's folder copied or moved keeps the paths it was written with); of those there,
    the first that holds that run (`restart_ends`); None where none is there. InputError
    naming the restart and each place where those there are all of another run: a
    reversal refuses it before its first step, where its comparison, after the last, would
    refuse it and leave a reversed trajectory with no verdict."""
    from revdem_cli.io.restart import restart_scenario

    named = restart_scenario(restart)[1]
    places: list[Path] = []
    for path in (named, restart.parent / named.name) if named.name else ():
        if all(path.resolve() != place.resolve() for place in places):
            places.append(path)
    said = []
    for path in places:
        what = f"the forward trajectory it names, {path}," if path == named else f"{path} beside it"
        if not path.is_file():
            said.append(f"{what} is not there")
            continue
        with open_trajectory(path) as f:
            why = restart_ends(restart, f, path)
        if not why:
            return path, tuple(places)
        said.append(f"{what} is of another run: {why}")
    if any(path.is_file() for path in places):
        raise InputError(f"{restart}: {'; and '.join(said)}")
    return None, tuple(places)


def runs_apart(first: Scenario, second: Scenario) -> str:
    """What sets apart the runs of two stored scenarios, in words: 'runs of different
    scenarios (or of other --set): key = a and b; ...', up to three fields (`fields_apart`);
    '' where they are one. Two files of one run store the same scenario, whatever their
    paths: a comparison, a reversal and a resumption each refuse a file of another run."""
    from revdem_cli.config import fields_apart

    apart = fields_apart(first, second)
    if not apart:
        return ""
    named = "; ".join(f"{key} = {a} and {b}" for key, a, b in apart[:3])
    more = f" and {len(apart) - 3} more" if len(apart) > 3 else ""
    return f"runs of different scenarios (or of other --set): {named}{more}"


def first_divergence_of(rows, tolerance: Reversal) -> int | None:
    """Step of the first row (in the second run's order) whose errors exceed the tolerance."""
    limits = (
        tolerance.position_tolerance_rel,
        np.inf,
        tolerance.velocity_tolerance,
        tolerance.angular_velocity_tolerance,
    )
    for row in rows:
        if any(value > limit for value, limit in zip(row[1:], limits, strict=True)):
            return row[0]
    return None


def divergence_causes(forward, divergence_step: int | None) -> list[dict]:
    """What destroyed information just before the reversed run parted from the forward one.

    The reversed run parts at the frame `divergence_step`, having come from the next frame
    of the forward run: the mechanisms that acted in between, newest first; if none did,
    those that acted at any step after it up to the restart (the reversal met them first:
    a drop held at its terminal velocity by drag parts only where the forward run started
    from rest, far from where the drag map's fixed point took its time). If none did:
    the reversed run's division by gamma_d where the run has drag, which amplifies round-off
    exponentially, and a time step above the critical one or the kinematic limit where the
    run was let go on at one (`--allow-unstable-dt`); otherwise nothing is named (round-off
    growth alone). A motion rounded away (`motion_below_round_off`: x + dt v == x) is never
    named: the reversed drift rounds x - dt v to x the same way (round to nearest is
    symmetric), so it destroys no more than any rounding; a rolling sphere at rest logs it
    every step and reverses to 1e-19 m without its rolling law.
    """
    if divergence_step is None or "observables/events" not in forward:
        return []
    steps = frame_steps(forward)
    later = np.nonzero(steps > divergence_step)[0]
    if len(later) == 0:
        return []
    scenario = _scenario_of(forward)
    walls = [wall.name for wall in scenario.walls] if scenario else []
    ids = forward["particles/all/id"][:]
    for frame in (int(later[0]), -1):  # just before it parted, else any time after
        log = forward["observables/events/value"][frame]
        window = [
            k
            for k in range(len(KINDS))
            if k != MOTION_LOST and log[k, COUNT] > 0 and log[k, LAST] > divergence_step
        ]
        if window:
            break
    velocity_read = _velocity_read(scenario)
    causes = sorted(
        (_cause(k, log[k], walls, ids, velocity_read) for k in window),
        key=lambda cause: -cause["step"],
    )
    if scenario is not None and _steered_back(scenario):
        causes.insert(0, _proportional_servo(int(steps[-1]), divergence_step))
    if causes or scenario is None:
        return causes
    if scenario.damping.drag < 1.0:
        causes.append(_drag_amplification(scenario.damping.drag, int(steps[-1]), divergence_step))
    from revdem_cli.timestep.guard import time_step_excess

    excess = time_step_excess(scenario)
    if excess is not None:
        causes.append(_unstable_time_step(excess, int(steps[-1]), divergence_step))
    return causes


def _scenario_of(trajectory) -> Scenario | None:
    text = trajectory["parameters/revdem"].attrs.get("scenario_json")
    return Scenario.model_validate_json(text) if text else None


def _drag_amplification(drag: float, restart_step: int, step: int) -> dict:
    """The reversed step divides velocities by gamma_d (Hanley 2020 Eq 28): round-off grows
    by 1/gamma_d per step on the way back."""
    exponent = (restart_step - step) * -math.log(drag)
    return _of_the_run(
        "drag_amplifies_round_off", step, exponent, restart_step - step,
        f"the reversed run divides velocities by gamma_d = {drag:g} each step (Eq 28): "
        f"round-off has grown by e^{exponent:.3g} over the {restart_step - step} steps back "
        "from the restart",
    )  # fmt: skip


def _of_the_run(mechanism: str, step: int, amount: float, steps: int, why: str) -> dict:
    """A cause of the whole run, where no mechanism destroyed information (`_run_cause`)."""
    return _run_cause(
        mechanism, step, amount, steps, f"no mechanism destroyed information here, but {why}"
    )


def _run_cause(mechanism: str, step: int, amount, steps: int, message: str) -> dict:
    """A cause of the whole run, not of a contact or a particle: no particle or partner,
    acting at each of the `steps` back from the restart."""
    return {
        "mechanism": mechanism,
        "step": step,
        **dict.fromkeys(("particle", "partner", "particle_id", "partner_id", "partner_wall")),
        "amount": amount,
        "occurrences": steps,
        "message": message,
    }


def _steered_back(scenario: Scenario) -> bool:
    """Whether the reversed stage holds a stress on some edge of the cell by the
    proportional servo, which reversed still steers towards its target."""
    stage = scenario.reversed_stage
    if scenario.cell is None or scenario.cell.servo != "proportional" or stage is None:
        return False
    motion = stage.cell
    return motion is not None and any(
        axis is not None and axis.stress is not None for axis in motion.axes()
    )


def _proportional_servo(restart_step: int, step: int) -> dict:
    """The proportional servo sets dL/dt from the stress error at the start of each step
    (Hanley 2020 §3.2.3): reversed it still steers towards its target, where the time
    reverse of a relaxation would steer away from it, so the reversal follows the forward
    run only as closely as the servo tracks its target."""
    return _run_cause(
        "proportional_servo", step, None, restart_step - step,
        "the proportional servo sets the cell's strain rate from its stress error at each "
        "step, and reversed still steers towards its target, where the time reverse of that "
        "relaxation would steer away from it (Hanley 2020 §3.2.3): the reversal follows the "
        "forward run only as closely as the servo tracks its target",
    )  # fmt: skip


def _unstable_time_step(excess, restart_step: int, step: int) -> dict:
    """A run let go on above the critical time step, whose velocity-Verlet steps amplify
    round-off each step (Peng 2020 Eq 47), or above the kinematic limit, where contacts can
    be missed going either way."""
    what = (
        "velocity-Verlet is unstable there and amplifies round-off every step"
        if excess.limit_name == "critical time step"
        else "a contact can begin or end unseen between two steps, going forward or back"
    )
    amount = excess.dt / excess.limit if excess.limit > 0.0 else math.inf
    return _of_the_run(
        "time_step_above_limit", step, amount, restart_step - step, f"{excess}: {what}"
    )


CONTACTS = frozenset(
    {"contact_lost_with_shear_force", "coulomb_slip", "rolling_limit",
     "contact_lost_with_rolling_moment", "viscous_damping"}
)  # fmt: skip
"""The mechanisms that act at a contact: theirs is the only cause with a partner."""


def _velocity_read(scenario: Scenario | None) -> str:
    """Why a velocity-dependent force breaks reversal, under the run's scheme."""
    order = scenario.integrator.predictor_order if scenario is not None else 0
    if order == 0:
        return "it pairs forces with the velocity of the other half step when reversed"
    return (
        f"it reads the time-reversible velocity predictor of order {order} (Kolafa & Lisal "
        f"2011), whose values going forward and back differ by O(dt^{2 * order + 1}) where "
        "the force is smooth in time, and by more across a kink: a linear dashpot's jump as a "
        "contact opens or closes (second order), local damping's sign change (no better than "
        "velocity Verlet)"
    )


def _newtons(force: float) -> str:
    """A force in the prefix of N its size reads in: 4 mN, 7.73 MN (the fcc test's 'removed
    7.73e+06 mN')."""
    if force == 0.0:
        return "0 N"
    for factor, unit in ((1e6, "MN"), (1e3, "kN"), (1.0, "N"), (1e-3, "mN"), (1e-6, "µN")):
        if abs(force) >= factor:
            return f"{force / factor:.3g} {unit}"
    return f"{force * 1e9:.3g} nN"


def _cause(kind: int, entry, walls: list[str], ids: np.ndarray, velocity_read: str) -> dict:
    """One mechanism of the event log `entry` as compare.json gives it: its last step, the
    particle and, at a contact (CONTACTS), the partner (a sphere's index in the arrays, -1 - w
    for wall w) with their ids (a wall's partner_wall its name), null where there is none,
    the amount, the count and one line that names them."""
    step, q, partner, amount = (
        int(entry[LAST]),
        int(entry[PARTICLE]),
        int(entry[PARTNER]),
        float(entry[AMOUNT]),
    )
    particle = particle_named(q, ids) if q >= 0 else "no particle"
    contact = f"the contact of {particle} and {partner_named(partner, ids, walls)}"
    messages = {
        "contact_lost_with_shear_force": f"{contact} lost shear force {_newtons(amount)} at "
        f"step {step}: the force zeroed at separation cannot be recovered",
        "coulomb_slip": f"{contact} slid at step {step}: the Coulomb limit removed "
        f"{_newtons(amount)} of shear force, which cannot be recovered",
        "local_damping": f"local damping (gamma_l = {amount:g}) acted up to step {step}: "
        f"{velocity_read}",
        "viscous_damping": f"viscous contact damping (beta = {amount:g}) acted up to step "
        f"{step}, last at {contact}: {velocity_read}",
        "velocity_fixed_point_under_drag": f"{particle} reached a fixed point of the drag "
        f"map at step {step} (|v| = {amount:.4g} m/s, terminal velocity or rest): the time spent "
        "there cannot be recovered",
        "rolling_limit": f"{contact} rolled at step {step}: the limit of its rolling law "
        f"removed {amount:.3g} N m of rolling moment, which cannot be recovered",
        "contact_lost_with_rolling_moment": f"{contact} lost rolling moment {amount:.3g} N m "
        f"at step {step}: the moment zeroed at separation cannot be recovered",
    }
    paired = KINDS[kind] in CONTACTS
    return {
        "mechanism": KINDS[kind],
        "step": step,
        "particle": q if q >= 0 else None,
        "partner": partner if paired else None,
        "particle_id": int(ids[q]) if q >= 0 else None,
        "partner_id": int(ids[partner]) if paired and partner >= 0 else None,
        "partner_wall": walls[-1 - partner] if paired and partner < 0 else None,
        "amount": amount,
        "occurrences": int(entry[COUNT]),
        "message": messages[KINDS[kind]],
    }
