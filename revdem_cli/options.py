"""What the command line's options take, shared by `cli` and the commands in modules of
their own (`timestep.command`): an --out as the user gave it."""

from __future__ import annotations

from pathlib import Path

import typer


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


def named_file(value: str | Path) -> str | Path:
    """An --out that names a file (or a folder, as `export --vtk`'s does), kept as the
    string given: Path drops a trailing separator, by which `io.refuse_overwriting` tells
    a folder named where a file is wanted."""
    if isinstance(value, Path):
        return value
    return _given(value, "name a file")
