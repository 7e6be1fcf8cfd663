"""Hostile input that once crashed revdem (a segmentation fault, a traceback) or slipped past
it: each gets one line and exit status 2 now, and the compiled kernels never see it."""

import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.compare import read_verdict
from revdem_cli.kernels.neighbours import build_pairs
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()
COLLISION = str(CONFIGS / "collision.toml")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_the_pair_search_takes_any_position_without_leaving_its_grid():
    """A cell coordinate beyond the int64 range (1e17 m in cells of 1 cm) once converted to
    a negative index and wrote outside the grid; far, infinite and NaN positions now land in
    the grid's edge cells, and the pairs found are the true ones."""
    x = np.array([[0.0, 0.0, 0.0], [0.009, 0.0, 0.0], [1e17, 0, 0], [1e300, 0, 0], [-1e300, 0, 0]])
    radius = np.full(len(x), 0.005)
    pair_i, pair_j = np.zeros(16, dtype=np.int32), np.zeros(16, dtype=np.int32)
    periodic, length = np.zeros(3, dtype=np.int64), np.ones(3)
    count = build_pairs(x, radius, 5e-4, periodic, length, pair_i, pair_j)
    assert (count, pair_i[0], pair_j[0]) == (1, 0, 1)
    x[2] = [np.nan, np.inf, -np.inf]
    assert build_pairs(x, radius, 5e-4, periodic, length, pair_i, pair_j) == 1


def test_a_position_float64_cannot_resolve_is_refused():
    result = invoke("validate", COLLISION, "--set", "particles.0.position=[1e17,0,0]")
    assert_one_line_error(
        result,
        "particles[0].position: sphere 0 of particles starts 1e+17 m from the origin, where "
        "float64 resolves a position only to 16 m",
    )
    assert_one_line_error(
        invoke("validate", COLLISION, "--set", "particles.1.position=[0,0,-1e300]"),
        "particles[1].position: sphere 1 of particles starts 1e+300 m from the origin",
    )


@pytest.mark.parametrize(
    ("velocity", "fragment"),
    [
        ("[1e5,0,0]", "is 40 times the kinematic limit 2.5e-09 s (the fastest sphere or wall, "
                      "at 1e+05 m/s, would move more than half the neighbour skin"),
        ("[1e10,0,0]", "times the kinematic limit"),
        ("[1e200,0,0]", "is 4e+196 times the kinematic limit 2.5e-204 s"),
        ("[1e300,1e300,0]", "at 1.41e+300 m/s"),
    ],
)  # fmt: skip
def test_a_step_that_jumps_past_contacts_is_refused(velocity, fragment, tmp_path):
    """At 1e10 m/s two spheres once passed through each other in one step and the run said
    "reversible"; at 1e200 m/s the guard's v² overflowed and the run crashed."""
    result = invoke(
        "run", COLLISION, "--out", tmp_path, "-q", "--set", f"particles.0.velocity={velocity}"
    )
    assert_one_line_error(result, "integrator.dt = 1e-07 s", fragment)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["validate", "run", "sweep"])
def test_setting_a_field_inside_a_value_is_one_line(command, tmp_path):
    args = ["--out", tmp_path] if command != "validate" else []
    value = "1,2" if command == "sweep" else "1"
    result = invoke(command, COLLISION, *args, "--set", f"integrator.dt.x={value}")
    assert_one_line_error(result, "--set integrator.dt.x: 'dt' holds a value, not a table")


def test_a_yaml_key_given_twice_is_refused(tmp_path):
    text = (CONFIGS / "smoke" / "collision.yaml").read_text()
    path = tmp_path / "twice.yaml"
    path.write_text(text + "name: another\n")
    assert_one_line_error(invoke("validate", path), "the key 'name' is given twice")


@pytest.mark.parametrize("suffix", [".toml", ".yaml"])
def test_a_file_nested_without_end_is_refused(suffix, tmp_path):
    path = tmp_path / f"deep{suffix}"
    separator = " = " if suffix == ".toml" else ": "
    path.write_text("name" + separator + "[" * 50000 + "]" * 50000 + "\n")
    assert_one_line_error(invoke("validate", path), f"{path}: nested more than 64 levels deep")


@pytest.mark.parametrize(
    ("size", "fragment"),
    [
        ("1e-300 1e-300 1e-300", "--semi-axes with --density 1000: the ellipsoid's volume"),
        ("1e300 1e300 1e300", "--semi-axes with --density 1000: the ellipsoid's volume"),
        ("1e200 1 1", "are not all positive finite float64 numbers"),
        ("3 2 1e-300", "outside float64's range in the criteria"),
    ],
)
def test_dt_of_a_particle_float64_cannot_hold_is_one_line(size, fragment):
    """These once ended in ZeroDivisionError and OverflowError tracebacks."""
    args = ["dt", "--shape", "ellipsoid", "--semi-axes", *size.split(), "--density", "1000"]
    assert_one_line_error(invoke(*args, "--kn", "1e10"), fragment)


