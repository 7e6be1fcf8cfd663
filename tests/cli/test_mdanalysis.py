"""revdem trajectories open in MDAnalysis' H5MD reader, frame by frame, as written."""

import h5py
import MDAnalysis
import numpy as np


def test_mdanalysis_reads_positions_velocities_time_and_the_box(smoke_run):
    path = smoke_run / "collision_smoke.forward.h5"
    universe = MDAnalysis.Universe.empty(2, trajectory=True)
    # SI units ("m") are not among MDAnalysis' length units, so the file is read as it is.
    universe.load_new(str(path), format="H5MD", convert_units=False)
    with h5py.File(path, "r") as f:
        position = f["particles/all/position/value"][:]
        velocity = f["particles/all/velocity/value"][:]
        time = f["particles/all/position/time"][:]
        steps = f["particles/all/position/step"][:]
    assert len(universe.trajectory) == len(position) == 21
    for frame in (0, 10, 20):
        ts = universe.trajectory[frame]
        # MDAnalysis holds coordinates in float32
        np.testing.assert_allclose(universe.atoms.positions, position[frame], rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(universe.atoms.velocities, velocity[frame], rtol=1e-6)
        assert ts.time == time[frame] and ts.data["step"] == steps[frame]
        # boundary "none": the box is the bounding box of the spheres at that frame
        extent = (position[frame] + 0.005).max(axis=0) - (position[frame] - 0.005).min(axis=0)
        np.testing.assert_allclose(ts.dimensions, [*extent, 90, 90, 90], rtol=1e-6)
    assert not np.allclose(position[20], position[0])


def test_the_units_are_declared_si_and_left_off_what_mdanalysis_would_refuse(smoke_run):
    """H5MD's units module says SI; a `unit` attribute "m" on the positions would make
    MDAnalysis' reader refuse the file (its lengths are Angstrom, nm, pm and fm)."""
    with h5py.File(smoke_run / "collision_smoke.forward.h5", "r") as f:
        assert f["h5md/modules/units"].attrs["system"] == b"SI"
        assert "unit" not in f["particles/all/position/value"].attrs
    attributes = MDAnalysis.coordinates.H5MD.H5MDReader._unit_translation
    assert "m" not in attributes["length"]  # were it added, positions could say "m"
