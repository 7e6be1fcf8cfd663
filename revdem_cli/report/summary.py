"""One-screen summaries printed at the end of a command."""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from revdem_cli.report.info import stage_lines


def comparison_table(verdict: dict) -> Table:
    """The forward-versus-reversed comparison as a table."""
    tol = verdict["tolerance"]
    table = Table(title="forward vs reversed", title_justify="left")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_column("tolerance", justify="right")
    table.add_row("frames compared", str(verdict["frames_compared"]), "")
    if verdict.get("reversal_unfinished"):  # the frames it wrote before it stopped
        back = verdict["frames"]["step"][-1]
        table.add_row("reversal", f"unfinished: frames back to step {back}", "")
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
    unfinished = verdict.get("reversal_unfinished")
    if unfinished:  # a verdict on the steps it went back, not on a whole reversal
        said = escape(unfinished)
        if verdict["reversible"]:
            return (
                "[bold yellow]reversible so far[/]: the reversed run retraces the forward run "
                f"within tolerance, but the reversal is unfinished: {said}"
            )
        whole = verdict_line(verdict | {"reversal_unfinished": None})
        return f"{whole}\n  the reversal is unfinished: {said}"
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
    said = {
        "chosen_dt": outputs.chosen_dt,
        "stopped": outputs.stopped,
        "unmet": outputs.unmet,
        "unheld": outputs.unheld,
        "servo": outputs.servo,
        "capped": outputs.capped,
    }
    for label, text in stage_lines(said):
        console.print(f"  {label:<20} {text}", soft_wrap=True)
    if outputs.verdict is not None:
        console.print(verdict_line(outputs.verdict))
    elif outputs.reverse is not None:
        looked = " nor ".join(escape(str(path)) for path in outputs.forward_sought)
        where = f": no file at {looked}" if looked else ""
        console.print(
            f"[yellow]no comparison[/]: the forward trajectory named in the restart is not "
            f"there{where}",
            soft_wrap=True,
        )