def test_a_polyhedron_scaled_out_of_float64_is_one_line(tmp_path):
    corners = [[sx * 1e-300, sy * 1e-300, sz * 1e-300] for sx in (-1, 1) for sy in (-1, 1)
               for sz in (-1, 1)]  # fmt: skip
    path = tmp_path / "cube.txt"
    path.write_text("\n".join(" ".join(str(v) for v in c) for c in corners))
    result = invoke(
        "dt", "--shape", "polyhedron", "--vertices", path, "--density", "1", "--kn", "1"
    )
    assert_one_line_error(result, "--vertices with --density 1: the polyhedron's volume")


def test_a_sweep_of_a_hundred_million_values_is_refused():
    args = ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "1000", "--kn", "1e5"]
    result = invoke(*args, "--sweep", "kn=1:2:100000000")
    assert_one_line_error(result, "COUNT must be between 1 and 10000")


@pytest.mark.parametrize("arguments", [["run", COLLISION, "--bogus"], ["bogus"], ["run", "--out"]])
def test_a_usage_error_is_one_line(arguments):
    result = invoke(*arguments)
    assert_one_line_error(result, "(see revdem")


def test_an_empty_out_is_refused_not_read_as_here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("run", COLLISION, "--out", "", "-q")
    assert_one_line_error(result, "Invalid value for '--out': an empty path")
    assert not list(tmp_path.iterdir())
    # dt --figures "" wrote its 13 figures here; --restart "" read "." as a restart
    for option in ("--figures", "--restart"):
        assert_one_line_error(invoke("dt", option, ""), f"'{option}': an empty path")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("what", ["validate", "info", "reverse", "dt"])
def test_a_fifo_is_refused_at_once(what, tmp_path):
    """Reading a FIFO once blocked for ever, waiting for a writer."""
    import os

    fifo = tmp_path / "pipe.h5"
    os.mkfifo(fifo)
    args = {"validate": ["validate", fifo], "info": ["info", fifo], "reverse": ["reverse", fifo],
            "dt": ["dt", "--restart", fifo]}[what]  # fmt: skip
    assert_one_line_error(invoke(*args), "not a regular file: a FIFO, socket or device")


def test_a_symbolic_link_at_an_output_is_not_written_through(tmp_path):
    out, outside = tmp_path / "out", tmp_path / "outside.h5"
    out.mkdir()
    link = out / "collision.forward.h5"
    link.symlink_to(outside)
    args = ["run", COLLISION, "--out", out, "-q", "--set", "stages.0.steps=100"]
    assert_one_line_error(invoke(*args), f"{link}: exists (a symbolic link)")
    assert invoke(*args, "--force").exit_code == 0
    assert not outside.exists() and not link.is_symlink() and link.is_file()


def test_a_run_beside_another_runs_checkpoint_is_refused(tmp_path):
    (tmp_path / "oedometer.checkpoint.h5").write_bytes(b"")
    for force in ([], ["--force"]):
        result = invoke("run", COLLISION, "--out", tmp_path, "-q", *force)
        assert_one_line_error(result, "the checkpoint of another unfinished run")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["oedometer.checkpoint.h5"]


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """The collision, 200 steps each way, run twice into two folders."""
    folders = []
    for name in ("a", "b"):
        out = tmp_path_factory.mktemp(name)
        args = ["run", COLLISION, "--out", out, "-q", "--set", "stages.0.steps=200"]
        assert invoke(*args).exit_code == 0
        folders.append(out)
    return folders


def test_a_comparison_takes_a_forward_run_and_its_own_reversal(two_runs, tmp_path):
    """Once a file compared with itself was "reversible, bitwise identical", and two unrelated
    runs were diagnosed as round-off growth. A reversal is the forward run's whose restart
    holds its last frame: the same run made twice (revdem is deterministic) or its folder
    copied or moved (which keeps the paths it was written with, and was refused)."""
    import shutil

    import h5py

    a, b = two_runs
    forward, reverse = a / "collision.forward.h5", a / "collision.reverse.h5"
    assert_one_line_error(invoke("compare", forward, forward), "compared with itself")
    assert_one_line_error(invoke("compare", reverse, forward), "these are reverse and forward")
    assert invoke("compare", forward, b / "collision.reverse.h5").exit_code == 0
    copy = tmp_path / "copied"
    shutil.copytree(a, copy)
    result = invoke("compare", copy / "collision.forward.h5", copy / "collision.reverse.h5")
    assert result.exit_code == 0, result.output
    with h5py.File(copy / "collision.forward.h5", "r+") as f:  # another last frame
        f["particles/all/position/value"][-1, 0, 0] += 1e-9
    other = copy / "collision.forward.h5"
    assert_one_line_error(
        invoke("compare", other, reverse),
        f"{other}: not the forward run that {reverse} reverses",
        f"ends the forward run {forward}; {other} holds no frame at step 200 with the "
        "restart's state",
    )
    result = invoke("compare", forward, reverse, "--json")
    assert result.exit_code == 0
    assert '"pairing": ' in result.output and "the restart that ends" in result.output


