"""Checkpoints: when a run saves one, where, and what SIGINT and SIGTERM do.

A checkpoint is taken at an output frame once `output.checkpoint_interval` seconds of wall
time have passed since the last: the trajectory is flushed, then the state is written to
`<name>.checkpoint.h5` beside it, to a temporary name renamed over the old one. A finished
run removes it. `revdem run --resume DIR` continues from it, and the continued trajectory
is the one an uninterrupted run writes.

SIGINT and SIGTERM stop a run at the next whole step, wherever it falls between frames,
with a checkpoint there: the compiled stage loop runs in the main thread (`threads.Stepper`),
where Python's handler waits for it to return, so each signal also wakes a watcher thread
(`signal.set_wakeup_fd`), which sets the flag the loop reads at every step. After the last
step a signal stops the comparison and figures at once (`Unfinished`). A run off the main
thread, a sweep's variant on a dask worker, takes no signal: a stop file the sweep writes
sets the same flag (`polling`).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from revdem_cli.errors import InputError
from revdem_cli.io import write_text
from revdem_cli.io.restart import Restart, write_restart
from revdem_cli.threads import Stepper

SUFFIX = ".checkpoint.h5"


def checkpoint_path(out_dir: Path, name: str) -> Path:
    return Path(out_dir) / f"{name}{SUFFIX}"


class Interrupted(BaseException):
    """The run stopped on a signal after writing a checkpoint at `step`, into `path`.

    A BaseException, as KeyboardInterrupt is: a script's `except Exception:` around a run
    (to note a failed variant and go on) does not take Ctrl-C for a failure and go on."""

    def __init__(self, signum: int, step: int, path: Path):
        self.exit_code = 128 + signum
        self.step, self.path = step, Path(path)
        super().__init__(f"{signal.Signals(signum).name} at step {step}: checkpoint {path} written")


class Unfinished(BaseException):
    """The run stopped on a signal after its last step, before what it writes then (a
    comparison, figures) was written: its trajectories and restart are whole. A
    BaseException, as `Interrupted` is."""

    def __init__(self, signum: int, what: str):
        self.exit_code = 128 + signum
        super().__init__(f"{signal.Signals(signum).name} after the last step, before {what}")


class Checkpoints:
    """The checkpoint policy of one run: its file, its interval, the signal it was sent, and
    the `Stepper` that signal stops."""

    def __init__(self, path: Path, interval: float):
        self.path = Path(path)
        self.interval = interval
        self.signal = 0  # the signal that asked for a checkpoint and a stop
        self.saved = time.monotonic()
        self.stepper = Stepper()
        self.finishing = ""  # once stepped to the end: what the run writes after

    def finish(self, what: str) -> None:
        """The run has taken its last step and writes `what` (its comparison, its figures):
        in the main thread, where Python runs the handler, a signal now stops it at once, as
        `Unfinished` (one already taken too); off it (a sweep's variant, which its stop file
        stops) the run writes them and ends."""
        if threading.current_thread() is not threading.main_thread():
            return
        self.finishing = what
        if self.signal:
            raise Unfinished(self.signal, what)

    def due(self) -> bool:
        return self.signal != 0 or time.monotonic() - self.saved >= self.interval

    def save(self, restart: Restart) -> None:
        """Write the checkpoint; raise Interrupted after it if a signal asked for one."""
        write_restart(self.path, restart)
        self.saved = time.monotonic()
        if self.signal:
            raise Interrupted(self.signal, restart.state.step, self.path)

    def discard(self) -> None:
        self.path.unlink(missing_ok=True)

    def ask(self, signum: int) -> None:
        """A signal asks for a checkpoint and a stop: the stage loop halts at its next step."""
        self.signal = signum
        self.stepper.halt[0] = 1

    @contextmanager
    def on_signals(self, stop_file: Path | None = None) -> Iterator[None]:
        """While inside: SIGINT and SIGTERM ask for a checkpoint at the next whole step and a
        stop (a second one stops at once). Only the main thread can take signals; it runs
        their Python handler between bytecodes, not while it steps in compiled code, so a
        watcher thread takes each from the wakeup pipe as the signal arrives (`watching`).
        In another thread (a sweep's variant on a dask worker) `stop_file`, once it exists,
        asks as the signal it names would (`polling`)."""
        if threading.current_thread() is not threading.main_thread():
            with polling(stop_file, self.ask):
                yield
            return
        with first_signal(self._taken), watching(SIGNALS, self.ask):
            yield

    def _taken(self, signum: int) -> None:
        """A signal taken by Python's handler: a stop asked, and after the last step the run
        stopped at once."""
        self.ask(signum)
        if self.finishing:
            raise Unfinished(signum, self.finishing)


SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a run, or a sweep, with a checkpoint."""


SAME_SIGNAL = 1.0
"""Seconds within which a second signal is the first one delivered again, not a second
request: GNU `timeout` signals its child, then its whole process group (the child again),
and a terminal's Ctrl-C reaches every process of the foreground group."""


@contextmanager
def first_signal(act) -> Iterator[None]:
    """While inside, in the main thread (the only one Python gives signals to): the first
    of SIGNALS calls `act(signum)`, which may raise; one more than SAME_SIGNAL seconds later
    puts back the handlers there were and does what they did (stops at once); nothing
    elsewhere."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {kind: signal.getsignal(kind) for kind in SIGNALS}
    first: list[float] = []  # when the first signal came

    def handler(signum, frame):
        if not first:
            first.append(time.monotonic())
            act(signum)
        elif time.monotonic() - first[0] > SAME_SIGNAL:
            for kind in SIGNALS:
                signal.signal(kind, before[kind])
            signal.raise_signal(signum)

    for kind in SIGNALS:
        signal.signal(kind, handler)
    try:
        yield
    finally:
        for kind in SIGNALS:
            signal.signal(kind, before[kind])


_DONE = b"\0"  # no signal is numbered 0: what ends the watcher


@contextmanager
def watching(kinds: tuple[int, ...], ask) -> Iterator[None]:
    """While inside: `ask(signum)` as soon as one of the signals `kinds` arrives, from a
    thread of its own that reads the byte Python's C-level handler writes for it to a pipe
    (`signal.set_wakeup_fd`: whichever thread the signal interrupts, and while the main
    thread is in compiled code that released the GIL). Call from the main thread."""
    read, write = os.pipe()
    os.set_blocking(write, False)
    previous = signal.set_wakeup_fd(write, warn_on_full_buffer=False)

    def watch():
        while (byte := os.read(read, 1)) != _DONE:
            if byte[0] in kinds:
                ask(byte[0])

    watcher = threading.Thread(target=watch, name="revdem-signals", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        signal.set_wakeup_fd(previous)
        os.set_blocking(write, True)
        os.write(write, _DONE)
        watcher.join()
        os.close(read)
        os.close(write)


STOP_POLL = 0.05
"""Seconds between two looks for a stop file: a variant stops within about this of it."""


def ask_to_stop(path: Path, signum: int) -> None:
    """Write the stop file at `path` (its folder made if need be): the runs polling it stop
    as on signal `signum`."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_text(path, f"{signum}\n")


def stop_asked(path: Path | None) -> int:
    """The signal the stop file at `path` names; 0 if there is none."""
    try:
        return int(Path(path).read_text()) if path is not None else 0
    except FileNotFoundError:
        return 0


@contextmanager
def polling(path: Path | None, ask) -> Iterator[None]:
    """While inside: `ask(signum)` once the stop file at `path` appears (`ask_to_stop`),
    from a thread of its own that looks for it every STOP_POLL seconds; nothing if `path`
    is None."""
    if path is None:
        yield
        return
    done = threading.Event()

    def poll():
        while not done.wait(STOP_POLL):
            if signum := stop_asked(path):
                ask(signum)
                return

    poller = threading.Thread(target=poll, name="revdem-stop-file", daemon=True)
    poller.start()
    try:
        yield
    finally:
        done.set()
        poller.join()


def stopped_run(trajectory: Path, f) -> tuple[bool, Path | None]:
    """(whether the run that writes the trajectory `f`, the file `trajectory`, is
    unfinished; its checkpoint beside it, where there is one). It is where that checkpoint
    is there (the run stopped, or goes on) or where the file says its run did not reach its
    end (it failed, or was stopped at once, and left none); not where it ended, or where a
    file written before trajectories said so does not say and has no checkpoint beside it.
    `revdem info` and `revdem compare` each say so, in the same words (`unfinished_words`)."""
    from revdem_cli.io import stored_scenario
    from revdem_cli.io.h5md import ended

    trajectory = Path(trajectory)
    name = stored_scenario(f["parameters/revdem"].attrs["scenario_json"], trajectory).name
    checkpoint = checkpoint_path(trajectory.parent, name)
    if checkpoint.exists():
        return True, checkpoint
    return ended(f) is False, None


def unfinished_words(trajectory: Path, checkpoint: Path | None) -> str:
    """How the run of `trajectory` is unfinished, where `stopped_run` finds it is, in words."""
    if checkpoint is not None:
        return (
            f"{checkpoint} is beside it (the run stopped, or goes on); continue with revdem run "
            f"--resume {Path(trajectory).parent}"
        )
    return (
        "its run did not reach its end and left no checkpoint (it failed, or was stopped at once)"
    )


def find_checkpoints(out_dir: Path) -> list[Path]:
    """The checkpoints in `out_dir`, by name."""
    return sorted(Path(out_dir).glob(f"*{SUFFIX}"))


def find_checkpoint(out_dir: Path) -> Path:
    """The one checkpoint in `out_dir`; InputError if there is none or more than one."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        what = "a file, not the folder of a run" if out_dir.exists() else "no such directory"
        raise InputError(f"--resume {out_dir}: {what}")
    found = find_checkpoints(out_dir)
    if not found:
        raise InputError(
            f"--resume {out_dir}: no checkpoint (*{SUFFIX}) there: the run finished, or "
            "stopped before its first checkpoint"
        )
    if len(found) > 1:
        names = ", ".join(path.name for path in found)
        raise InputError(f"--resume {out_dir}: several checkpoints ({names}); keep one")
    return found[0]
