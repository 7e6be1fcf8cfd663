"""A trajectory's frames in the formats particle viewers and other codes read: GSD
(HOOMD-blue's, which OVITO reads with radii and the box), LAMMPS text dumps (`dump custom`,
which OVITO, VMD and LAMMPS' own tools read) and a LAMMPS data file of the last frame
(`read_data`, to continue the run in LAMMPS or LIGGGHTS).

Each takes the frames of a revdem H5MD trajectory as they are: each sphere's id, type (its
material, numbered from 1 in the order of [materials]), radius, position and velocity, and
the box at each frame, the periodic cell [0, L) where the run had one, else the spheres'
bounding box over the frames exported (open boundaries): one box for every frame, so that
a viewer's positions relative to it (GSD's, from its centre) keep their displacements.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from revdem_cli.errors import InputError
from revdem_cli.io import FRAME_FIELDS
from revdem_cli.io.h5md import (
    frame_steps,
    frames_per_block,
    open_trajectory,
    read_contacts,
    read_frames,
)


@dataclass(frozen=True)
class Frame:
    step: int
    time: float
    lower: np.ndarray  # lower corner of the box, m, (3,)
    upper: np.ndarray  # upper corner, m, (3,)
    periodic: bool
    id: np.ndarray  # (N,)
    type: np.ndarray  # the material, numbered from 1, (N,)
    radius: np.ndarray  # m, (N,)
    mass: np.ndarray  # kg, (N,)
    # the per-sphere values (None where the format does not write them: `frames`' `writes`)
    position: np.ndarray | None  # m, (N, 3)
    velocity: np.ndarray | None  # m/s, (N, 3)
    angular_velocity: np.ndarray | None  # rad/s, (N, 3)
    force: np.ndarray | None  # N, (N, 3)
    contacts: dict[str, np.ndarray] | None  # the frame's contact list, if the run wrote it
    # and the format writes it


FrameProgress = Callable[[str, int, int], None]
"""progress(label, done, total), called as each frame is written (`report.progress`)."""


CONTACTS = "contacts"
"""What a format names, beside the per-sphere fields (`io.FRAME_FIELDS`), where it writes
the frames' contact lists."""

LAMMPS_DUMP_WRITES = ("position", "velocity")
"""What of a frame a LAMMPS dump writes, and `frames` reads for it (no forces, no spins)."""

GSD_WRITES = ("position", "velocity", CONTACTS)
"""What of a frame a GSD export writes: the contacts as bonds."""

LAMMPS_DATA_WRITES = ("position", "velocity", "angular_velocity")
"""What of its frame a LAMMPS data file writes: a sphere's spin, not the force on it."""


def frames(
    trajectory: str | Path,
    writes: tuple[str, ...],
    at_step: int | None = None,
    progress: FrameProgress | None = None,
) -> Iterator[Frame]:
    """The frames of a revdem trajectory (`at_step`: the one at that step alone; -1, its
    last), checked by `open_trajectory` first, and each frame's per-sphere values by
    `h5md.read_frames` (finite); `progress` told of each once its consumer has it done. InputError
    naming the steps it has where none is at `at_step`. Every export reads its frames
    here, and of them only what its format `writes` (per-sphere fields of
    `io.FRAME_FIELDS`, and `CONTACTS`): a value it does not write is neither read nor
    refused where damaged."""
    unknown = set(writes) - {*FRAME_FIELDS, CONTACTS}
    if unknown:
        raise ValueError(f"frames: no such part of a frame: {', '.join(sorted(unknown))}")
    with open_trajectory(trajectory) as f:
        particles = f["particles/all"]
        radius, mass, ids = particles["radius"][:], particles["mass"][:], particles["id"][:]
        species = particles["species"][:] if "species" in particles else np.zeros_like(ids)
        periodic = "periodic" in str(particles["box"].attrs["boundary"][0])
        times = particles["position/time"][:]
        steps = frame_steps(f)
        first, stop = 0, len(steps)
        if at_step is not None:
            first = len(steps) - 1 if at_step == -1 else _frame_at(steps, at_step, trajectory)
            stop = first + 1
        per_block = frames_per_block(len(radius))
        if periodic:
            edges = particles["box/edges/value"][:]
        else:
            lower, upper = _bounding_box(f, radius, range(first, stop))
        for start in range(first, stop, per_block):  # read a block of frames at once
            block = np.arange(start, min(stop, start + per_block))
            read = {name: read_frames(f, name, block) for name in FRAME_FIELDS if name in writes}
            for row, k in enumerate(block):
                if periodic:
                    lower, upper = np.zeros(3), edges[k]
                values = {name: read[name][row] if name in read else None for name in FRAME_FIELDS}
                contacts = read_contacts(f, k) if CONTACTS in writes else None
                yield Frame(int(steps[k]), float(times[k]), lower, upper, periodic, ids,
                            species + 1, radius, mass, **values, contacts=contacts)  # fmt: skip
                if progress is not None:  # of the frames exported: one alone, 1 of 1
                    progress(Path(trajectory).name, int(k) + 1 - first, stop - first)


