"""Damaged and foreign files: `revdem reverse`, `compare`, `info` and `export` given a
truncated file, a file of another program, a file of another schema version or a restart whose
stored scenario was edited each print one line naming the file and exit with status 2, and
write nothing. Truncations and overwritten bytes are generated (hypothesis, derandomized)."""

import json
import shutil
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.io import SCHEMA_VERSION
from revdem_cli.io.restart import seal
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()
NAME = "collision_smoke"
COMMANDS = ("reverse", "compare", "info", "export")

SETTINGS = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """The YAML collision, 200 steps each way: its forward, restart and reversed files."""
    out = tmp_path_factory.mktemp("run")
    args = ["run", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(out), "-q"]
    result = runner.invoke(app, [*args, "--set", "stages.0.steps=200"])
    assert result.exit_code == 0, result.output
    return out


def invoke(command: str, path: Path, run: Path, out: Path):
    """`revdem COMMAND` on `path` (compare: against the run's reversed trajectory), writing
    into `out` where the command writes."""
    args = {
        "reverse": ["reverse", path, "--out", out, "-q"],
        "compare": ["compare", path, run / f"{NAME}.reverse.h5"],
        "info": ["info", path],
        "export": ["export", "--vtk", path, "--out", out, "-q"],
    }[command]
    return runner.invoke(app, [str(a) for a in args])


def refused(command: str, path: Path, run: Path, *fragments: str) -> None:
    """The command exits 2 with one line naming `path` and the fragments, writing nothing."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "out"
        result = invoke(command, path, run, out)
        assert_one_line_error(result, f"error: {path}: ", *fragments)
        assert not out.exists()


def copy(run: Path, kind: str, folder: Path, name: str = "") -> Path:
    """A copy of the run's `kind` file (forward, reverse, restart) in `folder`."""
    path = folder / (name or f"{NAME}.{kind}.h5")
    shutil.copy(run / f"{NAME}.{kind}.h5", path)
    return path


def _attrs(f: h5py.File):
    return f["revdem"].attrs if "revdem" in f else f["parameters/revdem"].attrs


def edited(path: Path, change) -> Path:
    """`path` with its stored scenario (JSON) changed by change(dict)."""
    with h5py.File(path, "r+") as f:
        scenario = json.loads(_attrs(f)["scenario_json"])
        change(scenario)
        _attrs(f)["scenario_json"] = json.dumps(scenario)
    return path


