"""Errors that the command line turns into one clear line: bad input (exit status 2), and
a run that cannot go on (exit status 1)."""

import errno
import os
from numbers import Integral


class InputError(Exception):
    """Bad input from the user: a scenario field, a file, a command-line value.

    The message must name what is wrong and where (field path, file, step, particle).
    """


class RunFailed(RuntimeError):
    """A run that cannot go on: its state blew up, or left what revdem can represent. The
    message names the step, the particles and what to change."""


def whole_number(value) -> bool:
    """Whether `value` is an integer a count or an index may be (a numpy integer too; not a
    bool, not 2.5 or "5"), as a script may pass anything where an option takes an int."""
    return isinstance(value, Integral) and not isinstance(value, bool)


def given_options(ctx, names: tuple[str, ...] | None = None, beside: tuple[str, ...] = ()):
    """The options of the command of `ctx` (click's context) given on its command line, as
    the user spells them, in the order of its --help: of those named in `names` (None: all
    its options), less those in `beside`."""
    return [
        param.opts[0]
        for param in ctx.command.params
        if (names is None or param.name in names)
        and param.name not in beside
        and ctx.get_parameter_source(param.name).name != "DEFAULT"
    ]


def check_regular(path, what: str) -> None:
    """InputError if `path` exists but is not a regular file: a FIFO or a device would block
    a reader for ever, waiting for a writer."""
    import stat
    from pathlib import Path

    try:
        mode = Path(path).stat().st_mode
    except OSError:
        return  # missing or unreadable: the reader says so
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        raise InputError(
            f"{path}: cannot read {what} (not a regular file: a FIFO, socket or device)"
        )


class WriteFailed(RunFailed):
    """A file could not be written (a full disk, a file-size limit, a lost mount): the
    message names the file and why."""

    def __init__(self, path, exc: BaseException):
        super().__init__(f"cannot write {path}: {why_not_written(exc)}")


def why_not_written(exc: BaseException) -> str:
    """The reason of a failed write in a few words: the system's for its errno (HDF5 puts it
    in its message), else the message itself."""
    import re

    number = getattr(exc, "errno", None)
    if not isinstance(number, int):
        found = re.search(r"errno = (\d+)", str(exc))
        number = int(found[1]) if found else None
    if number:
        return f"{os.strerror(number)} (errno {number})"
    return " ".join(str(exc).split())[:200] or type(exc).__name__


PATH_ERRORS = frozenset(
    {errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENOENT, errno.EACCES, errno.EPERM,
     errno.EROFS, errno.ENAMETOOLONG}
)  # fmt: skip
"""The errnos of a path the user gave that cannot be used as given (`path_problem`), as
opposed to a failure of the machine (a full disk, a lost mount)."""


def not_a_folder(path) -> str | None:
    """Why a folder cannot be at `path`, or be made there: a file there, or at a folder
    above it, named in one line; None if nothing is in the way."""
    from pathlib import Path

    path = Path(path)
    blocking = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), None)
    if blocking == path:
        return f"{path}: a file, not a folder"
    if blocking is not None:
        return f"{path}: {blocking} is a file, not a folder"
    return None


def path_problem(exc: OSError) -> str | None:
    """What is wrong with the path an OSError names, in one line that says where: a file
    where a folder is needed (the path itself or one above it), a folder where a file is,
    or the system's reason; None where it names no path or the error is not the path's."""
    from pathlib import Path

    if exc.filename is None or exc.errno not in PATH_ERRORS:
        return None
    path = Path(exc.filename)
    if exc.errno in (errno.ENOTDIR, errno.EEXIST) and (problem := not_a_folder(path)):
        return problem
    if exc.errno == errno.EISDIR:
        return f"{path}: a folder, not a file"
    return f"{path}: {os.strerror(exc.errno)}"
