"""`revdem export`: VTK (a .vtp file a frame and a .pvd series that ParaView reads), and GSD
and LAMMPS dumps, read back by OVITO itself (the `ovito` package)."""

import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS

runner = CliRunner()


def arrays(piece):
    """{name: values} of every DataArray in a Piece, shaped by its components."""
    found = {}
    for array in piece.iter("DataArray"):
        values = np.array(array.text.split(), dtype=float)
        found[array.get("Name")] = values.reshape(-1, int(array.get("NumberOfComponents", 1)))
    return found


def test_vtk_export_writes_every_frame_with_particle_data(smoke_run, tmp_path):
    trajectory = smoke_run / "collision_smoke.reverse.h5"
    result = runner.invoke(app, ["export", "--vtk", str(trajectory), "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output

    series = ET.parse(tmp_path / "collision_smoke.reverse.pvd").getroot()
    datasets = series.findall("Collection/DataSet")
    assert len(datasets) == 21
    with h5py.File(trajectory, "r") as f:
        times = f["particles/all/position/time"][:]
        position = f["particles/all/position/value"][:]
        velocity = f["particles/all/velocity/value"][:]
        omega = f["particles/all/angular_velocity/value"][:]
    assert [float(d.get("timestep")) for d in datasets] == times.tolist()

    for frame in (0, 7, 20):
        root = ET.parse(tmp_path / datasets[frame].get("file")).getroot()
        assert root.get("type") == "PolyData"
        piece = root.find("PolyData/Piece")
        assert piece.get("NumberOfPoints") == "2"
        data = arrays(piece)
        np.testing.assert_array_equal(data["position"], position[frame])
        np.testing.assert_array_equal(data["velocity"], velocity[frame])
        np.testing.assert_array_equal(data["angular_velocity"], omega[frame])
        np.testing.assert_array_equal(data["radius"].ravel(), [0.005, 0.005])
        np.testing.assert_array_equal(data["connectivity"].ravel(), [0, 1])


def test_export_needs_a_format_and_a_trajectory(smoke_run):
    for args, message in (
        (
            ["export", str(smoke_run / "collision_smoke.forward.h5")],
            "--format must be one of vtk, gsd, lammps-dump; give one",
        ),
        (
            ["export", str(smoke_run / "collision_smoke.forward.h5"), "--vtk", "--format", "gsd"],
            "ask for two formats",
        ),
        (["export", "--vtk", str(smoke_run / "collision_smoke.restart.h5")], "not a revdem"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 2 and message in result.output, result.output


@pytest.fixture(scope="module")
def packings(tmp_path_factory) -> dict[str, Path]:
    """Short runs of the smoke oedometer (walls, open boundaries) and of the fcc triaxial
    test (a periodic cell that deforms): their forward trajectories."""
    out = tmp_path_factory.mktemp("packings")
    runs = {
        "oedometer": (CONFIGS / "smoke" / "oedometer.toml", 4, "oedometer_smoke"),
        "fcc": (CONFIGS / "fcc_triaxial.toml", 2, "fcc_triaxial"),
    }
    found = {}
    for key, (config, stages, name) in runs.items():
        short = [
            f"stages.{k}.{f}" for k in range(stages) for f in ("steps=400", "output_every=100")
        ]
        sets = [part for item in short for part in ("--set", item)]
        args = ["run", str(config), "--out", str(out / key), "-q", "--no-reverse", *sets]
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        found[key] = out / key / f"{name}.forward.h5"
    return found


@pytest.mark.parametrize("kind", ["oedometer", "fcc"])
@pytest.mark.parametrize("fmt", ["gsd", "lammps-dump"])
def test_ovito_reads_every_frame_of_an_export(packings, kind, fmt, tmp_path):
    """OVITO sees the frames, particles, radii and positions of the H5MD trajectory (GSD in
    float32, relative to the box's centre; the dump with every digit), and the periodic
    cell's edges as its box."""
    from ovito.io import import_file

    trajectory = packings[kind]
    target = tmp_path / f"export.{'gsd' if fmt == 'gsd' else 'dump'}"
    result = runner.invoke(app, ["export", str(trajectory), "--format", fmt, "--out", str(target)])
    assert result.exit_code == 0, result.output
    with h5py.File(trajectory, "r") as f:
        position = f["particles/all/position/value"][:]
        radius = f["particles/all/radius"][:]
        edges = f["particles/all/box/edges/value"][:]
    pipeline = import_file(str(target))
    assert pipeline.source.num_frames == len(position) > 3
    for frame in (0, len(position) // 2, len(position) - 1):
        data = pipeline.compute(frame)
        assert data.particles.count == len(radius)
        seen = np.asarray(data.particles.positions)
        if fmt == "gsd":
            np.testing.assert_allclose(np.asarray(data.particles["Radius"]), radius, rtol=1e-6)
            centre = data.cell[:, 3] + 0.5 * data.cell[:, :3].diagonal()
            lower = position[frame] - seen  # the box's centre, the same for every sphere
            np.testing.assert_allclose(lower - lower[0], 0.0, atol=1e-6 * edges[frame].max())
            assert np.abs(centre).max() < 1e-6 * edges[frame].max()
        else:  # 17 digits: OVITO reads positions to an ulp or two, radii into float32
            np.testing.assert_allclose(np.asarray(data.particles["Radius"]), radius, rtol=3e-7)
            np.testing.assert_allclose(seen, position[frame], rtol=0, atol=1e-15 * edges.max())
        if kind == "fcc":
            np.testing.assert_allclose(data.cell[:, :3].diagonal(), edges[frame], rtol=1e-6)
            assert all(data.cell.pbc)
