"""The `revdem` command line: parse, call, print. No physics here; heavy imports are lazy."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperGroup

from revdem_cli import __version__
from revdem_cli.errors import InputError, RunFailed, given_options, path_problem
from revdem_cli.options import OnceEach, named_file, named_folder
from revdem_cli.timestep.command import dt as _dt


class _Commands(TyperGroup):
    """Turns bad input anywhere in a command into one line on stderr and exit status 2 (a
    path given that cannot be used too: `errors.path_problem`), and a run that cannot go on
    (RunFailed) or a failure of the machine or the file system (RuntimeError, OSError,
    MemoryError) into one line and exit status 1. Any other exception is a bug and keeps its
    traceback."""

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        """As click's, but a usage error (an unknown option, a missing argument) is one line
        "error: COMMAND: what is wrong" and exit status 2, not a box with the usage."""
        from typer._click.exceptions import NoArgsIsHelpError, UsageError

        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            code = super().main(*args, standalone_mode=False, **kwargs)
        except NoArgsIsHelpError as exc:  # `revdem` alone: its help
            typer.echo(exc.ctx.get_help())
            sys.exit(2)
        except UsageError as exc:
            where = exc.ctx.command_path if exc.ctx else "revdem"
            message = " ".join(exc.format_message().split())
            param = getattr(exc, "param", None)
            if param is not None and (param.nargs or 1) > 1:  # too few values took the next
                message += f" ({param.opts[0]} takes {param.nargs} values)"  # option as one
            typer.echo(f"error: {where}: {message} (see {where} --help)", err=True)
            sys.exit(2)
        except typer.Abort:
            typer.echo("aborted", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except InputError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2) from None
        except (typer.Exit, typer.Abort):
            raise  # typer's own ways out are RuntimeErrors too
        except KeyboardInterrupt:  # outside a run, or a second Ctrl-C within one
            typer.echo("stopped: SIGINT, no checkpoint written", err=True)
            raise typer.Exit(130) from None
        except RunFailed as exc:
            typer.echo(f"failed: {exc}", err=True)
            raise typer.Exit(1) from None
        except BrokenPipeError:  # the reader of stdout went away (`revdem ... | head`):
            # nothing is left to say; stdout is pointed at /dev/null so that the last flush
            # does not fail again, and the status is 1, as click gives a --help cut short
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            raise typer.Exit(1) from None
        except OSError as exc:
            problem = path_problem(exc)  # a path given that cannot be used: bad input
            if problem is not None:
                typer.echo(f"error: {problem}", err=True)
                raise typer.Exit(2) from None
            typer.echo(f"failed: {type(exc).__name__}: {exc}", err=True)
            raise typer.Exit(1) from None
        except (RuntimeError, MemoryError) as exc:
            typer.echo(f"failed: {type(exc).__name__}: {exc}", err=True)
            raise typer.Exit(1) from None


app = typer.Typer(
    cls=_Commands,
    name="revdem",
    help="DEM of spheres forward and in reversed time; critical time steps of convex particles.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=True,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"revdem {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")
    ] = False,
) -> None:
    """revdem: reversible DEM experiments and critical time steps."""


AllowUnstableDt = Annotated[
    bool,
    typer.Option(
        "--allow-unstable-dt",
        help="Take a dt above the critical estimate (or the kinematic limit), which is refused "
        "otherwise.",
    ),
]


Threads = Annotated[
    int | None,
    typer.Option(
        "--threads",
        min=1,
        help="Threads of the parallel loops (default: the cores this process may use).",
    ),
]


def _progress_of(unit: str, compiling: bool):
    from revdem_cli.report.progress import RunProgress

    return RunProgress(unit=unit, compiling=compiling)


@app.command()
def run(
    ctx: typer.Context,
    scenario: Annotated[
        Path | None, typer.Argument(help="Scenario file (.toml, .yaml or .yml).")
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", parser=named_folder, help="Output directory.")
    ] = Path("out"),
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", help="Override a scenario field, e.g. --set integrator.dt=5e-8."),
    ] = None,
    no_reverse: Annotated[
        bool, typer.Option("--no-reverse", help="Run forward only, even if a stage is reversed.")
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
    allow_unstable_dt: AllowUnstableDt = False,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite the outputs of an earlier run in --out.")
    ] = False,
    resume: Annotated[
        Path | None,
        typer.Option(
            "--resume",
            help="Continue the run whose checkpoint is in this directory, instead of a scenario.",
        ),
    ] = None,
    threads: Threads = None,
) -> None:
    """Run a scenario forward; if a stage is marked reverse, run it backwards and compare.

    A file with kind = "critical_time_step" is a time-step study: its figures go to --out.
    Outputs already in --out are kept: the run refuses to start unless --force, and where
    another revdem run writes into --out (it holds --out/.lock). A run
    stopped by Ctrl-C (exit 130) or SIGTERM (143) writes a checkpoint at the step it was
    at; it, or one that crashed, continues with --resume DIR from its newest checkpoint,
    into the same trajectory an uninterrupted run writes.

    Example: revdem run configs/collision.toml --out out
    """
    from revdem_cli import api
    from revdem_cli.report.summary import print_summary

    if resume is not None:
        if scenario is not None or overrides:
            raise InputError("--resume DIR continues a run as it was: give no scenario or --set")
        given = given_options(ctx, ("out", "no_reverse", "force", "allow_unstable_dt"))
        if given:
            raise InputError(
                f"--resume DIR continues a run as it was, into DIR: {', '.join(given)} "
                "cannot change it (--quiet and --threads can)"
            )
        print_summary(_interruptible(api.resume, resume, not quiet, threads).outputs)
        return
    if scenario is None:
        raise InputError("give a scenario file, or --resume DIR")

    from revdem_cli.timestep.study import read_study, run_study, study_outputs

    study = read_study(scenario, overrides or [])
    if study is not None:
        from revdem_cli.io.lock import sole_writer

        with sole_writer(out):
            api.keep_outputs(study_outputs(study, out), force)
            for path in run_study(study, out):
                typer.echo(f"wrote {path}")
        return

    experiment = api.load(scenario, overrides=overrides or [])
    result = _interruptible(
        api.run, experiment, out, not no_reverse, force, allow_unstable_dt, not quiet, threads
    )
    print_summary(result.outputs)


def _interruptible(command, *args):
    """Run `command`; a checkpoint written on SIGINT or SIGTERM ends it with one line and
    exit status 128 + the signal's number."""
    from revdem_cli.checkpoint import Interrupted, Unfinished

    try:
        return command(*args)
    except Interrupted as exc:
        typer.echo(f"stopped: {exc}; continue with revdem run --resume {exc.path.parent}", err=True)
        raise typer.Exit(exc.exit_code) from None
    except Unfinished as exc:
        typer.echo(f"stopped: {exc}", err=True)
        raise typer.Exit(exc.exit_code) from None