def _frame_at(steps: np.ndarray, step: int, trajectory) -> int:
    """The index of the frame at `step`; InputError naming the steps there are where none."""
    found = np.flatnonzero(steps == step)
    if len(found):
        return int(found[0])
    shown = ", ".join(str(s) for s in steps[:3]) + (f", ..., {steps[-1]}" if len(steps) > 3 else "")
    raise InputError(
        f"--step {step}: {Path(trajectory).name} has no frame there; its frames are at steps "
        f"{shown}"
    )


def _bounding_box(f, radius: np.ndarray, exported: range) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) corners of the box that holds every sphere of the frames `exported` of
    the open trajectory `f`, m."""
    lower, upper = np.full(3, np.inf), np.full(3, -np.inf)
    per_block = frames_per_block(len(radius))
    for start in range(exported.start, exported.stop, per_block):
        block = read_frames(f, "position", np.arange(start, min(exported.stop, start + per_block)))
        lower = np.minimum(lower, (block - radius[:, None]).min(axis=(0, 1)))
        upper = np.maximum(upper, (block + radius[:, None]).max(axis=(0, 1)))
    return lower, upper


def export_lammps_dump(
    trajectory: str | Path, path: str | Path, progress: FrameProgress | None = None
) -> Path:
    """Every frame as a LAMMPS `dump custom` text file: ITEM: TIMESTEP, NUMBER OF ATOMS, BOX
    BOUNDS (pp on periodic axes, ff on open ones) and ATOMS id type radius x y z vx vy vz,
    in SI units, 17 significant digits (positions exactly as stored: in a periodic cell,
    where they are not wrapped into it, as LAMMPS' unwrapped xu yu zu)."""
    from revdem_cli.io import write_text

    path = Path(path)
    lines = []
    for frame in frames(trajectory, LAMMPS_DUMP_WRITES, progress=progress):
        bounds = "pp pp pp" if frame.periodic else "ff ff ff"
        lines += ["ITEM: TIMESTEP", str(frame.step), "ITEM: NUMBER OF ATOMS", str(len(frame.id))]
        lines += [f"ITEM: BOX BOUNDS {bounds}"]
        lines += [f"{lo:.17g} {hi:.17g}" for lo, hi in zip(frame.lower, frame.upper, strict=True)]
        xyz = "xu yu zu" if frame.periodic else "x y z"
        lines += [f"ITEM: ATOMS id type radius {xyz} vx vy vz"]
        table = np.column_stack([frame.radius, frame.position, frame.velocity])
        lines += [
            f"{i} {t} " + " ".join(f"{v:.17g}" for v in row)
            for i, t, row in zip(frame.id, frame.type, table, strict=True)
        ]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, "\n".join(lines) + "\n")
    return path


def _bonds(snapshot, contacts: dict[str, np.ndarray]) -> None:
    """The contacts between spheres as GSD bonds, one bond type, with each contact's normal
    force magnitude, forces, overlap and sliding as per-bond logged quantities."""
    pairs = contacts["value"][:, 1] >= 0
    snapshot.bonds.N = int(pairs.sum())
    snapshot.bonds.types = ["contact"]
    snapshot.bonds.typeid = np.zeros(snapshot.bonds.N, dtype=np.uint32)
    snapshot.bonds.group = contacts["value"][pairs].astype(np.uint32)
    normal = contacts["normal_force"][pairs]
    snapshot.log["bonds/normal_force_magnitude"] = np.sqrt((normal**2).sum(axis=1))
    for name in ("normal_force", "tangential_force", "overlap", "sliding"):
        snapshot.log[f"bonds/{name}"] = contacts[name][pairs]


GSD_IDS = "particles/Particle Identifier"
"""The GSD log chunk of the spheres' ids (under `log/`)."""


