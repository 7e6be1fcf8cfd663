"""Errors that the command line turns into one clear line: bad input (exit status 2), and
a run that cannot go on (exit status 1)."""


class InputError(Exception):
    """Bad input from the user: a scenario field, a file, a command-line value.

    The message must name what is wrong and where (field path, file, step, particle).
    """


class RunFailed(RuntimeError):
    """A run that cannot go on: its state blew up, or left what revdem can represent. The
    message names the step, the particles and what to change."""