def test_a_pair_moved_away_is_not_judged_by_a_later_run_where_it_was_made(tmp_path):
    """A forward run and its reversal copied elsewhere without their restart, and their
    folder then reused for a run of other settings: the restart found where the reversal
    was written belongs to that run, and refused the pair as not each other's."""
    made, lone = tmp_path / "made", tmp_path / "lone"
    args = ["run", COLLISION, "--out", made, "-q", "--set", "stages.0.steps=200"]
    assert invoke(*args).exit_code == 0
    lone.mkdir()
    for kind in ("forward", "reverse"):
        (lone / f"collision.{kind}.h5").write_bytes((made / f"collision.{kind}.h5").read_bytes())
    assert invoke(*args[:-1], "stages.0.steps=300", "--force").exit_code == 0
    result = invoke("compare", lone / "collision.forward.h5", lone / "collision.reverse.h5")
    assert result.exit_code == 0, result.output


def test_a_comparison_of_runs_of_other_settings_is_refused(two_runs, tmp_path):
    out = tmp_path / "c"
    args = ["run", COLLISION, "--out", out, "-q", "--set", "stages.0.steps=100"]
    assert invoke(*args).exit_code == 0
    result = invoke("compare", two_runs[0] / "collision.forward.h5", out / "collision.reverse.h5")
    assert_one_line_error(
        result, "runs of different scenarios (or of other --set): stages.0.steps = 200 and 100"
    )


def test_a_restart_whose_forward_run_was_replaced_is_refused_before_reversing(tmp_path):
    """A restart kept from a run whose folder was then reused for a run of other settings:
    its reversal ran every step, then its comparison refused the pair and left a reversed
    trajectory with no verdict. It is refused before its first step now, nothing written;
    the restart of the run there still reverses."""
    made, kept = tmp_path / "made", tmp_path / "kept.restart.h5"
    args = ["run", COLLISION, "--out", made, "-q", "--no-reverse", "--set", "stages.0.steps=200"]
    assert invoke(*args).exit_code == 0
    kept.write_bytes((made / "collision.restart.h5").read_bytes())
    assert invoke(*args[:-1], "stages.0.steps=300", "--force").exit_code == 0
    result = invoke("reverse", kept, "-q", "--out", tmp_path / "reversed")
    forward = (made / "collision.forward.h5").resolve()
    assert_one_line_error(
        result,
        f"{kept}: the forward trajectory it names, {forward}, is of another run: runs of "
        "different scenarios (or of other --set): stages.0.steps = 200 and 300",
    )
    assert not (tmp_path / "reversed").exists()
    result = invoke("reverse", made / "collision.restart.h5", "-q", "--out", tmp_path / "own")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "own" / "collision.compare.json").exists()


def test_a_restart_moved_with_its_forward_run_reverses_and_compares_with_it(tmp_path):
    """A run's folder moved keeps the path its restart names the forward trajectory by: the
    reversal said "no comparison", the trajectory beside the restart unlooked at. It is
    taken where the restart ends the run it holds (one of another run is refused, as where
    the restart names it), and where none is there, the places looked at are named."""
    made, moved, other = tmp_path / "made", tmp_path / "moved", tmp_path / "other"
    for out, steps in ((made, 200), (other, 300)):
        args = ["--out", out, "-q", "--no-reverse", "--set", f"stages.0.steps={steps}"]
        assert invoke("run", COLLISION, *args).exit_code == 0
    made.rename(moved)
    restart = moved / "collision.restart.h5"
    result = invoke("reverse", restart, "-q")
    assert result.exit_code == 0, result.output
    assert "no comparison" not in result.output
    assert read_verdict(moved / "collision.compare.json")["reversible"]
    (moved / "collision.forward.h5").unlink()
    result = invoke("reverse", restart, "-q", "--force")
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "no comparison" in said
    for path in (made.resolve(), moved.resolve()):
        assert str(path / "collision.forward.h5") in said
    (moved / "collision.forward.h5").write_bytes((other / "collision.forward.h5").read_bytes())
    result = invoke("reverse", restart, "-q", "--force")
    assert_one_line_error(
        result,
        f"{restart}: the forward trajectory it names, {made.resolve() / 'collision.forward.h5'}, "
        f"is not there; and {moved / 'collision.forward.h5'} beside it is of another run",
        "stages.0.steps = 200 and 300",
    )


