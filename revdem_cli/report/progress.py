"""Progress display for runs (rich): stage, steps, particle-steps per second, time elapsed
and to go; before a run whose kernels numba has yet to compile, a line that says so."""

from __future__ import annotations

import os
import time

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

COMPILING = "compiling the kernels: once after an install or upgrade, 3 to 4 min on 2 cores"

LOG_WIDTH = 132
"""Columns of the display written to a file or a pipe (a batch job's log), where rich would
take 80 and cut the times and rates to '0…'; a terminal's own width, or COLUMNS, rules."""


class RunProgress:
    """Context manager; call it as progress(label, done, total, particles) once per output
    frame, or progress(label, done, total) once per finished item counted in `unit`.
    `compiling`: the run will compile its kernels first, which it says as it starts."""

    def __init__(self, unit: str = "steps", compiling: bool = False):
        self.console = Console(stderr=True)
        if not self.console.is_terminal and "COLUMNS" not in os.environ:
            self.console = Console(stderr=True, width=LOG_WIDTH)
        self.compiling = compiling
        self.bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed:>9,.0f}/{task.total:,.0f} " + unit),
            TextColumn("{task.fields[rate]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=self.console,
            transient=False,
        )
        self.tasks: dict[str, int] = {}
        self.last: dict[str, tuple[float, int]] = {}  # each task's last call: time, done

    def __enter__(self) -> RunProgress:
        if self.compiling:
            self.console.print(COMPILING)
        return self

    def __exit__(self, *exc) -> None:
        if self.tasks:  # a display that never showed a bar leaves no blank line
            self.bar.__exit__(*exc)

    def __call__(self, label: str, done: int, total: int, particles: int = 0) -> None:
        if not self.tasks:  # the first call: the display starts
            if particles:  # the start of a run: what it computes on
                self.console.print(threads_line())
            self.bar.__enter__()
        now = time.perf_counter()
        if label not in self.tasks:
            self.tasks[label] = self.bar.add_task(label, total=total, rate="")
            self.last[label] = (now, done)
        then, done_then = self.last[label]
        shown = {}
        if now > then and done != done_then and particles:  # since the call before
            rate = particles * abs(done - done_then) / (now - then)
            shown["rate"] = f"{rate:,.3g} particle-steps/s"
        self.last[label] = (now, done)
        self.bar.update(self.tasks[label], completed=done, total=total, **shown)


def threads_line() -> str:
    """`2 threads at most (omp), 2 cores`: what a run computes on."""
    from revdem_cli import threads

    info = threads.summary()
    count = info["threads"]
    return (
        f"computing on {count} thread{'s' * (count > 1)} at most ({info['threading_layer']} "
        f"layer; {info['cores_available']} cores available)"
    )


def kernels_compiled(*kernels) -> bool:
    """Whether numba's disk cache holds `kernels` (default: the stage loop,
    `kernels.integrate.advance`, one signature for every run) compiled from these sources,
    the index file numba keeps for each: where it does not, a run's first steps wait minutes
    for it (*Compile time* in benchmarks/RECORD.md)."""
    from pathlib import Path

    if not kernels:
        from revdem_cli.kernels.integrate import advance

        kernels = (advance,)
    return all(Path(k._cache._cache_file._index_path).is_file() for k in kernels)
