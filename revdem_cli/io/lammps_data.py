"""LAMMPS data files of `atom_style sphere` in `units si`, read and written.

Read (`read_lammps_data`): the header's counts and box, the `Atoms # sphere` section (id,
type, diameter, density, x, y, z, and the image flags where present) and the `Velocities`
section (id, vx, vy, vz, ωx, ωy, ωz) where there is one; other sections (Pair Coeffs, ...)
are passed over. Atoms are taken in the order of their ids. A data file does not say which
axes are periodic (that is the input script's `boundary`): the scenario says it.

Written (`write_lammps_data`): a state as LAMMPS' `write_data` writes it, every number with
17 significant digits, so that reading it back gives the same float64 numbers bit for bit.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from revdem_cli.errors import InputError, check_regular


@dataclass(frozen=True)
class LammpsData:
    """The spheres of a data file, in the order of their ids."""

    path: Path
    lower: np.ndarray  # xlo, ylo, zlo, m, (3,)
    upper: np.ndarray  # xhi, yhi, zhi, m, (3,)
    id: np.ndarray  # (N,) int64
    type: np.ndarray  # (N,) int64
    radius: np.ndarray  # m, (N,)
    density: np.ndarray  # kg/m^3, (N,)
    position: np.ndarray  # m, (N, 3), as the file gives it (LAMMPS: inside the box)
    image: np.ndarray  # image flags, the box crossings of each atom, (N, 3) int64
    velocity: np.ndarray  # m/s, (N, 3); zero without a Velocities section
    angular_velocity: np.ndarray  # rad/s, (N, 3); zero without a Velocities section

    def __len__(self) -> int:
        return len(self.id)

    @property
    def unwrapped(self) -> np.ndarray:
        """Positions unwrapped by the image flags, m, (N, 3)."""
        return self.position + self.image * (self.upper - self.lower)


_SECTION = re.compile(r"^[A-Za-z]")

READ = ("Atoms", "Velocities")
"""The sections of a data file whose numbers revdem takes."""
SET_ASIDE = ("Pair Coeffs", "PairIJ Coeffs")
"""Sections that LAMMPS' `write_data` writes beside them and revdem sets aside: a contact's
coefficients come from the scenario's [materials] and [contact]. Any other section (Bonds,
Masses, Ellipsoids, a keyword misspelt) is refused, as LAMMPS refuses a keyword it does not
know: its numbers would be lost without a word."""
_UNITS = re.compile(r"units\s*=\s*(\w+)")


def _fail(path: Path, line: int | None, what: str) -> InputError:
    """The one line that names the data file, its line where known, and what is wrong."""
    where = f" line {line}:" if line is not None else ""
    return InputError(f"{path}:{where} {what}")


def _numbers(path: Path, number: int, words: list[str], count: int, what: str) -> list[float]:
    if len(words) < count:
        raise _fail(path, number, f"{what} needs {count} numbers, found {len(words)}")
    try:
        return [float(w) for w in words[:count]]
    except ValueError:
        raise _fail(
            path, number, f"{what}: '{' '.join(words[:count])}' are not all numbers"
        ) from None


def _lines(path: Path) -> list[str]:
    check_regular(path, "LAMMPS data file")
    try:
        return path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not a text file"
        raise InputError(f"{path}: cannot read LAMMPS data file ({reason})") from None


def read_header(path: str | Path) -> tuple[int, np.ndarray, np.ndarray]:
    """(atoms, lower corner, upper corner) from the header of a data file."""
    header = _header(Path(path), _lines(Path(path)))
    return header[0], header[1], header[2]


def _header(path: Path, lines: list[str]) -> tuple[int, np.ndarray, np.ndarray, int]:
    """(atoms, lower, upper, index of the first section line)."""
    units = _UNITS.search(lines[0]) if lines else None
    if units and units.group(1) != "si":
        raise _fail(path, 1, f"written in units {units.group(1)}; revdem reads units si")
    atoms, lower, upper = None, [None] * 3, [None] * 3
    k = 1
    while k < len(lines):
        text = lines[k].split("#")[0].strip()
        if text and _SECTION.match(text):
            break
        words = text.split()
        if words[-2:] in (["xlo", "xhi"], ["ylo", "yhi"], ["zlo", "zhi"]):
            axis = "xyz".index(words[-1][0])
            lower[axis], upper[axis] = _numbers(path, k + 1, words, 2, f"{words[-2]} {words[-1]}")
        elif words[-1:] == ["atoms"]:
            atoms = int(_numbers(path, k + 1, words, 1, "atoms")[0])
        elif words[-3:] == ["xy", "xz", "yz"]:
            raise _fail(path, k + 1, "a triclinic box; revdem's boxes are orthogonal")
        k += 1
    if atoms is None or atoms < 1:
        raise _fail(path, None, "no atoms in the header ('N atoms')")
    if None in lower:
        raise _fail(path, None, "the header does not give the box (xlo xhi, ylo yhi, zlo zhi)")
    lower, upper = np.array(lower, dtype=np.float64), np.array(upper, dtype=np.float64)
    if not np.all(np.isfinite(lower) & np.isfinite(upper) & (upper > lower)):
        raise _fail(path, None, f"the box {lower.tolist()} to {upper.tolist()} is not a box")
    return atoms, lower, upper, k


def _sections(path: Path, lines: list[str], start: int) -> dict[str, list[tuple[int, list]]]:
    """Each section's keyword line (without its comment) and its data lines with numbers."""
    sections: dict[str, list[tuple[int, list]]] = {}
    rows = None
    for k in range(start, len(lines)):
        text = lines[k].split("#")[0].strip()
        if not text:
            continue
        if _SECTION.match(text):
            if text not in READ + SET_ASIDE:
                meant = [name for name in READ if name.lower() == text.lower()]
                hint = f" (did you mean {meant[0]}?)" if meant else ""
                raise _fail(
                    path, k + 1, f"section '{text}'{hint}: revdem reads the {' and '.join(READ)} "
                    f"of atom_style sphere, and sets aside {' and '.join(SET_ASIDE)}",
                )  # fmt: skip
            if text in sections:
                raise _fail(path, k + 1, f"a second {text} section")
            rows = sections.setdefault(text, [])
            if text == "Atoms":
                style = lines[k].partition("#")[2].strip()
                if style and style != "sphere":
                    raise _fail(path, k + 1, f"atom_style {style}; revdem reads atom_style sphere")
            continue
        rows.append((k + 1, text.split()))
    return sections


