"""Contact laws as records: a contact is made of one law from each family, each law one
module of this package, found by its name (as LAMMPS' GRANULAR package composes a contact of
normal, damping, tangential, rolling and twisting sub-models, but compiled).

A law module names its FAMILY and NAME, the EQUATION it implements, a one-line SUMMARY for
the scenario schema, and FIELDS: its coefficients in the scenario's [contact] table
(pydantic fields with a unit in each description; those in REQUIRED must be given when the
law is chosen, and none may be given when it is not). Each field is also a compiled
parameter of the law, a field of the compiled record `kernels.arrays.ContactLaw` (0 when not
given). It then defines the functions its family asks for (FAMILIES below): compiled helpers
over the record, scalars and 3-tuples, which `kernels.contact` calls through `dispatch`, and
Python ones.

Laws are numbered within their family from 1 in the order of their names; 0 is NONE, no law
of that family. Numbers never leave a process (files store the names).
"""

from __future__ import annotations

from dataclasses import dataclass

from revdem_cli import registry

NONE = 0
"""The number of 'no law' in a family that may be left out."""


@dataclass(frozen=True)
class Family:
    selector: str  # the [contact] field that names the law
    optional: bool  # whether 'none' may be chosen (the default then)
    functions: tuple[str, ...]  # the compiled functions each of its laws defines
    python: tuple[str, ...] = ()  # the Python functions each of its laws defines


FAMILIES = {
    "normal": Family(
        "model",
        optional=False,
        functions=("force",),  # (elastic force, its stiffness dF/dd, stored energy)
        # the overlap whose stored energy is a given energy; whether the stiffness comes from
        # the materials' elastic moduli (then the Rayleigh time step bounds it)
        python=("impact_overlap", "FROM_MATERIALS"),
    ),
    "tangential": Family("tangential", optional=True, functions=("stiffness",)),  # k_s
    "rolling": Family(
        "rolling", optional=True, functions=("stiffness", "limit")
    ),  # k_r, and the largest moment
}


def _discover() -> dict[str, dict[str, object]]:
    """Every law module of this package, by family and name."""
    found: dict[str, dict[str, object]] = {family: {} for family in FAMILIES}
    for module in registry.modules(__name__, __path__):
        family = FAMILIES.get(getattr(module, "FAMILY", None))
        if family is None:
            raise ImportError(f"{module.__name__}: FAMILY must be one of {', '.join(FAMILIES)}")
        names = ("NAME", "EQUATION", "SUMMARY", "FIELDS", "REQUIRED")
        what = f"a {module.FAMILY} law"
        registry.enter(found[module.FAMILY], module, what, names + family.functions + family.python)
    return found


LAWS = _discover()
"""Law modules by family and name, in the order of their numbers."""


def number(family: str, name: str) -> int:
    """The number of a law in its family ('none': NONE)."""
    if name == "none" and FAMILIES[family].optional:
        return NONE
    return 1 + list(LAWS[family]).index(name)


def fields() -> dict[str, object]:
    """Every law's [contact] fields, by name; a field two laws share is given once."""
    return {
        name: info
        for laws in LAWS.values()
        for law in laws.values()
        for name, info in law.FIELDS.items()
    }


def owners(field: str) -> list[tuple[str, str]]:
    """(family, name) of every law that takes a [contact] field."""
    return [
        (family, name)
        for family, found in LAWS.items()
        for name, law in found.items()
        if field in law.FIELDS
    ]


PARAMETERS = tuple(sorted(fields()))
"""Every law's coefficients, by field name: the compiled record ContactLaw ends with them."""


def parameters(contact) -> tuple[float, ...]:
    """The values of PARAMETERS in a validated [contact] table, 0 where not given."""
    return tuple(float(getattr(contact, name) or 0.0) for name in PARAMETERS)


def chosen(contact, family: str):
    """The module of the law of `family` that a validated [contact] table chooses, or None."""
    name = getattr(contact, FAMILIES[family].selector)
    return None if name == "none" else LAWS[family][name]


def evaluate(contact, family: str, function: str, *args):
    """A function of the law of `family` that a validated [contact] table chooses, outside
    the kernels (the Python form of a compiled one): the grids of fixed-point arithmetic, the
    time-step guard."""
    law = getattr(chosen(contact, family), function)
    return getattr(law, "py_func", law)(contact, *args)  # it reads its own fields only


def dispatch(family: str, function: str):
    """One compiled function that calls `function` of the law of `family` it is given by
    number, f(number, *args), built from the laws found (`kernels.choice`), so that a new law
    needs no line here."""
    from revdem_cli.kernels import choice

    laws = LAWS[family].values()
    return choice([getattr(law, function) for law in laws], f"{family}_{function}")
