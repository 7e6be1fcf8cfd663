"""VTK XML files of a trajectory, for ParaView: one PolyData (.vtp) file a frame and a .pvd
series that names them with their times.

Each particle is a point (and a vertex cell) carrying its radius, id, type (its material,
numbered from 1 in the order of [materials]), velocity, angular
velocity and force as point data, so a Glyph filter with spheres scaled by `radius` draws
the particles. A trajectory with contacts ([output] contacts) also gets the force chains,
STEM.contacts.NNNNN.vtp and STEM.contacts.pvd: a line a contact, from the sphere's centre
to its partner's (the nearest image across a periodic face) or to the contact point on a
wall, with the contact's forces as cell data; colour by `normal_force_magnitude`, or give
the lines a width by it with a Tube filter. Plain XML with ASCII data; no VTK library is
needed to write or read them.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from revdem_cli.io.h5md import frame_steps, open_trajectory
from revdem_cli.io.particles import CONTACTS, FrameProgress, frames

VTK_WRITES = ("position", "velocity", "angular_velocity", "force", CONTACTS)
"""What of a frame a VTK export writes (`particles.frames`): every per-sphere field, and the
contacts as force chains."""

CHAINS = ".contacts"
"""What the force chains' names add to the spheres': STEM.contacts.pvd and its frames."""

DIGITS = 5
"""The fewest digits of a frame's number in its file's name (more where the frames need)."""


def own_files(out_dir: str | Path, stem: str) -> list[Path]:
    """The files an earlier export of the trajectory STEM.h5 wrote in `out_dir`: its series
    STEM.pvd and the force chains' STEM.contacts.pvd, and the frames each lists named as
    this export names its frames (STEM.NNNNN.vtp, STEM.contacts.NNNNN.vtp); nothing else
    (a frame no series lists, another trajectory's export, a file of the user's own), sorted
    by name. A series that cannot be read lists none."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    found = []
    for series in (out_dir / f"{stem}.pvd", out_dir / f"{stem}{CHAINS}.pvd"):
        if not series.is_file():
            continue
        found.append(series)
        frame = re.compile(rf"{re.escape(series.stem)}\.\d{{{DIGITS},}}\.vtp")
        try:
            listed = [d.get("file", "") for d in ET.parse(series).iter("DataSet")]
        except (ET.ParseError, OSError):
            listed = []
        found += [
            out_dir / name
            for name in listed
            if frame.fullmatch(name) and (out_dir / name).is_file()
        ]
    return sorted(set(found))


def _data_array(parent: ET.Element, name: str, values: np.ndarray, kind: str) -> None:
    values = np.asarray(values)
    array = ET.SubElement(parent, "DataArray", type=kind, Name=name, format="ascii")
    if values.ndim == 2:
        array.set("NumberOfComponents", str(values.shape[1]))
    fmt = "%.17g" if kind == "Float64" else "%d"
    array.text = " ".join(fmt % v for v in values.ravel())


def _polydata(position: np.ndarray, point_data: dict[str, np.ndarray]) -> ET.ElementTree:
    n = len(position)
    root = ET.Element("VTKFile", type="PolyData", version="0.1", byte_order="LittleEndian")
    piece = ET.SubElement(
        ET.SubElement(root, "PolyData"), "Piece", NumberOfPoints=str(n), NumberOfVerts=str(n)
    )
    _data_array(ET.SubElement(piece, "Points"), "position", position, "Float64")
    verts = ET.SubElement(piece, "Verts")
    _data_array(verts, "connectivity", np.arange(n), "Int64")
    _data_array(verts, "offsets", np.arange(1, n + 1), "Int64")
    data = ET.SubElement(piece, "PointData", Scalars="radius", Vectors="velocity")
    for name, values in point_data.items():
        _data_array(data, name, values, "Int64" if name in ("id", "type") else "Float64")
    return ET.ElementTree(root)


def _force_chains(position: np.ndarray, box: np.ndarray | None, contacts: dict) -> ET.ElementTree:
    """The contacts of a frame as lines (see the module's docstring)."""
    i, partner = contacts["value"][:, 0], contacts["value"][:, 1]
    on_wall = partner < 0
    start = position[i]
    end = contacts["point"].copy()
    j = partner[~on_wall]
    d = position[j] - start[~on_wall]
    if box is not None:
        d -= box * np.round(d / box)  # nearest image
    end[~on_wall] = start[~on_wall] + d
    k = len(i)
    points = np.empty((2 * k, 3))
    points[0::2], points[1::2] = start, end
    root = ET.Element("VTKFile", type="PolyData", version="0.1", byte_order="LittleEndian")
    piece = ET.SubElement(
        ET.SubElement(root, "PolyData"), "Piece", NumberOfPoints=str(2 * k), NumberOfLines=str(k)
    )
    _data_array(ET.SubElement(piece, "Points"), "position", points, "Float64")
    lines = ET.SubElement(piece, "Lines")
    _data_array(lines, "connectivity", np.arange(2 * k), "Int64")
    _data_array(lines, "offsets", 2 * np.arange(1, k + 1), "Int64")
    data = ET.SubElement(piece, "CellData", Scalars="normal_force_magnitude")
    magnitude = np.sqrt((contacts["normal_force"] ** 2).sum(axis=1))
    _data_array(data, "normal_force_magnitude", magnitude, "Float64")
    for name in ("normal_force", "tangential_force", "overlap"):
        _data_array(data, name, contacts[name], "Float64")
    _data_array(data, "sliding", contacts["sliding"], "Int64")
    _data_array(data, "particle", i, "Int64")
    _data_array(data, "partner", partner, "Int64")
    return ET.ElementTree(root)