@app.command()
def reverse(
    restart: Annotated[Path, typer.Argument(help="Restart file written by `revdem run`.")],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", parser=named_folder, help="Output directory (default: beside the restart)."
        ),
    ] = None,
    steps: Annotated[
        int | None, typer.Option("--steps", help="Reverse only this many steps.")
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite the outputs of an earlier reversal.")
    ] = False,
    threads: Threads = None,
) -> None:
    """Run the stage that ended at RESTART backwards and compare with its forward trajectory.

    Outputs already in the output directory are kept: the reversal refuses to start unless
    --force, and where another revdem run writes into it (it holds its .lock).

    Example: revdem reverse out/collision.restart.h5
    """
    from revdem_cli import api
    from revdem_cli.report.summary import print_summary

    outputs = _interruptible(api.reverse, restart, out, steps, force, not quiet, threads).outputs
    print_summary(outputs)


@app.command()
def compare(
    first: Annotated[Path, typer.Argument(help="Trajectory, e.g. out/collision.forward.h5.")],
    second: Annotated[Path, typer.Argument(help="Trajectory, e.g. out/collision.reverse.h5.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the comparison as JSON.")] = False,
) -> None:
    """Compare two trajectories frame by frame at their common steps.

    Example: revdem compare out/collision.forward.h5 out/collision.reverse.h5 --json
    """
    import json

    from revdem_cli.compare import compare_trajectories
    from revdem_cli.report.summary import print_comparison

    verdict = compare_trajectories(first, second)
    if as_json:
        typer.echo(json.dumps(verdict, indent=2))
    else:
        print_comparison(verdict)