@pytest.mark.parametrize("command", COMMANDS)
def test_a_text_file_and_a_missing_file(command, run, tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("forward trajectory, to be written\n")
    refused(command, text, run, "not a readable HDF5 file (not HDF5)")
    refused(command, tmp_path / "missing.h5", run, "not a readable HDF5 file (no such file)")


@pytest.mark.parametrize("command", COMMANDS)
def test_an_hdf5_file_of_another_program(command, run, tmp_path):
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["results/table"] = np.arange(10.0)
        f.create_group("metadata").attrs["program"] = "other"
    message = {
        "reverse": "not a revdem restart file (no /revdem group)",
        "info": "not a revdem trajectory, restart, tape or sweep table",
    }.get(command, "not a revdem trajectory (no /parameters/revdem)")
    refused(command, plain, run, message)


@pytest.mark.parametrize("command", ["compare", "export"])
def test_an_h5md_file_of_another_program(command, run, tmp_path):
    other = tmp_path / "lammps.h5"
    with h5py.File(other, "w") as f:
        f.create_group("h5md/creator").attrs["name"] = "LAMMPS"
        f["particles/all/position/value"] = np.zeros((2, 2, 3))
        f["particles/all/position/step"] = [0, 1]
    refused(command, other, run, "not a revdem trajectory (an H5MD file written by LAMMPS)")


def test_a_restart_where_a_trajectory_belongs_and_the_other_way_round(run, tmp_path):
    refused("compare", run / f"{NAME}.restart.h5", run, "not a revdem trajectory (a revdem restart")
    refused("export", run / f"{NAME}.restart.h5", run, "not a revdem trajectory (a revdem restart")
    refused("reverse", run / f"{NAME}.forward.h5", run, "not a revdem restart file (a revdem traj")


@pytest.mark.parametrize("version", [1, SCHEMA_VERSION + 1])
@pytest.mark.parametrize("kind", ["restart", "forward"])
def test_another_schema_version(kind, version, run, tmp_path):
    path = copy(run, kind, tmp_path)
    with h5py.File(path, "r+") as f:
        _attrs(f)["schema_version"] = version
    what = "restart" if kind == "restart" else "trajectory"
    message = f"{what} schema version {version}, this revdem reads {SCHEMA_VERSION}"
    for command in ("reverse", "info") if kind == "restart" else ("compare", "info", "export"):
        refused(command, path, run, message)


def test_a_file_without_a_schema_version(run, tmp_path):
    path = copy(run, "forward", tmp_path)
    with h5py.File(path, "r+") as f:
        del _attrs(f)["schema_version"]
    refused("info", path, run, "damaged revdem file (a trajectory without a schema version)")


def _negative_radius(scenario):
    scenario["particles"][1]["radius"] = -0.005


def _third_particle(scenario):
    scenario["particles"].append(dict(scenario["particles"][0], position=[0.0, 0.1, 0.0]))


def _renamed_stage(scenario):
    scenario["stages"][0]["name"] = "other"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_negative_radius, "stored scenario: particles[1].radius: Input should be greater than 0"),
        (_third_particle, "particles/x: 2 spheres, but the stored scenario has 3"),
        (_renamed_stage, "revdem/stage: its stored scenario has no stage named 'collide'"),
    ],
)
def test_a_restart_whose_stored_scenario_was_edited(change, message, run, tmp_path):
    path = edited(copy(run, "restart", tmp_path), change)
    refused("reverse", path, run, message)
    refused("info", path, run, message.replace("particles/x", "particles/x"))


def test_a_restart_whose_stored_scenario_is_not_json(run, tmp_path):
    path = copy(run, "restart", tmp_path)
    with h5py.File(path, "r+") as f:
        f["revdem"].attrs["scenario_json"] = '{"name": "collision_smoke", '
    refused("reverse", path, run, "stored scenario: Invalid JSON")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_negative_radius, "stored scenario: particles[1].radius: Input should be greater than 0"),
        (_third_particle, "particles/all/radius: 2 spheres, but the stored scenario has 3"),
    ],
)
def test_a_trajectory_whose_stored_scenario_was_edited(change, message, run, tmp_path):
    path = edited(copy(run, "forward", tmp_path), change)
    for command in ("compare", "info", "export"):
        refused(command, path, run, message)


def test_a_reversal_whose_forward_trajectory_is_damaged_is_refused_before_it_runs(run, tmp_path):
    restart = copy(run, "restart", tmp_path)
    forward = tmp_path / "forward.h5"
    forward.write_bytes((run / f"{NAME}.forward.h5").read_bytes()[:5000])
    with h5py.File(restart, "r+") as f:
        f["revdem"].attrs["trajectory"] = str(forward)
        seal(f["revdem"])  # moved on purpose: its checksum recomputed
    out = tmp_path / "out"
    result = runner.invoke(app, ["reverse", str(restart), "--out", str(out), "-q"])
    assert_one_line_error(result, f"error: {forward}: not a readable HDF5 file (truncated: 5000 ")
    assert not out.exists()


TRAJECTORY_READERS = ("compare", "info", "export")


@pytest.mark.parametrize(
    ("kind", "dataset", "commands"),
    [
        ("forward", "particles/all/velocity/value", TRAJECTORY_READERS),
        ("forward", "particles/all/radius", TRAJECTORY_READERS),
        ("forward", "particles/all/position/step", TRAJECTORY_READERS),
        ("restart", "pairs/i", ("reverse", "info")),
        ("restart", "particles/x", ("reverse", "info")),
        ("restart", "particles/v", ("reverse",)),  # info does not read velocities
        ("restart", "walls/history", ("reverse",)),
    ],
)
def test_a_missing_dataset(kind, dataset, commands, run, tmp_path):
    path = copy(run, kind, tmp_path)
    with h5py.File(path, "r+") as f:
        del f[dataset]
    for command in commands:
        refused(command, path, run, "damaged revdem", f"(no dataset {dataset})")


