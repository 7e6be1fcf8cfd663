"""One-screen summaries printed at the end of a command."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from revdem_cli.engine import HELD
from revdem_cli.report.info import stop_condition, stresses_off


def comparison_table(verdict: dict) -> Table:
    """The forward-versus-reversed comparison as a table."""
    tol = verdict["tolerance"]
    table = Table(title="forward vs reversed", title_justify="left")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_column("tolerance", justify="right")
    table.add_row("frames compared", str(verdict["frames_compared"]), "")
    table.add_row(
        "max position error / smallest diameter",
        f"{verdict['max_position_error_rel']:.3e}",
        f"{tol['position_tolerance_rel']:.0e}",
    )
    table.add_row("max position error (m)", f"{verdict['max_position_error']:.3e}", "")
    table.add_row(
        "max velocity error (m/s)",
        f"{verdict['max_velocity_error']:.3e}",
        f"{tol['velocity_tolerance']:.0e}",
    )
    table.add_row(
        "max angular velocity error (rad/s)",
        f"{verdict['max_angular_velocity_error']:.3e}",
        f"{tol['angular_velocity_tolerance']:.0e}",
    )
    first = verdict["first_divergence_step"]
    table.add_row("first divergence step", "none" if first is None else str(first), "")
    table.add_row("bitwise identical", "yes" if verdict["bitwise_identical"] else "no", "")
    energy = verdict.get("total_energy_back")
    if energy is not None:
        step = energy["step"]
        table.add_row(f"total energy at step {step}, reversed (J)", f"{energy['reversed']:.6g}", "")
        table.add_row(f"total energy at step {step}, forward (J)", f"{energy['forward']:.6g}", "")
    tape = verdict.get("information_tape")
    if tape is not None:
        table.add_row("bits destroyed (information tape)", f"{tape['bits_destroyed']:.4g}", "")
        for name, part in tape["by_mechanism"].items():
            table.add_row(f"  {name}", f"{part['bits']:.4g}", "")
        table.add_row(
            "tape size / whole state every step", f"{tape['size_over_full_state']:.3g}", ""
        )
    return table


def verdict_line(verdict: dict) -> str:
    if verdict["reversible"]:
        return (
            "[bold green]reversible[/]: the reversed run retraces the forward run within tolerance"
        )
    line = f"[bold red]not reversible[/]: the runs part at step {verdict['first_divergence_step']}"
    causes = verdict.get("divergence_causes") or []
    if not causes:
        return line + "; no information-destroying mechanism acted: round-off growth"
    return line + "".join(f"\n  cause: {cause['message']}" for cause in causes)


def print_comparison(verdict: dict) -> None:
    console = Console()
    console.print(comparison_table(verdict))
    console.print(verdict_line(verdict))


def print_summary(outputs, console: Console | None = None) -> None:
    console = console or Console()
    if outputs.verdict is not None:
        console.print(comparison_table(outputs.verdict))
    written = [
        ("forward trajectory", outputs.forward),
        ("restart", outputs.restart),
        ("reversed trajectory", outputs.reverse),
        ("comparison", outputs.comparison),
    ]
    written += [*outputs.stage_files, *(("figure", path) for path in outputs.figures)]
    for label, path in written:
        if path is not None:
            console.print(f"  {label:<20} {path}")
    for path in outputs.stale_exports:
        said = "made before this run wrote its trajectory; export again"
        line = f"  {'stale export':<20} {path} ({said})"
        console.print(line, soft_wrap=True, markup=False)
    for stage, dt in outputs.chosen_dt.items():
        console.print(f"  {'time step':<20} {dt:.6g} s in stage {stage} (dt = 'auto')")
    for stage, (ran, most, every) in outputs.stopped.items():
        first = ", at its first check: its condition held from its start" if ran <= every else ""
        line = f"  {'stopped':<20} stage {stage} after {ran} of {most} steps{first}"
        console.print(line, soft_wrap=True)
    for stage, condition in outputs.unmet.items():
        line = (
            f"  {'not met':<20} stage {stage} ran all its steps without {stop_condition(condition)}"
        )
        if "kinetic_energy_at_end" in condition:
            line += (
                f": {condition['kinetic_energy_at_end']:.3g} J at its end, "
                f"{condition['rotation_share']:.0%} of it the spheres' rotation"
            )
        console.print(line, soft_wrap=True)
    for stage, axes in outputs.unheld.items():
        line = (
            f"  {'not held':<20} stage {stage} ended with its servo off its target stress: "
            f"{stresses_off(axes)} (more than {HELD:.0%} off: a servo_mass too small or a "
            "servo_gain too large overshoots, a stage too short does not get there)"
        )
        console.print(line, soft_wrap=True)
    if outputs.verdict is not None:
        console.print(verdict_line(outputs.verdict))
    elif outputs.reverse is not None:
        console.print(
            "[yellow]no comparison[/]: the forward trajectory named in the restart is not there"
        )
