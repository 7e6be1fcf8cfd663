"""One revdem process at a time writes into a folder: a run (`revdem run`, `run --resume`,
`revdem reverse`), a sweep, or one of a sweep's variants in its own folder under the sweep's.

Two runs writing into one folder at once replace and remove each other's files, and a check
of what is there, made before either writes anything, lets both through: so each holds an
exclusive lock of the folder's LOCK_FILE while it reads and writes there (`sole_writer`),
taken before it looks at what is there. The lock is the system's (flock): a process that
ends, even killed with SIGKILL, holds it no more, so a LOCK_FILE left behind blocks nothing.
A lock is of one folder, not of those inside it: a sweep holds its own folder, each variant
the folder it runs in.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from revdem_cli.errors import InputError


class FolderHeld(InputError):
    """Another revdem process writes into the folder: the files there are that process's."""


LOCK_FILE = ".lock"
"""In a folder while a revdem process writes there, locked by it (`sole_writer`)."""


@contextmanager
def sole_writer(folder: Path, where: str | None = None) -> Iterator[None]:
    """While inside, this process is the only revdem process writing into `folder` (made if
    need be): it holds an exclusive lock of its LOCK_FILE, which it removes as it leaves.
    FolderHeld, before anything there is read or written, if another holds it, naming the
    folder as `where` (default: `--out FOLDER`). A folder made here and left empty (the
    process refused) is removed."""
    folder = Path(folder)
    made = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    lock = _locked(path, where or f"--out {folder}")
    try:
        yield
    finally:
        path.unlink(missing_ok=True)  # before the lock is let go: none locks it after
        os.close(lock)
        if made and not any(folder.iterdir()):
            folder.rmdir()


def _locked(path: Path, where: str) -> int:
    """A descriptor of the file at `path` (made if need be), locked exclusively; FolderHeld
    naming `where` if another process holds it. The file locked is the one still there, not
    one that a process leaving removed after this one opened it."""
    while True:
        lock = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(lock)
            raise FolderHeld(
                f"{where}: another revdem run holds it (it locks {path}); wait for it to end"
            ) from None
        try:
            if os.stat(path).st_ino == os.fstat(lock).st_ino:
                return lock
        except FileNotFoundError:
            pass
        os.close(lock)