def test_frames_missing_from_one_series(run, tmp_path):
    path = copy(run, "forward", tmp_path)
    with h5py.File(path, "r+") as f:
        f["particles/all/force/value"].resize(2, axis=0)  # of 5 frames
    for command in ("compare", "info", "export"):
        refused(command, path, run, "damaged revdem trajectory (particles/all/force/value holds")


@SETTINGS
@given(data=st.data())
def test_a_truncated_file_is_refused_by_every_command(run, tried, data):
    kind = data.draw(st.sampled_from(["forward", "restart"]))
    command = data.draw(st.sampled_from(COMMANDS))
    whole = (run / f"{NAME}.{kind}.h5").read_bytes()
    cut = data.draw(st.integers(0, len(whole) - 1))
    tried["truncated file"] = tried.get("truncated file", 0) + 1
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{NAME}.{kind}.h5"
        path.write_bytes(whole[:cut])
        expected = "truncated: " if cut >= 512 else ""  # a start too short to name its length
        refused(command, path, run, "not a readable HDF5 file (", expected)


@SETTINGS
@given(data=st.data())
def test_overwritten_bytes_give_a_result_or_one_line(run, tried, data):
    """Bytes overwritten anywhere: the command works (the damage hit numbers, which HDF5
    does not check) or exits 2 with one line naming the file; never a traceback."""
    kind = data.draw(st.sampled_from(["forward", "restart"]))
    command = data.draw(st.sampled_from(["info", "compare", "export"]))
    whole = bytearray((run / f"{NAME}.{kind}.h5").read_bytes())
    at = data.draw(st.integers(0, len(whole) - 1))
    junk = data.draw(st.binary(min_size=1, max_size=64))
    whole[at : at + len(junk)] = junk
    tried["overwritten bytes"] = tried.get("overwritten bytes", 0) + 1
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{NAME}.{kind}.h5"
        path.write_bytes(bytes(whole))
        result = invoke(command, path, run, Path(folder) / "out")
        assert result.exit_code in (0, 2), (result.output, result.exception)
        if result.exit_code == 2:
            assert_one_line_error(result, f"error: {path}: ")


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("{bad", "not a revdem comparison (Expecting property name"),
        ("[1, 2]", "not a revdem comparison (not a JSON object)"),
        ("{}", "not a revdem comparison (no reversible, bitwise_identical"),
    ],
    ids=["not-json", "a-list", "empty"],
)
def test_a_damaged_verdict_beside_a_trajectory_is_named(run, tmp_path, text, why):
    """`info` on a trajectory and `report` on its folder read the NAME.compare.json beside
    it: a damaged one is named in one line, not taken for the trajectory nor for no run."""
    trajectory = copy(run, "forward", tmp_path)
    verdict = tmp_path / f"{NAME}.compare.json"
    verdict.write_text(text)
    assert_one_line_error(runner.invoke(app, ["info", str(trajectory)]), f"{verdict}: {why}")
    paper = tmp_path / "paper.toml"
    paper.write_text(f'[{NAME}]\nconfig = "c.yaml"\nreversible = true\n')
    report = ["report", str(tmp_path), "--paper", str(paper), "--out", str(tmp_path / "r.md")]
    assert_one_line_error(runner.invoke(app, report), f"{verdict}: {why}")
    assert not (tmp_path / "r.md").exists()


@pytest.mark.parametrize("command", ["compare", "export"])
@pytest.mark.parametrize("field", ["position", "velocity"])
def test_a_frame_not_finite_is_damage(run, tmp_path, command, field):
    """A run writes no frame that is not finite (`kernels.health` stops it first), so one is
    damage: `compare` passed a NaN error as within tolerance ("reversible") and an export
    carried it into every frame's box."""
    path = copy(run, "forward", tmp_path)
    with h5py.File(path, "r+") as f:
        values = f[f"particles/all/{field}/value"]
        frames = values[()]
        frames[3, 1, 0] = np.nan
        values[...] = frames
        step = int(f[f"particles/all/{field}/step"][3])
    refused(command, path, run, f"{field} of particle 1 (id 2) at step {step} is not finite")