@app.command()
def validate(
    scenario: Annotated[Path, typer.Argument(help="Scenario file (.toml, .yaml or .yml).")],
    overrides: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="Override a scenario field; of a sweep file, key=v1,v2,... as sweep takes it.",
        ),
    ] = None,
    allow_unstable_dt: AllowUnstableDt = False,
) -> None:
    """Check a scenario, time-step study or sweep file without running it, as run and sweep
    check it before they start: a time step above the critical estimate too.

    Example: revdem validate configs/collision.toml
    """
    from revdem_cli.config import load_scenario
    from revdem_cli.engine import check_time_step
    from revdem_cli.sweep import load_variants, read_sweep_file
    from revdem_cli.timestep.study import read_study

    study = read_study(scenario, overrides or [])
    if study is not None:
        typer.echo(f"{scenario}: valid time-step study: figures {study.figures}")
        return
    sweep = read_sweep_file(scenario, overrides or [])
    if sweep is not None:
        variants = load_variants(sweep, allow_unstable_dt=allow_unstable_dt)
        typer.echo(f"{scenario}: valid sweep: {len(variants)} variants of {sweep.scenario}")
        return
    spec, _ = load_scenario(scenario, overrides or [])
    if not allow_unstable_dt:
        check_time_step(spec, str(scenario))
    steps = sum(stage.steps for stage in spec.stages)
    typer.echo(
        f"{scenario}: valid: {len(spec.spheres)} particles, {len(spec.stages)} "
        f"stage(s), at most {steps} steps"
    )


@app.command()
def schema() -> None:
    """Print the JSON schema of scenario files (every field with its unit).

    Example: revdem schema > scenario.schema.json
    """
    import json

    from revdem_cli.config import Scenario

    typer.echo(json.dumps(Scenario.model_json_schema(), indent=2))


