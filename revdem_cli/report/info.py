"""`revdem info`: what a revdem file holds, read without running anything."""

from __future__ import annotations

from pathlib import Path

import h5py

from revdem_cli.config.schema import SERVO_PARAMETERS
from revdem_cli.errors import InputError
from revdem_cli.io import open_hdf5


def describe(path: str | Path) -> dict:
    """A summary of a revdem trajectory, restart file or checkpoint; InputError for anything
    else."""
    path = Path(path)
    f = open_hdf5(path)
    try:
        with f:
            if "revdem" in f and f["revdem"].attrs.get("kind") == "restart":
                return _restart(path)
            if "parameters/revdem" in f and "particles/all/position" in f:
                return _trajectory(path, f)
            if f.attrs.get("kind") == "revdem tape":
                return _tape(path, f)
            if "sweep" in f and "columns" in f["sweep"].attrs:  # kind = "revdem sweep"
                return _sweep(path)
            raise InputError(f"{path}: not a revdem trajectory, restart, tape or sweep table")
    except (KeyError, ValueError, OSError) as exc:
        raise InputError(f"{path}: damaged revdem file ({exc})") from None


def _scenario(text: str) -> dict:
    from revdem_cli.config import Scenario

    scenario = Scenario.model_validate_json(text)
    return {
        "scenario": scenario.name,
        "stages": [
            {
                "name": s.name,
                "steps": s.steps,
                "dt": s.dt or scenario.integrator.dt,
                "output_every": s.output_every,
                "reverse": s.reverse,
                "stop_when": s.stop_when.model_dump(exclude_none=True) if s.stop_when else None,
            }
            for s in scenario.stages
        ],
        "arithmetic": scenario.integrator.arithmetic,
        "scheme": scenario.integrator.scheme,
        "trvp_order": scenario.integrator.predictor_order or None,
        "cell": list(scenario.cell.size) if scenario.cell else None,
    }


def _grids(steps: list[float]) -> str:
    """A fixed-point run's grid steps (`state.fixed_grid`, in the order of `fixed.X` to
    `fixed.EDGE_RATE`) in words."""
    x, y, z, v, w, f, t, edge, rate = (f"{step:.3g}" for step in steps)
    return (
        f"position {x} {y} {z} (m, or of the edge in a deforming cell), velocity {v} m/s, "
        f"angular velocity {w} rad/s, force {f} N, moment {t} N m, edge {edge} m, edge rate "
        f"{rate} m/s"
    )


def _scheme(info: dict) -> str:
    """How velocity-dependent forces read the velocity at a full step, as `info` prints it."""
    if info["scheme"] == "verlet":
        return "verlet (velocity-dependent forces read the half-step velocity)"
    return (
        f"trvp (velocity-dependent forces read the time-reversible velocity predictor of "
        f"order {info['trvp_order']}, Kolafa & Lisal 2011)"
    )


def stop_condition(condition: dict | None) -> str:
    """A stage's stop condition in words, 'kinetic_energy_below 1e-07 (from step 2000 of
    the stage)'; '' for none."""
    if not condition:
        return ""
    after = condition.get("after_steps")
    (name, value), *_ = ((k, v) for k, v in condition.items() if k != "after_steps")
    if isinstance(value, dict):
        value = " ".join(f"{key} {item}" for key, item in value.items())
    return f"{name} {value}" + (f" (from step {after} of the stage)" if after else "")


def _trajectory(path: Path, f: h5py.File) -> dict:
    from revdem_cli.checkpoint import stopped_run
    from revdem_cli.compare import compared_files, read_verdict
    from revdem_cli.io.h5md import ended

    attrs = f["parameters/revdem"].attrs
    steps = f["particles/all/position/step"][:]
    info = {
        "file": str(path),
        "kind": "trajectory",
        "direction": str(attrs["direction"]),
        **_scenario(str(attrs["scenario_json"])),
        "particles": int(f["particles/all/radius"].shape[0]),
        "frames": int(len(steps)),
        "first_step": int(steps[0]) if len(steps) else None,
        "last_step": int(steps[-1]) if len(steps) else None,
    }
    if info["cell"] is not None and len(steps):  # the cell's edges at the first and last frame
        edges = f["particles/all/box/edges/value"]
        info["cell_frames"] = [[float(e) for e in edges[0]], [float(e) for e in edges[-1]]]
    if info["arithmetic"] == "fixed" and "fixed_grid" in attrs:
        info["grids"] = [float(step) for step in attrs["fixed_grid"]]
    info["ended"] = ended(f)  # None: written before trajectories said
    info["unfinished"], checkpoint = stopped_run(path, f)
    if checkpoint is not None:  # the run stopped, or is going on
        info["checkpoint"] = str(checkpoint)
    restart = path.with_name(f"{info['scenario']}.restart.h5")
    if info["direction"] == "forward" and restart.is_file():  # what its run said of its stages
        from revdem_cli.io.restart import restart_summary

        info |= _stages_ran(restart_summary(restart))
    comparison = path.with_name(f"{info['scenario']}.compare.json")
    if comparison.exists():
        verdict = read_verdict(comparison)
        if path.name in compared_files(verdict):
            shown = ("reversible", "max_position_error_rel", "first_divergence_step",
                     "bitwise_identical")  # fmt: skip
            info["comparison"] = {key: verdict[key] for key in shown}
        else:  # another run's, copied or left there: its verdict is not this trajectory's
            info["comparison_of_other_files"] = {
                "file": str(comparison),
                "pairing": verdict.get("pairing"),
            }
    return info


