"""Registries of records found by name: the modules of a package, each a law or a shape."""

from __future__ import annotations

import importlib
import pkgutil


def modules(package: str, path) -> list:
    """The modules of a package (`__name__`, `__path__`), in the order of their file names."""
    found = sorted(pkgutil.iter_modules(path), key=lambda info: info.name)
    return [importlib.import_module(f"{package}.{info.name}") for info in found]


def check(module, what: str, names) -> None:
    """ImportError naming what a record module lacks of `names`: a half-added record never
    loads, so it never runs as something else."""
    missing = [name for name in names if not hasattr(module, name)]
    if missing:
        raise ImportError(f"{module.__name__}: {what} defines {', '.join(missing)}")