@app.command()
def info(
    file: Annotated[
        Path | None,
        typer.Argument(help="A revdem trajectory, restart, checkpoint, tape or sweep.h5."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
    system: Annotated[
        bool,
        typer.Option(
            "--system", help="Describe this machine as revdem computes on it, instead of a file."
        ),
    ] = False,
) -> None:
    """Summarise a revdem trajectory, restart, tape or sweep table, or (--system) this machine.

    Kind, direction, scenario, stages, particles, frames and steps, dt, and the reversal
    verdict when the run's NAME.compare.json lies beside the trajectory and names it among
    the files it compared (else that it compares other files); of a sweep's
    sweep.h5, each variant's status and verdict. --system: the
    threading layer numba loaded, the threads and cores, numba's version, the kernel caches
    and what they hold.

    Example: revdem info out/collision.forward.h5
    """
    import json

    if system and file is not None:
        raise InputError(
            f"info: --system describes this machine, {file} a file: give them separately"
        )
    if not system and file is None:
        raise InputError("info: give a trajectory or restart file, or --system")
    if system:
        from revdem_cli.report.info import system_lines, system_summary

        summary = system_summary()
        typer.echo(json.dumps(summary, indent=2) if as_json else "\n".join(system_lines(summary)))
        return
    from revdem_cli.report.info import describe, info_lines

    summary = describe(file)
    typer.echo(json.dumps(summary, indent=2) if as_json else "\n".join(info_lines(summary)))


@app.command()
def export(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory, e.g. out/collision.forward.h5.")],
    format: Annotated[
        str | None,
        typer.Option(
            "--format",
            help="vtk (a .vtp a frame and a .pvd series, for ParaView), gsd (one .gsd, for "
            "OVITO and HOOMD-blue), lammps-dump (one text dump, for OVITO, VMD, LAMMPS) or "
            "lammps-data (the last frame as a data file, for LAMMPS' read_data).",
        ),
    ] = None,
    vtk: Annotated[bool, typer.Option("--vtk", help="The same as --format vtk.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
    out: Annotated[
        str | None,
        typer.Option(
            "--out",
            parser=named_file,
            help="Output directory (vtk) or file (default: TRAJECTORY without .h5, + .vtk, "
            ".gsd, .dump or .data).",
        ),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(
            "--force",
            help="Write over a file that --out names and exists (vtk: the series and frames "
            "of an earlier export of TRAJECTORY in the --out folder).",
        ),
    ] = False,
    step: Annotated[
        int | None,
        typer.Option(
            "--step",
            help="lammps-data: the frame at this step (default: the last); the other formats "
            "write every frame.",
        ),
    ] = None,
) -> None:
    """Export a trajectory: VTK for ParaView, GSD or a LAMMPS dump for OVITO, a LAMMPS data
    file of its last frame for LAMMPS and LIGGGHTS.

    ParaView: open the .pvd and glyph the points with spheres scaled by `radius`. OVITO
    reads the radii and the box of a .gsd or a .dump as they are. A scenario reads a data
    file back in its particles_from table (lammps_data = FILE).

    In a periodic cell that deforms, every format's velocities are the spheres' own, relative
    to the cell's affine motion (as revdem keeps them, like Yade's homothetic cell), where
    LAMMPS and LIGGGHTS read vx vy vz as total velocities: a sphere at x in a cell straining
    at rate e (1/s, each axis's dL/dt / L) moves at v + e x. The trajectory keeps the cell's
    edges at each frame but not their rates, so export does not add it.

    Example: revdem export out/collision.forward.h5 --format gsd
    """
    from revdem_cli.io import EXPORT_SUFFIXES, export_target

    if vtk and format not in (None, "vtk"):
        raise InputError(f"export: --vtk and --format {format} ask for two formats; give one")
    format = "vtk" if vtk else format
    if format not in EXPORT_SUFFIXES:
        given = "give one" if format is None else f"got {format!r}"
        raise InputError(f"export: --format must be one of {', '.join(EXPORT_SUFFIXES)}; {given}")
    from contextlib import nullcontext
    from functools import partial

    from revdem_cli.io import particles, refuse_overwriting
    from revdem_cli.io.vtk import export_vtk, own_files

    target = out or export_target(trajectory, format)  # as given: see options.named_file
    keep = out is not None and not force
    if format != "vtk":
        refuse_overwriting("export", target, keep, trajectory)
    elif keep and (earlier := own_files(target, trajectory.stem)):  # its --out is a folder
        more = f" and {len(earlier) - 1} more" if len(earlier) > 1 else ""
        raise InputError(
            f"export: --out {target}: holds {earlier[0].name}{more} of an earlier export of "
            f"{trajectory.name}; use --force to overwrite"
        )
    if step is not None and format != "lammps-data":
        raise InputError(f"export: --step picks the frame of a lammps-data export; {format} "
                         "writes every frame")  # fmt: skip
    exporter = {
        "vtk": export_vtk,
        "gsd": particles.export_gsd,
        "lammps-dump": particles.export_lammps_dump,
        "lammps-data": partial(particles.export_lammps_data, step=step),
    }[format]
    with nullcontext() if quiet else _progress_of("frames", False) as shown:
        written = exporter(trajectory, target, shown)
    if format == "vtk":  # each series and its frames: the spheres', and the force chains'
        for series, frames in written.items():
            typer.echo(f"wrote {series} and its {len(frames)} frame files")
    else:
        typer.echo(f"wrote {written}")


@app.command()
def sweep(
    scenario: Annotated[
        Path, typer.Argument(help='Scenario file, or a sweep file (TOML, kind = "sweep").')
    ],
    sets: Annotated[
        list[str] | None,
        typer.Option(
            "--set", help="key=v1,v2,...: values of a scenario field; every combination runs."
        ),
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", parser=named_folder, help="Output directory.")
    ] = Path("out/sweep"),
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            help="Address of a dask scheduler, whose own workers run the variants (default: "
            "a local cluster).",
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            min=1,
            help="Worker processes of the local cluster (default 2); refused with "
            "--scheduler, whose workers are those started for it.",
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress display.")] = False,
    threads: Annotated[
        int | None,
        typer.Option(
            "--threads",
            min=1,
            help="Threads of each variant's parallel loops (default: on a local cluster the "
            "cores this process may use over --workers, at least 1; on a scheduler's workers "
            "the cores each may use). A scheduler's workers check it against their own pools.",
        ),
    ] = None,
    allow_unstable_dt: AllowUnstableDt = False,
    force: Annotated[
        bool,
        typer.Option("--force", help="Overwrite an earlier sweep's tables and runs in --out."),
    ] = False,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Go on with the sweep stopped in --out: keep the variants done, continue "
            "the stopped ones from their checkpoints, run the rest.",
        ),
    ] = False,
) -> None:
    """Run every combination of --set values, forward and reversed, in parallel (dask).

    Each variant runs in its own folder under --out; sweep.csv and sweep.h5 there hold each
    variant's values, status, reversal verdict and final energies. Exit status 1 if a
    variant failed. Ctrl-C or SIGTERM stops each running variant at a whole step with a
    checkpoint and writes the table (exit status 130 or 143); --resume goes on.

    Example: revdem sweep configs/collision_shear.toml --set contact.friction=0.1,0.3,inf
    """
    from revdem_cli.report.progress import kernels_compiled
    from revdem_cli.sweep import FAILED, read_sweep, run_sweep, stop_summary

    plan = read_sweep(scenario, sets or [])
    from contextlib import nullcontext

    compiling = scheduler is None and not kernels_compiled()  # a local cluster's workers
    # compile into this machine's cache; a remote one's workers keep caches of their own
    with nullcontext() if quiet else _progress_of("variants", compiling) as shown:
        rows, tables, signum = run_sweep(
            plan, out, scheduler, workers, shown, threads, allow_unstable_dt, force, resume
        )
    failed = sum(row["status"] == FAILED for row in rows)
    for path in tables:
        typer.echo(f"wrote {path}")
    if not signum:  # stopped, the line below counts each status
        typer.echo(f"{len(rows)} variant{'s' * (len(rows) != 1)}, {failed} failed")
    for row in rows:
        if row["status"] == FAILED:
            typer.echo(f"failed: {row['folder']}: {row['error']}", err=True)
    if signum:
        typer.echo(
            f"stopped: {signal.Signals(signum).name}: {stop_summary(rows)}; continue with the "
            "same command and --resume",
            err=True,
        )
        raise typer.Exit(128 + signum)
    if failed:
        raise typer.Exit(1)


@app.command()
def report(
    directory: Annotated[Path, typer.Argument(help="Directory of runs, e.g. out.")],
    paper: Annotated[
        Path | None,
        typer.Option(
            "--paper",
            help="What the paper reports (default: the project's "
            "scenarios/hanley2020/paper_numbers.toml, wherever revdem is run from).",
        ),
    ] = None,
    out: Annotated[
        str | None,
        typer.Option(
            "--out", parser=named_file, help="Markdown file (default: DIRECTORY/report.md)."
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Write over a file that --out names and exists.")
    ] = False,
) -> None:
    """Write a Markdown page setting the paper's numbers beside the runs in DIRECTORY.

    Example: revdem report out
    """
    from revdem_cli.io import refuse_overwriting
    from revdem_cli.report.paper import HANLEY_2020, write_report

    target = out or directory / "report.md"
    keep = out is not None and not force
    refuse_overwriting("report", target, keep)
    written = write_report(directory, paper or HANLEY_2020, target, keep)
    typer.echo(f"wrote {written}")


app.command("dt")(_dt)


def _reflowed(doc: str) -> str:
    """A command's docstring as its --help shows it: each paragraph's lines joined, so that
    the help wraps at the terminal's width, not where the source's lines end."""
    import inspect

    return "\n\n".join(" ".join(part.split()) for part in inspect.cleandoc(doc).split("\n\n"))


for _command in app.registered_commands:
    _command.cls = OnceEach  # an option given twice is refused, not taken last-wins
    if _command.help is None and _command.callback.__doc__:
        _command.help = _reflowed(_command.callback.__doc__)


def main() -> None:
    try:
        app()
    except SystemExit as exc:
        stuck = sys.modules.get("revdem_cli.io.h5md")
        if stuck is not None and stuck.STUCK:  # see io.h5md.STUCK: its message is out
            import os

            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(exc.code if isinstance(exc.code, int) else 1)
        raise


if __name__ == "__main__":
    main()