def _tape(path: Path, f: h5py.File) -> dict:
    """An information tape (`io.tape`)."""
    from revdem_cli.io.tape import summary

    return {
        "file": str(path),
        "kind": "tape",
        "stage": str(f.attrs["stage"]),
        "first_step": int(f.attrs["first_step"]),
        "particles": int(f.attrs["particles"]),
        "tape": summary(path),
    }


def _sweep(path: Path) -> dict:
    """A sweep's table (`sweep.write_table`): each variant's folder, the values it set and
    every result (status, verdict, energies, seconds, error), which the lines show in part
    (`_sweep_lines`) and `--json` in full."""
    from revdem_cli.sweep import table_rows

    return {"file": str(path), "kind": "sweep", "variants": table_rows(path)}


def _sweep_lines(info: dict) -> list[str]:
    variants = info["variants"]
    counts = {}
    for variant in variants:
        counts[variant["status"]] = counts.get(variant["status"], 0) + 1
    width = max(len(v["folder"]) for v in variants)
    lines = [
        f"file:       {info['file']}",
        f"kind:       sweep table of {len(variants)} variants ("
        + ", ".join(f"{count} {status}" for status, count in counts.items())
        + ")",
    ]
    for v in variants:
        if v["status"] != "done":
            verdict = v["error"] or ""
        elif v["reversible"] is None:
            verdict = "not reversed"
        else:
            verdict = "reversible" if v["reversible"] else "not reversible"
            verdict += f" (max position error / diameter {v['max_position_error_rel']:.3g})"
        lines.append(f"  {v['folder']:<{width}}  {v['status']:<11}  {verdict}".rstrip())
    return lines


def _restart(path: Path) -> dict:
    """A restart file, or a checkpoint: a restart taken part-way through a run; read whole,
    every checksum checked, as `revdem reverse` and `--resume` read it."""
    from revdem_cli.io.restart import read_restart

    restart = read_restart(path, checkpoint=None)
    resumption = restart.resumption
    run = _scenario(restart.scenario_json)
    if run["cell"] is not None:  # the cell as the state has it, not where it started
        run["cell"] = [float(edge) for edge in restart.state.cell.length]
    return {
        "file": str(path),
        "kind": "restart" if resumption is None else "checkpoint",
        "direction": "forward" if resumption is None else resumption.phase,
        **run,
        "particles": int(restart.state.particles.x.shape[0]),
        "step": int(restart.state.step),
        "stage": restart.stage,
        "stage_dt": float(restart.stage_dt),
        "trajectory": restart.trajectory,
        **_tape_of(path, restart.tape),
        **_stages_ran(restart.summary),
    }


def _stages_ran(summary: str) -> dict:
    """What the run a restart ends said of its stages (`Restart.summary`), where it said
    anything: `stages_ran`, {stopped, unmet, unheld, chosen_dt, capped} of those it has, and
    with unheld the kind of the cell's servo (None where the run did not keep it)."""
    import json

    summary = json.loads(summary)
    said = {
        key: value
        for key, value in summary.items()
        if key in ("stopped", "unmet", "unheld", "chosen_dt", "capped") and value
    }
    if "unheld" in said:
        said["servo"] = summary.get("servo")
    return {"stages_ran": said} if said else {}


def stresses_off(axes: dict) -> str:
    """The stresses a servo ended a stage with off their targets (`engine.Outputs.unheld`),
    in words: 'σ_xx 6.386e+04 Pa against 1.5e+05, ...'."""
    return ", ".join(
        f"σ_{axis}{axis} {stress:.4g} Pa against {target:.4g}"
        for axis, (stress, target) in axes.items()
    )


def servo_overshoot(servo: str | None) -> str:
    """What makes a servo of kind `servo` overshoot, in words (`SERVO_PARAMETERS`); both
    kinds' where the kind is not known (None: a restart written before runs kept it)."""
    if servo is None:
        return " or ".join(f"{servo_overshoot(kind)} ({kind})" for kind in SERVO_PARAMETERS)
    parameter, way = SERVO_PARAMETERS[servo]
    return f"a {parameter} {way}"


