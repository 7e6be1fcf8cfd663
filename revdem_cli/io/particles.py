"""A trajectory's frames in the formats particle viewers read: GSD (HOOMD-blue's, which OVITO
reads with radii and the box) and LAMMPS text dumps (`dump custom`, which OVITO, VMD and
LAMMPS' own tools read).

Both take the frames of a revdem H5MD trajectory as they are: one particle type, its id,
radius, position and velocity, and the box at each frame, the periodic cell [0, L) where
the run had one, else the bounding box of the spheres (open boundaries).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from revdem_cli.io.h5md import frame_steps, open_trajectory, read_frame


@dataclass(frozen=True)
class Frame:
    step: int
    time: float
    lower: np.ndarray  # lower corner of the box, m, (3,)
    upper: np.ndarray  # upper corner, m, (3,)
    periodic: bool
    id: np.ndarray  # (N,)
    radius: np.ndarray  # m, (N,)
    position: np.ndarray  # m, (N, 3)
    velocity: np.ndarray  # m/s, (N, 3)


def frames(trajectory: str | Path) -> Iterator[Frame]:
    """The frames of a revdem trajectory, checked by `open_trajectory` first."""
    with open_trajectory(trajectory) as f:
        particles = f["particles/all"]
        radius, ids = particles["radius"][:], particles["id"][:]
        periodic = "periodic" in str(particles["box"].attrs["boundary"][0])
        times = particles["position/time"][:]
        for k, step in enumerate(frame_steps(f)):
            position = read_frame(f, "position", k)
            if periodic:
                lower, upper = np.zeros(3), particles["box/edges/value"][k]
            else:
                lower = (position - radius[:, None]).min(axis=0)
                upper = (position + radius[:, None]).max(axis=0)
            velocity = read_frame(f, "velocity", k)
            yield Frame(int(step), float(times[k]), lower, upper, periodic, ids, radius,
                        position, velocity)  # fmt: skip


def export_lammps_dump(trajectory: str | Path, path: str | Path) -> Path:
    """Every frame as a LAMMPS `dump custom` text file: ITEM: TIMESTEP, NUMBER OF ATOMS, BOX
    BOUNDS (pp on periodic axes, ff on open ones) and ATOMS id type radius x y z vx vy vz,
    in SI units, 17 significant digits (positions exactly as stored)."""
    from revdem_cli.io import write_text

    path = Path(path)
    lines = []
    for frame in frames(trajectory):
        bounds = "pp pp pp" if frame.periodic else "ff ff ff"
        lines += ["ITEM: TIMESTEP", str(frame.step), "ITEM: NUMBER OF ATOMS", str(len(frame.id))]
        lines += [f"ITEM: BOX BOUNDS {bounds}"]
        lines += [f"{lo:.17g} {hi:.17g}" for lo, hi in zip(frame.lower, frame.upper, strict=True)]
        lines += ["ITEM: ATOMS id type radius x y z vx vy vz"]
        table = np.column_stack([frame.radius, frame.position, frame.velocity])
        lines += [
            f"{i} 1 " + " ".join(f"{v:.17g}" for v in row)
            for i, row in zip(frame.id, table, strict=True)
        ]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, "\n".join(lines) + "\n")
    return path


def export_gsd(trajectory: str | Path, path: str | Path) -> Path:
    """Every frame as a GSD file (the `gsd` package, HOOMD schema): positions relative to
    the box's centre (HOOMD's boxes are centred on the origin), diameters, velocities, the
    box edges, the step. GSD stores float32: positions to about 1e-7 of the box."""
    import gsd.hoomd

    from revdem_cli.errors import WriteFailed

    path = Path(path)
    open_trajectory(trajectory).close()  # checked before anything is written
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with gsd.hoomd.open(tmp, "w") as out:
            for frame in frames(trajectory):
                snapshot = gsd.hoomd.Frame()
                snapshot.configuration.step = frame.step
                edges = frame.upper - frame.lower
                snapshot.configuration.box = [*edges, 0.0, 0.0, 0.0]
                snapshot.particles.N = len(frame.id)
                snapshot.particles.types = ["sphere"]
                centre = 0.5 * (frame.lower + frame.upper)
                snapshot.particles.position = (frame.position - centre).astype(np.float32)
                snapshot.particles.diameter = (2.0 * frame.radius).astype(np.float32)
                snapshot.particles.velocity = frame.velocity.astype(np.float32)
                out.append(snapshot)
        tmp.replace(path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise WriteFailed(path, exc) from None
    return path