def read_lammps_data(path: str | Path) -> LammpsData:
    """The spheres of a LAMMPS data file; InputError naming the file and line of the first
    thing that is not a sphere revdem can run."""
    path = Path(path)
    lines = _lines(path)
    atoms, lower, upper, start = _header(path, lines)
    sections = _sections(path, lines, start)
    rows = sections.get("Atoms")
    if not rows:
        raise _fail(path, None, "no Atoms section")
    if len(rows) != atoms:
        raise _fail(path, None, f"the header gives {atoms} atoms, the Atoms section {len(rows)}")
    table = np.zeros((atoms, 10))
    for row, (number, words) in enumerate(rows):
        count = 10 if len(words) >= 10 else 7
        table[row, :count] = _numbers(path, number, words, count, "an atom (id type diameter "
                                      "density x y z [ix iy iz])")  # fmt: skip
    ids = table[:, 0].astype(np.int64)
    odd = np.flatnonzero((ids != table[:, 0]) | (ids < 1))
    if len(odd):  # LAMMPS numbers atoms from 1
        number, words = rows[odd[0]]
        raise _fail(path, number, f"atom id {words[0]} is not a positive integer")
    order = np.argsort(ids, kind="stable")
    table, ids = table[order], ids[order]
    if np.any(np.diff(ids) == 0):
        raise _fail(
            path, None, f"atom id {ids[np.flatnonzero(np.diff(ids) == 0)[0]]} is given twice"
        )
    bad = ~np.isfinite(table[:, 2:7]).all(axis=1) | (table[:, 2] <= 0) | (table[:, 3] <= 0)
    if bad.any():
        number = rows[order[np.flatnonzero(bad)[0]]][0]
        raise _fail(path, number, "an atom needs a positive diameter and density and a finite "
                    "position (atom_style sphere: id type diameter density x y z)")  # fmt: skip
    velocity = np.zeros((atoms, 6))
    moving = sections.get("Velocities", [])
    if moving:
        if len(moving) != atoms:
            raise _fail(path, None, f"{atoms} atoms but {len(moving)} velocities")
        where = {atom: row for row, atom in enumerate(ids)}
        given = set()
        for number, words in moving:
            values = _numbers(path, number, words, 7, "a velocity (id vx vy vz wx wy wz)")
            atom = int(values[0])
            if atom not in where:
                raise _fail(path, number, f"a velocity of atom {atom}, which is not there")
            if atom in given:  # another atom's is then missing
                raise _fail(path, number, f"a second velocity of atom {atom}")
            given.add(atom)
            velocity[where[atom]] = values[1:]
    return LammpsData(
        path=path,
        lower=lower,
        upper=upper,
        id=ids,
        type=table[:, 1].astype(np.int64),
        radius=0.5 * table[:, 2],
        density=table[:, 3],
        position=table[:, 4:7].copy(),
        image=table[:, 7:10].astype(np.int64),
        velocity=velocity[:, :3].copy(),
        angular_velocity=velocity[:, 3:].copy(),
    )


def wrapped(position: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(positions in the periodic box [0, L), image flags): position = wrapped + image L to
    round-off. A position that rounds onto the upper face is put on the lower one."""
    image = np.floor(position / edges)
    inside = position - image * edges
    onto_upper = inside >= edges
    inside[onto_upper] -= edges[np.nonzero(onto_upper)[1]]
    image[onto_upper] += 1
    return inside, image.astype(np.int64)


def lammps_data_text(
    ids, radius, mass, position, image, velocity, angular_velocity, types, lower, upper,
    step: int, title: str,
) -> str:  # fmt: skip
    """The text of a data file as `write_data` writes it for atom_style sphere, units si,
    the atoms in the given order with their ids, density = mass / (4/3 π r³) (Hanley 2020
    §3: solid spheres)."""
    n = len(radius)
    density = np.asarray(mass) / (4.0 / 3.0 * math.pi * np.asarray(radius) ** 3)
    out = [f"LAMMPS data file via revdem, {title}, timestep = {step}, units = si", ""]
    out += [f"{n} atoms", f"{int(np.max(types))} atom types", ""]
    for axis, (lo, hi) in enumerate(zip(lower, upper, strict=True)):
        name = "xyz"[axis]
        out.append(f"{lo:.17g} {hi:.17g} {name}lo {name}hi")
    out += ["", "Atoms # sphere", ""]
    out += [
        f"{k} {t} {2.0 * r:.17g} {d:.17g} {x[0]:.17g} {x[1]:.17g} {x[2]:.17g} {i[0]} {i[1]} {i[2]}"
        for k, t, r, d, x, i in zip(ids, types, radius, density, position, image, strict=True)
    ]
    out += ["", "Velocities", ""]
    out += [
        f"{k} " + " ".join(f"{c:.17g}" for c in (*v, *w))
        for k, v, w in zip(ids, velocity, angular_velocity, strict=True)
    ]
    return "\n".join(out) + "\n"
