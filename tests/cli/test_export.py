"""`revdem export`: VTK (a .vtp file a frame and a .pvd series that ParaView reads), and GSD
and LAMMPS dumps, read back by OVITO itself (the `ovito` package)."""

import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS, assert_one_line_error

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
    result = runner.invoke(app, ["export", "--vtk", str(trajectory), "--out", str(tmp_path), "-q"])
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
        np.testing.assert_array_equal(data["type"].ravel(), [1, 1])  # the one material
        np.testing.assert_array_equal(data["connectivity"].ravel(), [0, 1])
    series = tmp_path / "collision_smoke.reverse.pvd"
    assert result.output.splitlines()[-1] == f"wrote {series} and its 21 frame files"


def test_export_needs_a_format_and_a_trajectory(smoke_run):
    for args, message in (
        (
            ["export", str(smoke_run / "collision_smoke.forward.h5")],
            "--format must be one of vtk, gsd, lammps-dump, lammps-data; give one",
        ),
        (
            ["export", str(smoke_run / "collision_smoke.forward.h5"), "--vtk", "--format", "gsd"],
            "ask for two formats",
        ),
        (["export", "--vtk", str(smoke_run / "collision_smoke.restart.h5")], "not a revdem"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 2 and message in result.output, result.output


@pytest.mark.parametrize(
    "repeated, option",
    [(["--format", "gsd", "--format", "vtk"], "--format"),
     (["--format", "gsd", "--out", "{tmp}/a.gsd", "--out", "{tmp}/b.gsd"], "--out"),
     (["--format", "lammps-data", "--step", "0", "--step", "1000"], "--step")],
)  # fmt: skip
def test_an_option_given_twice_is_refused_not_taken_last_wins(
    smoke_run, tmp_path, repeated, option
):
    """`--format gsd --format vtk` wrote VTK and `--out a --out b` wrote b, where `--vtk
    --format gsd` was refused: each option of export is taken once, as dt's are."""
    forward = smoke_run / "collision_smoke.forward.h5"
    before = sorted(smoke_run.iterdir())
    args = [arg.format(tmp=tmp_path) for arg in repeated]
    result = runner.invoke(app, ["export", str(forward), *args, "-q"])
    assert_one_line_error(result, f"export: {option} is given 2 times; give it once")
    assert sorted(smoke_run.iterdir()) == before and not list(tmp_path.iterdir())


@pytest.mark.parametrize("fmt", ["gsd", "lammps-data"])
def test_an_export_never_writes_over_the_trajectory_or_another_runs_file(smoke_run, fmt):
    forward, restart = (smoke_run / f"collision_smoke.{kind}.h5" for kind in ("forward", "restart"))
    kept = {path: path.read_bytes() for path in (forward, restart)}
    for target, what in ((forward, "the file it reads"), (restart, "HDF5")):
        args = ["export", str(forward), "--format", fmt, "--out", str(target)]
        assert_one_line_error(runner.invoke(app, args), f"--out {target}: {what}, which")
    assert all(path.read_bytes() == data for path, data in kept.items())


def test_an_export_writes_over_a_file_it_names_only_with_force(smoke_run, tmp_path):
    """A verdict or a figure of a run, named by --out, is kept (it was overwritten without a
    word); --force writes over it, and the default target is the export's own to rewrite."""
    forward, verdict = (
        smoke_run / "collision_smoke.forward.h5",
        smoke_run / "collision_smoke.compare.json",
    )
    kept = verdict.read_bytes()
    args = ["export", str(forward), "--format", "lammps-dump", "--out", str(verdict)]
    assert_one_line_error(runner.invoke(app, args), f"--out {verdict}: exists; use --force")
    assert verdict.read_bytes() == kept
    mine = tmp_path / "verdict.json"
    mine.write_bytes(kept)
    args = ["export", str(forward), "--format", "lammps-dump", "--out", str(mine), "--force"]
    assert runner.invoke(app, args).exit_code == 0
    assert mine.read_text().startswith("ITEM: TIMESTEP")
    local = tmp_path / "forward.h5"
    local.symlink_to(forward)
    for _ in range(2):  # its default target, local.dump, again
        result = runner.invoke(app, ["export", str(local), "--format", "lammps-dump", "-q"])
        assert result.exit_code == 0, result.output
    assert (tmp_path / "forward.dump").read_text().startswith("ITEM: TIMESTEP")


def _earlier_series(folder, stem: str, frames: list[str]) -> None:
    """An earlier export's series STEM.pvd in `folder`, listing `frames`, each written."""
    listed = "".join(f'<DataSet timestep="0" part="0" file="{name}"/>' for name in frames)
    text = f'<VTKFile type="Collection"><Collection>{listed}</Collection></VTKFile>'
    (folder / f"{stem}.pvd").write_text(text)
    for name in frames:
        (folder / name).write_text("earlier")


def test_a_vtk_export_removes_its_earlier_frames_and_nothing_else(smoke_run, tmp_path):
    """An export over an earlier one of more frames, or with force chains, left their files:
    ParaView, opening the .vtp files as a group, showed the frames of two runs. The folder
    now holds the frames its series lists: the frames the earlier series listed go, in a
    folder --out names with --force (refused without), in its own folder always; no other
    file goes, not even one named as a frame that no series lists."""
    trajectory = smoke_run / "collision_smoke.forward.h5"
    stem = trajectory.stem
    folder = tmp_path / "vtk"
    folder.mkdir()
    _earlier_series(folder, stem, [f"{stem}.00021.vtp", f"{stem}.00030.vtp"])
    _earlier_series(folder, f"{stem}.contacts", [f"{stem}.contacts.00003.vtp"])
    others = ["notes.txt", "collision_smoke.reverse.00030.vtp", f"{stem}.0003.vtp",
              f"{stem}.00003.vtp.bak", "other.forward.pvd", f"{stem}.00500.vtp"]  # fmt: skip
    for name in others:
        (folder / name).write_text("mine")
    before = sorted(p.name for p in folder.iterdir())
    args = ["export", str(trajectory), "--vtk", "--out", str(folder), "-q"]
    assert_one_line_error(
        runner.invoke(app, args),
        f"--out {folder}: holds {stem}.00021.vtp and 4 more of an earlier export of "
        f"{trajectory.name}; use --force",
    )
    assert sorted(p.name for p in folder.iterdir()) == before
    result = runner.invoke(app, [*args, "--force"])
    assert result.exit_code == 0, result.output
    series = ET.parse(folder / f"{stem}.pvd").getroot()
    listed = [d.get("file") for d in series.findall("Collection/DataSet")]
    assert len(listed) == 21
    assert sorted(p.name for p in folder.iterdir()) == sorted([*listed, f"{stem}.pvd", *others])

    local = tmp_path / "forward.h5"
    local.symlink_to(trajectory)
    (tmp_path / "forward.vtk").mkdir()
    _earlier_series(tmp_path / "forward.vtk", "forward", ["forward.00030.vtp"])
    (tmp_path / "forward.vtk" / "forward.00777.vtp").write_text("mine")
    result = runner.invoke(app, ["export", str(local), "--vtk", "-q"])
    assert result.exit_code == 0, result.output
    assert not (tmp_path / "forward.vtk" / "forward.00030.vtp").exists()
    assert (tmp_path / "forward.vtk" / "forward.00777.vtp").read_text() == "mine"


def test_a_vtk_export_into_a_file_is_refused_as_the_other_formats_are(smoke_run, tmp_path):
    """A file where the vtk folder goes (--out, a folder above it, or the default
    NAME.vtk) failed with exit 1 naming the hidden folder the frames are written into; it is
    bad input, refused in one line naming the file in the way, as the other formats do."""
    forward = smoke_run / "collision_smoke.forward.h5"
    mine = tmp_path / "mine.txt"
    mine.write_text("mine")
    refused = {
        mine: f"{mine}: a file, not a folder",
        mine / "sub": f"{mine / 'sub'}: {mine} is a file, not a folder",
    }
    for out, line in refused.items():
        result = runner.invoke(app, ["export", str(forward), "--vtk", "--out", str(out), "-q"])
        assert_one_line_error(result, line)
    local = tmp_path / "forward.h5"
    local.symlink_to(forward)
    (tmp_path / "forward.vtk").write_text("mine")
    result = runner.invoke(app, ["export", str(local), "--vtk", "-q"])
    assert_one_line_error(result, f"{tmp_path / 'forward.vtk'}: a file, not a folder")
    assert mine.read_text() == (tmp_path / "forward.vtk").read_text() == "mine"


def test_a_vtk_export_that_cannot_write_names_the_folder_once(smoke_run, tmp_path, monkeypatch):
    """A folder where no folder may be made said `cannot write rodir/vtkout/vtkout`. Now a
    new --out folder that cannot be made is named as given (exit 2, as a path of the user's
    that cannot be used), and one that is there but takes no files is named itself."""
    import errno
    import os

    forward = smoke_run / "collision_smoke.forward.h5"
    read_only = tmp_path / "rodir"
    read_only.mkdir()
    (read_only / "there").mkdir()
    make_folder = os.mkdir

    def refused_inside(path, *args, **kwargs):
        if Path(path).parent in (read_only, read_only / "there"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        make_folder(path, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", refused_inside)
    new, there = read_only / "vtkout", read_only / "there"
    result = runner.invoke(app, ["export", str(forward), "--vtk", "--out", str(new), "-q"])
    assert_one_line_error(result, f"error: {new}: Permission denied")
    result = runner.invoke(app, ["export", str(forward), "--vtk", "--out", str(there), "-q"])
    assert result.exit_code == 1
    assert result.output == f"failed: cannot write {there}: Permission denied (errno 13)\n"


@pytest.mark.parametrize("stop", [KeyboardInterrupt, OSError])
def test_a_vtk_export_stopped_on_the_way_leaves_the_earlier_one_whole(smoke_run, tmp_path, stop):
    """The export removed the earlier export's files and then wrote its frames in place: a
    Ctrl-C or a full disk on the way left neither the earlier export nor a new one a .pvd
    names. Stopped at its third frame, the folder now holds what it held before."""
    from revdem_cli.errors import WriteFailed
    from revdem_cli.io.vtk import export_vtk

    trajectory = smoke_run / "collision_smoke.forward.h5"
    stem = trajectory.stem
    _earlier_series(tmp_path, stem, [f"{stem}.00000.vtp", f"{stem}.00001.vtp"])
    before = {p.name: p.read_text() for p in tmp_path.iterdir()}

    def progress(name, done, total):
        if done == 3:
            raise stop(28, "No space left on device", str(tmp_path / f"{stem}.00002.vtp"))

    expected = KeyboardInterrupt if stop is KeyboardInterrupt else WriteFailed
    with pytest.raises(expected):
        export_vtk(trajectory, tmp_path, progress)
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize(
    "fmt, field",
    [("lammps-dump", "position"), ("gsd", "velocity"), ("vtk", "position"),
     ("lammps-data", "velocity")],
)  # fmt: skip
def test_a_frame_that_is_not_finite_is_refused_by_every_format(smoke_run, tmp_path, fmt, field):
    """One nan position made an open system's bounding box, which a LAMMPS dump gives every
    frame, nan nan in all of them; the other formats wrote the nan as a value. The frame is
    refused, named by its step and the sphere, and what --out held before is kept."""
    import shutil

    trajectory = Path(shutil.copy(smoke_run / "collision_smoke.forward.h5", tmp_path))
    with h5py.File(trajectory, "r+") as f:
        values = f[f"particles/all/{field}/value"]
        frame = values[7]
        frame[1, 0] = np.nan
        values[7] = frame
        step = int(f["particles/all/position/step"][7])
    target = tmp_path / ("vtk" if fmt == "vtk" else "earlier.txt")
    if fmt != "vtk":
        target.write_text("earlier")
    args = ["export", str(trajectory), "--format", fmt, "--out", str(target), "--force", "-q"]
    if fmt == "lammps-data":
        args += ["--step", str(step)]
    before = sorted(tmp_path.iterdir())
    assert_one_line_error(
        runner.invoke(app, args),
        f"{trajectory}: damaged revdem trajectory: {field} of particle 1 (id 2) at step "
        f"{step} is not finite",
    )
    assert sorted(tmp_path.iterdir()) == before
    assert fmt == "vtk" or target.read_text() == "earlier"


@pytest.mark.parametrize(
    "fmt, unwritten",
    [("lammps-dump", ["force", "angular_velocity"]), ("gsd", ["force", "angular_velocity"]),
     ("lammps-data", ["force"])],
)  # fmt: skip
def test_an_export_reads_only_what_its_format_writes(smoke_run, tmp_path, fmt, unwritten):
    """Every format read each frame's forces, which VTK alone writes, and refused a
    trajectory whose forces were damaged (not finite) as if it wrote them. An export whose
    format does not write a field is the same whether that field is sound or damaged, and a
    format that writes it still refuses it damaged."""
    import shutil

    sound = smoke_run / "collision_smoke.forward.h5"
    damaged = tmp_path / "damaged" / sound.name
    damaged.parent.mkdir()
    shutil.copy(sound, damaged)
    with h5py.File(damaged, "r+") as f:
        for field in unwritten:
            f[f"particles/all/{field}/value"][...] = np.nan
    exported = []
    for trajectory in (sound, damaged):
        target = tmp_path / f"{trajectory.parent.name}.{fmt}"
        args = ["export", str(trajectory), "--format", fmt, "--out", str(target), "-q"]
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        exported.append(target.read_bytes())
    assert exported[1] == exported[0]
    args = ["export", str(damaged), "--format", "vtk", "--out", str(tmp_path / "vtk"), "-q"]
    refused = runner.invoke(app, args)
    assert_one_line_error(refused, "damaged revdem trajectory: ", "is not finite")
    assert any(f"trajectory: {field} of particle 0 (id 1)" in refused.output for field in unwritten)


@pytest.fixture(scope="module")
def packings(tmp_path_factory) -> dict[str, Path]:
    """Runs of the smoke oedometer (walls, open boundaries; its compression short) and of
    the fcc triaxial test (a periodic cell that deforms; both stages short), writing their
    contacts: their forward trajectories. The last stage of each is undamped."""
    out = tmp_path_factory.mktemp("packings")
    runs = {  # the oedometer poured, closed and settled in full: its spheres touch
        "oedometer": (CONFIGS / "smoke" / "oedometer.toml", [3], "oedometer_smoke"),
        "fcc": (CONFIGS / "fcc_triaxial.toml", [0, 1], "fcc_triaxial"),
    }
    found = {}
    for key, (config, stages, name) in runs.items():
        short = [f"stages.{k}.{f}" for k in stages for f in ("steps=400", "output_every=100")]
        short += ["output.contacts=true", "output.figures=['contact_forces','contact_normals']"]
        sets = [part for item in short for part in ("--set", item)]
        args = ["run", str(config), "--out", str(out / key), "-q", "--no-reverse", *sets]
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        found[key] = out / key / f"{name}.forward.h5"
    return found


@pytest.mark.parametrize("kind", ["oedometer", "fcc"])
@pytest.mark.parametrize("fmt", ["gsd", "lammps-dump"])
def test_ovito_reads_every_frame_of_an_export(packings, kind, fmt, tmp_path):
    """OVITO sees the frames, particles, ids, radii and positions of the H5MD trajectory
    (GSD in float32, relative to the box's centre; the dump with every digit), and the
    periodic cell's edges as its box."""
    from ovito.io import import_file

    trajectory = packings[kind]
    target = tmp_path / f"export.{'gsd' if fmt == 'gsd' else 'dump'}"
    result = runner.invoke(app, ["export", str(trajectory), "--format", fmt, "--out", str(target)])
    assert result.exit_code == 0, result.output
    with h5py.File(trajectory, "r") as f:
        position = f["particles/all/position/value"][:]
        radius = f["particles/all/radius"][:]
        mass = f["particles/all/mass"][:]
        ids = f["particles/all/id"][:]
        edges = f["particles/all/box/edges/value"][:]
    pipeline = import_file(str(target))
    assert pipeline.source.num_frames == len(position) > 3
    offsets = []
    for frame in (0, len(position) // 2, len(position) - 1):
        data = pipeline.compute(frame)
        assert data.particles.count == len(radius)
        np.testing.assert_array_equal(np.asarray(data.particles["Particle Identifier"]), ids)
        seen = np.asarray(data.particles.positions)
        if fmt == "gsd":
            np.testing.assert_allclose(np.asarray(data.particles["Radius"]), radius, rtol=1e-6)
            np.testing.assert_allclose(np.asarray(data.particles["Mass"]), mass, rtol=1e-6)
            centre = data.cell[:, 3] + 0.5 * data.cell[:, :3].diagonal()
            lower = position[frame] - seen  # the box's centre, the same for every sphere
            np.testing.assert_allclose(lower - lower[0], 0.0, atol=1e-6 * edges[frame].max())
            assert np.abs(centre).max() < 1e-6 * edges[frame].max()
            offsets.append(lower[0])
        else:  # 17 digits: OVITO reads positions to an ulp or two, radii into float32
            np.testing.assert_allclose(np.asarray(data.particles["Radius"]), radius, rtol=3e-7)
            np.testing.assert_allclose(seen, position[frame], rtol=0, atol=1e-15 * edges.max())
        if kind == "fcc":
            np.testing.assert_allclose(data.cell[:, :3].diagonal(), edges[frame], rtol=1e-6)
            assert all(data.cell.pbc)
    if fmt == "lammps-dump":  # unwrapped in a periodic cell: LAMMPS' xu yu zu, not x y z
        columns = "xu yu zu" if kind == "fcc" else "x y z"
        assert f"ITEM: ATOMS id type radius {columns} vx vy vz\n" in target.read_text()
    if fmt == "gsd" and kind == "oedometer":  # open: one box, so displacements are kept
        np.testing.assert_allclose(np.array(offsets) - offsets[0], 0.0, atol=1e-6 * edges.max())


def _contacts(trajectory: Path, frame: int) -> dict[str, np.ndarray]:
    from revdem_cli.io.h5md import read_contacts

    with h5py.File(trajectory, "r") as f:
        return read_contacts(f, frame)


@pytest.mark.parametrize("kind", ["oedometer", "fcc"])
def test_the_contacts_of_a_frame_sum_to_each_sphere_s_net_force(packings, kind):
    """Newton's second law at a frame of an undamped stage: each sphere's weight plus the
    forces of its contacts (on it where it is `particle`, the reaction where it is the
    partner, wall contacts) is the net force the engine summed, to round-off; normal forces
    push the spheres apart; the count of sphere contacts is the coordination number."""
    import json

    trajectory = packings[kind]
    with h5py.File(trajectory, "r") as f:
        force = f["particles/all/force/value"][-1]
        position = f["particles/all/position/value"][-1]
        mass = f["particles/all/mass"][:]
        step = f["particles/all/force/step"][-1]
        scenario = json.loads(f["parameters/revdem"].attrs["scenario_json"])
        rows = f["observables/coordination_number/step"][:]
        coordination = f["observables/coordination_number/value"][np.flatnonzero(rows == step)[0]]
    contacts = _contacts(trajectory, -1)
    particle, partner = contacts["value"][:, 0], contacts["value"][:, 1]
    on_wall = partner < 0
    assert (~on_wall).sum() > 100 and (kind == "fcc" or on_wall.sum() > 10)
    total = contacts["normal_force"] + contacts["tangential_force"]
    summed = mass[:, None] * np.array(scenario["gravity"])
    np.add.at(summed, particle, total)
    np.subtract.at(summed, partner[~on_wall], total[~on_wall])
    scale = np.abs(total).max()
    np.testing.assert_allclose(summed, force, rtol=0, atol=1e-12 * scale)
    towards = contacts["point"] - position[particle]  # r - δ/2 along the normal
    assert ((contacts["normal_force"] * towards).sum(axis=1) < 0).all()
    assert np.all(contacts["overlap"] > 0)
    assert 2 * (~on_wall).sum() / len(mass) == pytest.approx(coordination, rel=1e-12)


def test_a_vtk_export_counts_the_frames_of_each_series(packings, tmp_path):
    """With contacts it said the spheres' series had a frame more than it wrote (the force
    chains' .pvd counted as one): each series now with the frames written for it."""
    trajectory = packings["oedometer"]
    result = runner.invoke(app, ["export", str(trajectory), "--vtk", "--out", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    with h5py.File(trajectory, "r") as f:
        frames = len(f["particles/all/position/step"])
    assert result.output.splitlines() == [
        f"wrote {tmp_path / series}.pvd and its {frames} frame files"
        for series in (trajectory.stem, f"{trajectory.stem}.contacts")
    ]
    assert len(list(tmp_path.glob("*.vtp"))) == 2 * frames


@pytest.mark.parametrize("kind", ["oedometer", "fcc"])
def test_force_chains_open_in_vtk_and_bonds_in_ovito(packings, kind, tmp_path):
    """The force-chain VTK series, read by VTK's own XML reader (ParaView's): a line a
    contact, coloured by |f_n|; the GSD export's bonds, read by OVITO: the sphere pairs."""
    import vtk
    from ovito.io import import_file
    from vtk.util.numpy_support import vtk_to_numpy

    trajectory = packings[kind]
    name = trajectory.stem
    result = runner.invoke(
        app, ["export", str(trajectory), "--format", "vtk", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    series = ET.parse(tmp_path / f"{name}.contacts.pvd").getroot()
    files = [d.get("file") for d in series.findall("Collection/DataSet")]
    with h5py.File(trajectory, "r") as f:
        frames = len(f["particles/all/position/step"])
        position = f["particles/all/position/value"][-1]
    assert len(files) == frames
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(tmp_path / files[-1]))
    reader.Update()
    chains = reader.GetOutput()
    contacts = _contacts(trajectory, -1)
    assert chains.GetNumberOfLines() == len(contacts["value"])
    magnitude = vtk_to_numpy(chains.GetCellData().GetArray("normal_force_magnitude"))
    np.testing.assert_array_equal(magnitude, np.linalg.norm(contacts["normal_force"], axis=1))
    ends = vtk_to_numpy(chains.GetPoints().GetData()).reshape(-1, 2, 3)
    np.testing.assert_array_equal(ends[:, 0], position[contacts["value"][:, 0]])
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    with h5py.File(trajectory, "r") as f:
        radius = f["particles/all/radius"][:]
    pairs = contacts["value"][:, 1] >= 0
    i, j = contacts["value"][pairs].T
    np.testing.assert_allclose(
        length[pairs], radius[i] + radius[j] - contacts["overlap"][pairs], rtol=1e-12
    )

    target = tmp_path / "export.gsd"
    result = runner.invoke(
        app, ["export", str(trajectory), "--format", "gsd", "--out", str(target)]
    )
    assert result.exit_code == 0, result.output
    data = import_file(str(target)).compute(frames - 1)
    bonds = np.sort(np.asarray(data.particles.bonds.topology), axis=1)
    np.testing.assert_array_equal(bonds, contacts["value"][pairs])


@pytest.mark.parametrize("kind", ["oedometer", "fcc"])
def test_contact_figures_are_drawn(packings, kind):
    out = packings[kind].parent
    for figure in ("contact_forces", "contact_normals"):
        png = out / f"{packings[kind].name.removesuffix('.forward.h5')}.{figure}.png"
        assert png.stat().st_size > 10_000, png


def test_the_contact_forces_figure_sets_the_reversal_beside_the_state_it_returned_to(tmp_path):
    """The figure set the reversal's end beside the forward run's end, two other states
    (806 against 801 contacts in the oedometer), and said it showed the reversal bringing
    back the starting network. It now draws the forward run at the step the reversal
    returned to too; a reversible run's two lie on each other."""
    from revdem_cli.io.h5md import frame_steps, open_trajectory
    from revdem_cli.report.figures import _normalised_forces

    sets = ["stages.0.steps=400", "stages.1.steps=400", "stages.1.output_every=100"]
    sets += ["output.contacts=true", "output.figures=['contact_forces']"]
    args = ["run", str(CONFIGS / "fcc_triaxial.toml"), "--out", str(tmp_path), "-q"]
    ran = runner.invoke(app, [*args, *(part for item in sets for part in ("--set", item))])
    assert ran.exit_code == 0, ran.output
    forward, reverse = (tmp_path / f"fcc_triaxial.{run}.h5" for run in ("forward", "reverse"))
    with open_trajectory(reverse) as f:
        back = int(frame_steps(f)[-1])
    assert back == 400  # the reversed stage's first step
    there, returned = _normalised_forces(forward, back), _normalised_forces(reverse)
    assert len(there) == len(returned) > 100
    np.testing.assert_allclose(returned, there, rtol=1e-9)
    assert (tmp_path / "fcc_triaxial.contact_forces.png").stat().st_size > 10_000


@pytest.mark.parametrize("fmt", ["gsd", "lammps-dump"])
def test_an_export_is_readable_as_the_other_outputs_are(smoke_run, tmp_path, fmt):
    """The gsd library writes rw-r-----: a .gsd was unreadable to the group's others, where
    every other output follows the umask (rw-r--r-- under 022)."""
    import os

    trajectory = smoke_run / "collision_smoke.forward.h5"
    target = tmp_path / f"out.{fmt}"
    mask = os.umask(0o022)
    try:
        result = runner.invoke(
            app, ["export", str(trajectory), "--format", fmt, "--out", str(target)]
        )
    finally:
        os.umask(mask)
    assert result.exit_code == 0, result.output
    assert target.stat().st_mode & 0o777 == 0o644


def test_gsd_keeps_hoomds_box_convention_in_a_cell_and_for_an_open_system(tmp_path):
    """A sphere that crossed a periodic cell's face lay outside the GSD box, its image flag
    0 (HOOMD-blue refuses such a frame); and an open system's box, periodic to every GSD
    reader, let OVITO find neighbours across it. In the cell every position is now in
    [-L/2, L/2) and position + image L is the unwrapped one; an open system's box is twice
    its bounding box."""
    import gsd.hoomd

    text = (CONFIGS / "smoke" / "collision.yaml").read_text()
    runs = {"open": text}
    runs["cell"] = text.replace("stages:", "cell:\n  size: [0.03, 0.03, 0.03]\nstages:", 1)
    for kind, scenario in runs.items():
        path = tmp_path / f"{kind}.yaml"
        path.write_text(scenario)
        out = tmp_path / kind
        sets = ["--set", "stages.0.steps=40000", "--set", "stages.0.output_every=4000"]
        ran = runner.invoke(app, ["run", str(path), "--out", str(out), "-q", "--no-reverse", *sets])
        assert ran.exit_code == 0, ran.output
        trajectory = out / "collision_smoke.forward.h5"
        target = tmp_path / f"{kind}.gsd"
        assert runner.invoke(app, ["export", str(trajectory), "--format", "gsd", "--out",
                                   str(target)]).exit_code == 0  # fmt: skip
        with h5py.File(trajectory, "r") as f:
            unwrapped = f["particles/all/position/value"][:]
            radius = f["particles/all/radius"][:]
        with gsd.hoomd.open(target) as frames:
            for k, frame in enumerate(frames):
                edges = np.asarray(frame.configuration.box[:3], dtype=np.float64)
                position = frame.particles.position.astype(np.float64)
                image = frame.particles.image
                assert (position >= -edges / 2).all() and (position < edges / 2).all()
                if kind == "cell":
                    np.testing.assert_allclose(edges, 0.03)
                    shifted = position + image * edges + edges / 2
                    np.testing.assert_allclose(shifted, unwrapped[k], rtol=0, atol=1e-8)
                else:
                    assert not image.any()
                    span = (unwrapped + radius[:, None]).max(axis=(0, 1))
                    span -= (unwrapped - radius[:, None]).min(axis=(0, 1))
                    np.testing.assert_allclose(edges, 2 * span, rtol=1e-6)
        if kind == "cell":  # the spheres crossed the cell's faces: the flags are not all 0
            assert image.any()