def stage_lines(said: dict) -> list[tuple[str, str]]:
    """(label, text) of each thing a run said of its stages (`_stages_ran`'s keys, each
    where there is any: `engine.Outputs` chosen_dt, stopped, unmet and unheld, with servo,
    the kind of the servo that did not hold, and capped, the stages whose law cut contact
    histories at their start, `stage.StageStart`), as the run's summary prints them and
    `info` of its restart gives them back."""
    lines = [
        ("time step", f"{dt:.6g} s in stage {stage} (dt = 'auto')")
        for stage, dt in said.get("chosen_dt", {}).items()
    ]
    for stage, (ran, most, every) in said.get("stopped", {}).items():
        first = ", at its first check: its condition held from its start" if ran <= every else ""
        lines.append(("stopped", f"stage {stage} after {ran} of {most} steps{first}"))
    for stage, condition in said.get("unmet", {}).items():
        text = f"stage {stage} ran all its steps without {stop_condition(condition)}"
        if "kinetic_energy_at_end" in condition:
            text += (
                f": {condition['kinetic_energy_at_end']:.3g} J at its end, "
                f"{condition['rotation_share']:.0%} of it the spheres' rotation"
            )
        lines.append(("not met", text))
    unheld = said.get("unheld", {})
    if unheld:
        from revdem_cli.engine import HELD  # here, as `info` of other files loads no kernels

        lines += [
            (
                "not held",
                f"stage {stage} ended with its servo off its target stress: "
                f"{stresses_off(axes)} (more than {HELD:.0%} off: "
                f"{servo_overshoot(said.get('servo'))} overshoots, a stage too short does not "
                "get there)",
            )
            for stage, axes in unheld.items()
        ]
    lines += [
        ("capped", capped_words(stage, start)) for stage, start in said.get("capped", {}).items()
    ]
    return lines


def capped_words(stage: str, start: dict) -> str:
    """What a stage's law cut at its start (`stage.StageStart`'s fields) in one line: 'stage
    shear began at step 22250 under friction 0.5: 201 contacts slid to the new limit,
    0.000641 J of elastic energy gone'."""
    rolled = f" and {start['rolled']} rolled to theirs" if start["rolled"] else ""
    return (
        f"stage {stage} began at step {start['step']} under friction {start['friction']:g}: "
        f"{start['slid']} contacts slid to the new limit{rolled}, {start['energy_gone']:.3g} J "
        "of elastic energy gone"
    )


def _tape_of(path: Path, name: str) -> dict:
    """A restart's information tape, summarised, where it names one that is there."""
    from revdem_cli.io.tape import summary

    tape = path.parent / name
    return {"tape": summary(tape)} if name and tape.is_file() else {}


def _until(condition: dict | None) -> str:
    """A stage's stop condition as `info` prints it: ', until kinetic_energy_below 1e-07'."""
    return f", until {stop_condition(condition)}" if condition else ""


def _time_step(dt: float | str) -> str:
    return "dt chosen at its start" if dt == "auto" else f"{dt:.6g} s"


def tape_lines(tape: dict) -> list[str]:
    """An information tape's summary as `label: value` lines."""
    lines = [
        f"tape:       {tape['file']}, {tape['steps']} steps, {tape['entries']} entries, "
        f"{tape['bytes']} B ({tape['size_over_full_state']:.3g} of the state at every step)",
        f"destroyed:  {tape['bits_destroyed']:.6g} bits, {tape['bits_per_step']:.4g} a step",
    ]
    for name, part in tape["by_mechanism"].items():
        lines.append(f"  {name}: {part['bits']:.6g} bits, {part['with_entries']} with entries")
    return lines


