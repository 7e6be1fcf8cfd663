"""What the command line's options take, shared by `cli` and the commands in modules of
their own (`timestep.command`): an --out as the user gave it, and each option once."""

from __future__ import annotations

from pathlib import Path

import typer
from typer.core import TyperCommand


def _given(value: str, hint: str) -> str:
    """A path as given; an empty one is refused, not read as the current directory."""
    if not value.strip():
        raise typer.BadParameter(f"an empty path; {hint}")
    return value


def named_folder(value: str | Path) -> Path:
    """An --out that names a folder, as given (or its default)."""
    if isinstance(value, Path):
        return value
    return Path(_given(value, "give a directory (. for this one)"))


def file_to_read(value: str | Path) -> Path:
    """A file given to read (`dt --restart`), as given."""
    if isinstance(value, Path):
        return value
    return Path(_given(value, "name a file"))


def named_file(value: str | Path) -> str | Path:
    """An --out that names a file (or a folder, as `export --vtk`'s does), kept as the
    string given: Path drops a trailing separator, by which `io.refuse_overwriting` tells
    a folder named where a file is wanted."""
    if isinstance(value, Path):
        return value
    return _given(value, "name a file")


class OnceEach(TyperCommand):
    """A command whose options that take a value may each be given once: click keeps the last
    of a repeated one and drops the others, which would leave their user believing they
    counted. An option meant to be repeated (`--set`, click's `multiple`) may be."""

    def parse_args(self, ctx, args: list[str]) -> list[str]:
        from revdem_cli.errors import InputError

        _, _, order = self.make_parser(ctx).parse_args(args=list(args))
        for param in dict.fromkeys(order):
            times = order.count(param)
            repeatable = getattr(param, "is_flag", False) or getattr(param, "multiple", False)
            if times > 1 and not repeatable:
                raise InputError(
                    f"{ctx.info_name}: {param.opts[0]} is given {times} times; give it once"
                )
        return super().parse_args(ctx, args)
