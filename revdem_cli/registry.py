"""Registries of records found by name: the modules of a package, each a law or a shape."""

from __future__ import annotations

import importlib
import pkgutil


def modules(package: str, path) -> list:
    """The modules of a package (`__name__`, `__path__`), in the order of their file names."""
    found = sorted(pkgutil.iter_modules(path), key=lambda info: info.name)
    return [importlib.import_module(f"{package}.{info.name}") for info in found]


def enter(found: dict, module, what: str, names) -> None:
    """found[module.NAME] = module, once it holds all of `names`, each of its REQUIRED fields
    is one of its FIELDS and no module entered before took its NAME; else ImportError naming
    what is wrong: a half-added record never loads, so it never runs as something else."""
    missing = [name for name in names if not hasattr(module, name)]
    if missing:
        raise ImportError(f"{module.__name__}: {what} must define {', '.join(missing)}")
    unknown = [name for name in module.REQUIRED if name not in module.FIELDS]
    if unknown:
        raise ImportError(
            f"{module.__name__}: REQUIRED names {', '.join(unknown)}, which its FIELDS lack"
        )
    if module.NAME in found:
        raise ImportError(
            f"{module.__name__}: {what} named '{module.NAME}', as {found[module.NAME].__name__} is"
        )
    found[module.NAME] = module