def test_a_forced_run_that_fails_leaves_none_of_the_earlier_runs_files(tmp_path):
    """A forced run removes the earlier outputs before it starts: one that then blows up
    leaves its own files only, not the earlier verdict beside them."""
    args = ["run", COLLISION, "--out", tmp_path, "-q", "--set", "stages.0.steps=200"]
    assert invoke(*args).exit_code == 0
    assert (tmp_path / "collision.compare.json").exists()
    refused = invoke(*args, "--force", "--set", "integrator.dt=1e-3")  # input: nothing removed
    assert_one_line_error(refused, "times the critical time step")
    assert (tmp_path / "collision.compare.json").exists()
    failed = invoke(*args, "--force", "--set", "integrator.dt=1e-3", "--allow-unstable-dt")
    assert failed.exit_code == 1 and "blown up" in failed.output
    assert not (tmp_path / "collision.compare.json").exists()
    assert invoke("info", tmp_path / "collision.forward.h5").exit_code == 0


SMOKE = str(CONFIGS / "smoke" / "collision.yaml")


@pytest.mark.parametrize(
    ("arguments", "fragment"),
    [
        (["run", SMOKE, "--out", "{file}/sub"], "{file}/sub: {file} is a file, not a folder"),
        (["run", SMOKE, "--out", "{file}"], "{file}: a file, not a folder"),
        (["dt", "--figures", "{file}/x"], "{file}/x: {file} is a file, not a folder"),
    ],
    ids=["run-under-a-file", "run-into-a-file", "dt-figures"],
)  # fmt: skip
def test_an_output_path_through_a_file_is_one_line(arguments, fragment, tmp_path):
    """A path given that cannot be used (a file where a folder is to be made) is bad input:
    one line naming it and what is in the way, exit status 2, and the file left alone."""
    file = tmp_path / "afile"
    file.write_text("kept\n")
    result = invoke(*(a.format(file=file) for a in arguments))
    assert_one_line_error(result, fragment.format(file=file))
    assert file.read_text() == "kept\n"


def test_resuming_from_no_folder_or_a_file_is_one_line_with_progress_shown(tmp_path):
    """Without -q too: the progress display, never started, adds no blank line."""
    (tmp_path / "afile").write_text("kept\n")
    command = [sys.executable, "-m", "revdem_cli.cli", "run", "--resume", str(tmp_path / "none")]
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == f"error: --resume {tmp_path / 'none'}: no such directory\n"
    result = invoke("run", "--resume", tmp_path / "afile")
    assert_one_line_error(result, "afile: a file, not the folder of a run")


def test_a_field_set_twice_on_the_command_line_is_refused_not_cut_to_its_last_value():
    first, second = "integrator.dt=1e-7", "integrator.dt=2e-7"
    result = invoke("validate", COLLISION, "--set", first, "--set", second)
    assert_one_line_error(
        result, f"--set {second}: integrator.dt is given twice (also --set {first})"
    )


def test_too_few_values_of_a_vector_option_say_how_many_it_takes():
    """`--semi-axes 3 2 --density 1000` took `--density` as the third semi-axis and said
    only that it is not a number."""
    result = invoke("dt", "--shape", "ellipsoid", "--semi-axes", "3", "2", "--density", "1000")
    assert_one_line_error(result, "'--semi-axes'", "(--semi-axes takes 3 values)")


def test_a_threading_layer_numba_does_not_know_is_one_line():
    """NUMBA_THREADING_LAYER=bogus printed numba's 54-line traceback, exit 1."""
    import os
    import subprocess
    import sys

    env = os.environ | {"NUMBA_THREADING_LAYER": "bogus"}
    command = [sys.executable, "-m", "revdem_cli.cli", "info", "--system"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        "error: NUMBA_THREADING_LAYER bogus: The threading layer requested 'bogus' is unknown "
        "to Numba."
    ]


def test_a_sweep_of_one_value_from_start_to_another_stop_is_refused():
    """`kn=1e6:1e7:1` dropped STOP and gave the one row at START."""
    args = ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "1000"]
    result = invoke(*args, "--sweep", "kn=1e6:1e7:1")
    assert_one_line_error(result, "--sweep 'kn=1e6:1e7:1': COUNT 1 takes START alone")
    assert invoke(*args, "--sweep", "kn=1e6:1e6:1").exit_code == 0
