"""VTK XML files of a trajectory, for ParaView: one PolyData (.vtp) file a frame and a .pvd
series that names them with their times.

Each particle is a point (and a vertex cell) carrying its radius, id, velocity, angular
velocity and force as point data, so a Glyph filter with spheres scaled by `radius` draws
the particles. Plain XML with ASCII data; no VTK library is needed to write or read them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from revdem_cli.io.h5md import FRAME_FIELDS, frame_steps, open_trajectory, read_frame


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
        _data_array(data, name, values, "Int64" if name == "id" else "Float64")
    return ET.ElementTree(root)


def export_vtk(trajectory: str | Path, out_dir: str | Path) -> list[Path]:
    """Write every frame of `trajectory` as out_dir/STEM.NNNNN.vtp and the series
    out_dir/STEM.pvd (STEM: the trajectory's name without .h5); returns the .pvd first."""
    trajectory, out_dir = Path(trajectory), Path(out_dir)
    stem = trajectory.stem
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    written = []
    with open_trajectory(trajectory) as f:  # checked before anything is written
        out_dir.mkdir(parents=True, exist_ok=True)
        particles = f["particles/all"]
        constant = {"radius": particles["radius"][:], "id": particles["id"][:]}
        times = particles["position/time"][:]
        width = max(5, len(str(len(times) - 1)))
        for frame in range(len(frame_steps(f))):
            fields = {name: read_frame(f, name, frame) for name in FRAME_FIELDS}
            position = fields.pop("position")
            path = out_dir / f"{stem}.{frame:0{width}d}.vtp"
            _polydata(position, {**constant, **fields}).write(path, xml_declaration=True)
            ET.SubElement(
                collection,
                "DataSet",
                timestep=repr(float(times[frame])),
                part="0",
                file=path.name,
            )
            written.append(path)
    series = out_dir / f"{stem}.pvd"
    ET.ElementTree(root).write(series, xml_declaration=True)
    return [series, *written]