def _series(frames: list[tuple[float, Path]]) -> bytes:
    """A .pvd file naming each frame's file with its time."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    for time, frame in frames:
        ET.SubElement(collection, "DataSet", timestep=repr(time), part="0", file=frame.name)
    return ET.tostring(root, xml_declaration=True)


def export_vtk(
    trajectory: str | Path, out_dir: str | Path, progress: FrameProgress | None = None
) -> dict[Path, list[Path]]:
    """Write every frame of `trajectory` as out_dir/STEM.NNNNN.vtp and the series
    out_dir/STEM.pvd (STEM: the trajectory's name without .h5), and with contacts the force
    chains STEM.contacts.NNNNN.vtp and STEM.contacts.pvd, telling `progress` of each frame;
    returns each series written, the spheres' first, with its frame files.

    The frames are written into a folder of their own in `out_dir` (`writing_folder`) and
    moved into place once every one is written, so that an export stopped or failed on the
    way (Ctrl-C, a full disk) leaves the earlier export as it was. The files an earlier
    export of STEM left in `out_dir` (`own_files`) are then removed: one of more frames, or
    with contacts, would leave frames its series no longer lists, and ParaView, opening the
    .vtp files as a group, would show two runs' frames as one. The caller decides whether
    they may go (`revdem export`: in the trajectory's own folder, STEM.vtk, always; in one
    --out names, only with --force)."""
    import shutil

    from revdem_cli.errors import WriteFailed
    from revdem_cli.io import write_file

    trajectory, out_dir = Path(trajectory), Path(out_dir)
    stem = trajectory.stem
    writing = writing_folder(out_dir, stem)
    made = next((p for p in reversed([out_dir, *out_dir.parents]) if not p.exists()), None)
    moved = False  # `made`, the first folder the export makes, is removed if it fails
    with open_trajectory(trajectory) as f:  # checked before anything is written
        out_dir.mkdir(parents=True, exist_ok=True)  # a path that cannot be a folder (a file
        try:  # there or above, no permission) is the caller's to name: `errors.path_problem`
            shutil.rmtree(writing, ignore_errors=True)  # left by an export that was killed
            writing.mkdir()
            spheres, chains = _write_frames(trajectory, len(frame_steps(f)), writing, progress)
            for path in own_files(out_dir, stem):
                path.unlink()
            for _, frame in spheres + chains:
                frame.replace(out_dir / frame.name)
            moved = True
        except OSError as exc:
            raise WriteFailed(_as_the_user_knows_it(exc, out_dir, writing), exc) from None
        finally:
            shutil.rmtree(writing if moved or made is None else made, ignore_errors=True)
    written = {out_dir / f"{stem}.pvd": spheres}
    if chains:
        written[out_dir / f"{stem}{CHAINS}.pvd"] = chains
    for series, listed in written.items():
        write_file(series, _series(listed))
    return {
        series: [out_dir / frame.name for _, frame in listed] for series, listed in written.items()
    }


def _as_the_user_knows_it(exc: OSError, out_dir: Path, writing: Path) -> Path:
    """The path a failed write of an export names, as its user knows it: a frame in the
    hidden `writing` folder by the file it was to become in `out_dir`, that folder itself by
    `out_dir`, any other as it is."""
    if exc.filename is None:
        return out_dir
    path = Path(exc.filename)
    if path == writing:
        return out_dir
    return out_dir / path.name if path.parent == writing else path


def writing_folder(out_dir: Path, stem: str) -> Path:
    """The hidden folder in `out_dir` that an export of STEM writes its frames into before
    they take the place of an earlier export's."""
    return out_dir / f".{stem}.vtk-writing"


def _write_frames(
    trajectory: Path, count: int, folder: Path, progress: FrameProgress | None
) -> tuple[list[tuple[float, Path]], list[tuple[float, Path]]]:
    """Every frame of `trajectory`, of `count`, as a .vtp file in `folder`, and with contacts
    its force chains: (time, file) of the spheres' frames and of the chains'."""
    stem = trajectory.stem
    spheres, chains = [], []
    width = max(DIGITS, len(str(count - 1)))
    for index, frame in enumerate(frames(trajectory, VTK_WRITES, progress=progress)):
        point_data = {
            "radius": frame.radius,
            "id": frame.id,
            "type": frame.type,
            "velocity": frame.velocity,
            "angular_velocity": frame.angular_velocity,
            "force": frame.force,
        }
        path = folder / f"{stem}.{index:0{width}d}.vtp"
        _polydata(frame.position, point_data).write(path, xml_declaration=True)
        spheres.append((frame.time, path))
        if frame.contacts is not None:
            box = frame.upper if frame.periodic else None  # a periodic cell's lower corner is 0
            path = folder / f"{stem}{CHAINS}.{index:0{width}d}.vtp"
            _force_chains(frame.position, box, frame.contacts).write(path, xml_declaration=True)
            chains.append((frame.time, path))
    return spheres, chains
