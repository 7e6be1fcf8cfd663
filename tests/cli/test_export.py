"""`revdem export --vtk`: a .vtp file a frame and a .pvd series that ParaView reads."""

import xml.etree.ElementTree as ET

import h5py
import numpy as np
from typer.testing import CliRunner

from revdem_cli.cli import app

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
        (["export", str(smoke_run / "collision_smoke.forward.h5")], "choose a format (--vtk)"),
        (["export", "--vtk", str(smoke_run / "collision_smoke.restart.h5")], "not a revdem"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 2 and message in result.output, result.output
