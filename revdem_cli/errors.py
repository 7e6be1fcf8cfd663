"""Errors that the command line turns into one clear line and exit status 2."""


class InputError(Exception):
    """Bad input from the user: a scenario field, a file, a command-line value.

    The message must name what is wrong and where (field path, file, step, particle).
    """