def info_lines(info: dict) -> list[str]:
    """The summary as `label: value` lines."""
    from revdem_cli.checkpoint import unfinished_words

    if info["kind"] == "sweep":
        return _sweep_lines(info)
    if info["kind"] == "tape":
        return [
            f"file:       {info['file']}",
            f"kind:       information tape of stage {info['stage']} from step "
            f"{info['first_step']}, {info['particles']} particles",
            *tape_lines(info["tape"]),
        ]
    stages = ", ".join(
        f"{s['name']} ({'at most ' if s['stop_when'] else ''}{s['steps']} steps of "
        f"{_time_step(s['dt'])}{_until(s['stop_when'])}{', reversed' if s['reverse'] else ''})"
        for s in info["stages"]
    )
    lines = [
        f"file:       {info['file']}",
        f"kind:       {info['kind']}"
        + (f" ({info['direction']})" if info["kind"] != "restart" else ""),
        f"scenario:   {info['scenario']}",
        f"stages:     {stages}",
        f"particles:  {info['particles']}",
        f"arithmetic: {info['arithmetic']}"
        + (" (64-bit integers on fixed grids)" if info["arithmetic"] == "fixed" else ""),
        f"scheme:     {_scheme(info)}",
    ]
    if "grids" in info:
        lines.append(f"grids:      {_grids(info['grids'])}")
    if "cell_frames" in info:  # a trajectory's cell, which may move: at its ends
        first, last = (" x ".join(f"{e:.6g}" for e in edges) for edges in info["cell_frames"])
        at = f" at step {info['first_step']}, {last} m at step {info['last_step']}"
        lines.append(f"cell:       periodic, {first} m" + (at if last != first else ""))
    elif info["cell"] is not None:
        lines.append(f"cell:       periodic, {' x '.join(f'{e:.6g}' for e in info['cell'])} m")
    if info["kind"] == "trajectory":
        steps = f", steps {info['first_step']} to {info['last_step']}"
        lines.append(
            f"frames:     {info['frames']}{steps if info['frames'] else ' (none written)'}"
        )
        if info.get("unfinished"):
            checkpoint = Path(info["checkpoint"]) if "checkpoint" in info else None
            said = unfinished_words(Path(info["file"]), checkpoint)
            if checkpoint is None:
                said += ": " + (
                    "the frames are those it wrote" if info["frames"] else "it wrote no frame"
                )
            lines.append(f"unfinished: {said}")
    elif info["kind"] == "checkpoint":
        lines.append(
            f"step:       {info['step']} (in stage {info['stage']}, dt {info['stage_dt']:.6g} s)"
        )
        lines.append(f"resume:     revdem run --resume {Path(info['file']).parent}")
    else:
        lines.append(
            f"step:       {info['step']} "
            f"(end of stage {info['stage']}, dt {info['stage_dt']:.6g} s)"
        )
        lines.append(f"trajectory: {info['trajectory']}")
        if "tape" in info:
            lines += tape_lines(info["tape"])
    lines += [
        f"{label + ':':<11} {text}" for label, text in stage_lines(info.get("stages_ran", {}))
    ]
    other = info.get("comparison_of_other_files")
    if other is not None:
        lines.append(
            f"reversal:   not known: {Path(other['file']).name} beside it compares other "
            f"files ({other['pairing'] or 'it names none'})"
        )
    verdict = info.get("comparison")
    if verdict is not None:
        if verdict["reversible"]:
            line = "reversible"
        else:
            line = f"not reversible, the runs part at step {verdict['first_divergence_step']}"
        exact = ", bitwise identical" if verdict["bitwise_identical"] else ""
        lines.append(
            f"reversal:   {line} (max position error / diameter "
            f"{verdict['max_position_error_rel']:.3g}{exact})"
        )
    return lines


def system_summary() -> dict:
    """This machine as revdem computes on it (`revdem info --system`)."""
    import numba

    from revdem_cli import __version__, kernel_cache, threads
    from revdem_cli.kernels import HEAVY, LIGHT, parallel_from

    cache = Path(numba.config.CACHE_DIR)
    others = kernel_cache.others(cache)
    return {
        "revdem": __version__,
        "numba": numba.__version__,
        **threads.summary(),
        "parallel_from_particles": {"light": parallel_from[LIGHT], "heavy": parallel_from[HEAVY]},
        "kernel_cache": str(cache),
        "kernel_cache_bytes": kernel_cache.size(cache),
        "other_kernel_caches": len(others),
        "other_kernel_caches_bytes": sum(kernel_cache.size(p) for p in others),
        "other_kernel_caches_kept": kernel_cache.CACHES_KEPT,
    }


def system_lines(summary: dict) -> list[str]:
    return [
        f"revdem:          {summary['revdem']} (numba {summary['numba']})",
        f"threading layer: {summary['threading_layer']} "
        f"(order tried: {', '.join(summary['layer_priority'])}); parallel regions on revdem's "
        f"threads: the caller and {summary['pool_helpers']} helper"
        f"{'' if summary['pool_helpers'] == 1 else 's'}",
        f"threads:         {summary['threads']} of a pool of {summary['thread_pool']}; "
        f"{summary['cores_available']} cores available",
        f"parallel loops:  from {summary['parallel_from_particles']['heavy']} particles for the "
        f"pairs and walls, {summary['parallel_from_particles']['light']} for the kicks and drifts "
        "(serial below)",
        f"kernel cache:    {summary['kernel_cache']} ({_megabytes(summary['kernel_cache_bytes'])});"
        f" beside it {summary['other_kernel_caches']} of other versions "
        f"({_megabytes(summary['other_kernel_caches_bytes'])}), of which a new version keeps the "
        f"{summary['other_kernel_caches_kept']} last used",
    ]


def _megabytes(size: int) -> str:
    return f"{size / 1e6:.0f} MB"
