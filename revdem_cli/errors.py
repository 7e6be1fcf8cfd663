"""Errors that the command line turns into one clear line: bad input (exit status 2), and
a run that cannot go on (exit status 1)."""


class InputError(Exception):
    """Bad input from the user: a scenario field, a file, a command-line value.

    The message must name what is wrong and where (field path, file, step, particle).
    """


class RunFailed(RuntimeError):
    """A run that cannot go on: its state blew up, or left what revdem can represent. The
    message names the step, the particles and what to change."""


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
