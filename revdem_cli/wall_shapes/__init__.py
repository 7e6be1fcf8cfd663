"""Wall shapes as records: one module a shape, found by its name, as contact laws are
(`revdem_cli.laws`).

A shape module names itself (NAME), says in SUMMARY what its `point` and `normal` mean and
in SIDE where spheres must start, and holds FIELDS, its own [[walls]] fields beyond the
common ones (pydantic fields, units in their descriptions; those in REQUIRED must be given,
and no other shape's may be), `overlap`, compiled: (overlap, unit normal from the sphere
towards the wall) of a sphere at x of radius r, from the wall's point, unit axis and
radius (Walls.radius, 0 for shapes without one); and `reach_past`, in numpy: how far each of
the spheres (x, r) reaches past a wall at the start, m.

Shapes are numbered from 1 in the order of their names (Walls.kind); numbers never leave a
process.
"""

from __future__ import annotations

from revdem_cli import registry

CARRIED = ("radius",)
"""The fields of its own a shape's compiled `overlap` is given (`Walls.radius`): a shape with
another needs a column of `Walls` for it (`kernels/arrays.py`, `state.wall_arrays`)."""


def _discover() -> dict[str, object]:
    found = {}
    for module in registry.modules(__name__, __path__):
        names = ("NAME", "SUMMARY", "SIDE", "FIELDS", "REQUIRED", "overlap", "reach_past")
        registry.enter(found, module, "a wall shape", names)
        check_carried(module)
    return found


def check_carried(module) -> None:
    """ImportError where a shape has a field its compiled `overlap` is never given (CARRIED),
    which it would read as 0 without a word."""
    lost = [name for name in module.FIELDS if name not in CARRIED]
    if lost:
        raise ImportError(
            f"{module.__name__}: the field {', '.join(lost)} never reaches the compiled "
            f"overlap, which is given {', '.join(CARRIED)} alone (wall_shapes.CARRIED)"
        )


SHAPES = _discover()
"""Shape modules by name, in the order of their numbers."""


def number(name: str) -> int:
    """The number of a shape (Walls.kind)."""
    return 1 + list(SHAPES).index(name)


def fields() -> dict[str, object]:
    """Every shape's own [[walls]] fields, by name."""
    return {name: info for shape in SHAPES.values() for name, info in shape.FIELDS.items()}


def overlap():
    """One compiled function, f(number, point, axis, radius, x, r), calling the `overlap` of
    the shape it is given by number (`kernels.choice`)."""
    from revdem_cli.kernels import choice

    return choice([shape.overlap for shape in SHAPES.values()], "wall_overlap")