def export_gsd(
    trajectory: str | Path, path: str | Path, progress: FrameProgress | None = None
) -> Path:
    """Every frame as a GSD file (the `gsd` package, HOOMD schema): positions relative to
    the box's centre, in a periodic cell wrapped into it with image flags (`_gsd_box`; an
    open system's box twice its bounding box), diameters, masses,
    velocities, the box edges, the step, and each sphere's id, which the schema lacks, as the logged
    per-particle quantity `particles/Particle Identifier` (OVITO's name for ids, which it
    reads as that property, as from a LAMMPS dump). GSD stores float32: positions to about
    1e-7 of the box."""
    import gsd.hoomd

    from revdem_cli.errors import WriteFailed

    path = Path(path)
    with open_trajectory(trajectory) as f:  # checked before anything is written
        stored = json.loads(f["parameters/revdem"].attrs["scenario_json"])
    materials = list(stored["materials"])  # the types' names, in the order of their numbers
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with gsd.hoomd.open(tmp, "w") as out:
            for frame in frames(trajectory, GSD_WRITES, progress=progress):
                snapshot = gsd.hoomd.Frame()
                snapshot.configuration.step = frame.step
                edges, position, image = _gsd_box(frame)
                snapshot.configuration.box = [*edges, 0.0, 0.0, 0.0]
                snapshot.particles.N = len(frame.id)
                snapshot.particles.position = position
                snapshot.particles.image = image
                snapshot.particles.diameter = (2.0 * frame.radius).astype(np.float32)
                snapshot.particles.mass = frame.mass.astype(np.float32)
                snapshot.particles.velocity = frame.velocity.astype(np.float32)
                snapshot.particles.typeid = (frame.type - 1).astype(np.uint32)
                snapshot.particles.types = materials
                snapshot.log[GSD_IDS] = frame.id
                if frame.contacts is not None:
                    _bonds(snapshot, frame.contacts)
                out.append(snapshot)
        tmp.chmod(_file_mode())  # the gsd library makes its files rw-r-----
        tmp.replace(path)
    except OSError as exc:
        raise WriteFailed(path, exc) from None
    finally:  # a failed write, a frame refused or Ctrl-C leaves no temporary
        tmp.unlink(missing_ok=True)
    return path


def _file_mode() -> int:
    """The permissions a file written with Python's `open` gets here: rw for all, less the
    process's umask (read by setting it, then setting it back)."""
    import os

    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def _gsd_box(frame: Frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(box edges, float32 positions, image flags) of a frame in HOOMD's convention, whose
    boxes are periodic and centred on the origin and whose positions lie in [-L/2, L/2). A
    periodic cell's spheres are wrapped into it (`lammps_data.wrapped`), each crossing an
    image flag, so that position + image L is the unwrapped one. An open system's box is
    twice the spheres' bounding box about its centre: a viewer's periodic images of it then
    lie a bounding box apart, and no sphere finds a neighbour across its faces."""
    from revdem_cli.io.lammps_data import wrapped

    edges = frame.upper - frame.lower
    if not frame.periodic:
        centre = 0.5 * (frame.lower + frame.upper)
        image = np.zeros(frame.position.shape, dtype=np.int32)
        return 2.0 * edges, (frame.position - centre).astype(np.float32), image
    inside, image = wrapped(frame.position - frame.lower, edges)
    position = (inside - 0.5 * edges).astype(np.float32)
    half = (0.5 * edges).astype(np.float32)
    onto_upper = position >= half  # rounded onto the upper face in float32: the lower one
    position[onto_upper] -= (2.0 * half)[np.nonzero(onto_upper)[1]]
    image[onto_upper] += 1
    return edges, position, image.astype(np.int32)


def export_lammps_data(
    trajectory: str | Path,
    path: str | Path,
    progress: FrameProgress | None = None,
    step: int | None = None,
) -> Path:
    """The last frame (or the one at `step`) as a LAMMPS data file (atom_style sphere, units
    si, `read_data`): id, radius, density, position (in a periodic box wrapped into it, with
    image flags), velocity and angular velocity of every sphere, 17 significant digits, so
    that `[[particles_from]]` reads back the same numbers bit for bit, each under its id."""
    from revdem_cli.io import write_text
    from revdem_cli.io.lammps_data import lammps_data_text, wrapped

    (last,) = frames(trajectory, LAMMPS_DATA_WRITES, -1 if step is None else step, progress)
    position, image = last.position, np.zeros(last.position.shape, dtype=np.int64)
    if last.periodic:  # inside the box, with the crossings as image flags, as LAMMPS has them
        position, image = wrapped(last.position, last.upper)
    text = lammps_data_text(
        last.id, last.radius, last.mass, position, image, last.velocity,
        last.angular_velocity, last.type, last.lower, last.upper, last.step,
        f"{Path(trajectory).name} at step {last.step}",
    )  # fmt: skip
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, text)
    return path
