"""Progress display for runs (rich): stage, steps, particle-steps per second, ETA."""

from __future__ import annotations

import time

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn


class RunProgress:
    """Context manager; call it as progress(label, done, total, particles) once per output
    frame, or progress(label, done, total) once per finished item counted in `unit`."""

    def __init__(self, unit: str = "steps"):
        self.console = Console(stderr=True)
        self.bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed:>9,.0f}/{task.total:,.0f} " + unit),
            TextColumn("{task.fields[rate]}"),
            TimeRemainingColumn(),
            console=self.console,
            transient=False,
        )
        self.tasks: dict[str, int] = {}
        self.started: dict[str, float] = {}

    def __enter__(self) -> RunProgress:
        self.bar.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.bar.__exit__(*exc)

    def __call__(self, label: str, done: int, total: int, particles: int = 0) -> None:
        if particles and not self.tasks:  # the first frame of a run: what it computes on
            self.console.print(threads_line())
        if label not in self.tasks:
            self.tasks[label] = self.bar.add_task(label, total=total, rate="")
            self.started[label] = time.perf_counter()
        elapsed = time.perf_counter() - self.started[label]
        rate = (
            f"{particles * done / elapsed:,.3g} particle-steps/s"
            if elapsed > 0 and particles
            else ""
        )
        self.bar.update(self.tasks[label], completed=done, rate=rate)


def threads_line() -> str:
    """`2 threads at most (omp), 2 cores`: what a run computes on."""
    from revdem_cli import threads

    info = threads.summary()
    count = info["threads"]
    return (
        f"computing on {count} thread{'s' * (count > 1)} at most ({info['threading_layer']} "
        f"layer; {info['cores_available']} cores available)"
    )
