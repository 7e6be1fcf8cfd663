"""`revdem info`: a summary of any revdem file, one line and exit 2 for anything else."""

import json
from pathlib import Path

import h5py
import numpy as np
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import assert_one_line_error

runner = CliRunner()


def info(*args):
    return runner.invoke(app, ["info", *map(str, args)])


def test_a_forward_trajectory_shows_its_run_and_the_reversal_verdict(smoke_run):
    result = info(smoke_run / "collision_smoke.forward.h5")
    assert result.exit_code == 0, result.output
    assert "trajectory (forward)" in result.output
    assert "collision_smoke" in result.output
    assert "frames:     21, steps 0 to 1000" in result.output
    assert "reversal:   reversible" in result.output


def test_the_trajectory_of_a_stopped_run_says_so_and_how_to_go_on(tmp_path, smoke_run):
    """A killed run's trajectory showed its frames as a whole run's; its checkpoint beside
    it now says that the run is unfinished, and how to continue it. A finished run's does
    not (the smoke run above)."""
    from revdem_cli import api as revdem
    from tests.conftest import CONFIGS, crashed_after

    experiment = revdem.load(CONFIGS / "smoke" / "collision.yaml").changed(
        {"output.checkpoint_interval": 0.0}
    )
    crashed_after(experiment, tmp_path, 5)
    result = info(tmp_path / "collision_smoke.forward.h5")
    assert result.exit_code == 0, result.output
    assert (
        f"unfinished: {tmp_path / 'collision_smoke.checkpoint.h5'} is beside it (the run "
        f"stopped, or goes on); continue with revdem run --resume {tmp_path}"
    ) in result.output
    summary = json.loads(info(tmp_path / "collision_smoke.forward.h5", "--json").stdout)
    assert summary["checkpoint"] == str(tmp_path / "collision_smoke.checkpoint.h5")
    assert "unfinished" not in info(smoke_run / "collision_smoke.forward.h5").output


def test_a_trajectory_with_no_frames_says_none_were_written(tmp_path):
    """A run killed before its first frame leaves a trajectory of none: info printed
    'frames:     0, steps None to None'."""
    from revdem_cli.config import load_scenario
    from revdem_cli.engine import _writer
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state
    from tests.conftest import CONFIGS

    scenario, text = load_scenario(CONFIGS / "smoke" / "collision.yaml")
    path = tmp_path / "collision_smoke.forward.h5"
    _writer(path, initial_state(scenario), Model.of(scenario), text, "forward").close()
    shown = info(path).output.splitlines()
    assert "frames:     0 (none written)" in shown
    assert any(line.endswith("(it failed, or was stopped at once): it wrote no frame")
               for line in shown)  # fmt: skip
    summary = json.loads(info(path, "--json").stdout)
    assert (summary["frames"], summary["first_step"], summary["last_step"]) == (0, None, None)


def test_a_verdict_beside_a_trajectory_is_shown_only_where_it_compared_that_trajectory(
    smoke_run, tmp_path
):
    """Another run's NAME.compare.json copied beside a trajectory had its verdict shown as
    the trajectory's ("not reversible, the runs part at step 36250" of a run of 1000 steps).
    A verdict is shown where its pairing names the trajectory; else info says it compares
    other files."""
    import shutil

    forward = Path(shutil.copy(smoke_run / "collision_smoke.forward.h5", tmp_path))
    verdict = json.loads((smoke_run / "collision_smoke.compare.json").read_text())
    other = (
        "oedometer_smoke.reverse.h5 reverses oedometer_smoke.restart.h5, the restart that "
        "ends oedometer_smoke.forward.h5"
    )
    verdict |= {"reversible": False, "first_divergence_step": 36250, "pairing": other}
    (tmp_path / "collision_smoke.compare.json").write_text(json.dumps(verdict))
    shown = info(forward).output.splitlines()
    assert not any("36250" in line for line in shown)
    assert (
        "reversal:   not known: collision_smoke.compare.json beside it compares other files "
        f"({other})"
    ) in shown
    summary = json.loads(info(forward, "--json").stdout)
    assert "comparison" not in summary
    assert summary["comparison_of_other_files"]["pairing"] == other
    for name in ("forward", "reverse"):  # the run's own verdict, beside its trajectories
        assert "reversal:   reversible" in info(smoke_run / f"collision_smoke.{name}.h5").output


def test_info_of_a_file_and_of_the_system_is_asked_for_apart(smoke_run):
    result = info("--system", smoke_run / "collision_smoke.forward.h5")
    assert_one_line_error(result, "info: --system describes this machine", "separately")


def test_json_summary_of_a_reversed_trajectory(smoke_run):
    result = info(smoke_run / "collision_smoke.reverse.h5", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["kind"] == "trajectory" and summary["direction"] == "reverse"
    assert (summary["first_step"], summary["last_step"], summary["frames"]) == (1000, 0, 21)
    assert summary["particles"] == 2
    assert summary["stages"] == [
        {
            "name": "collide",
            "steps": 1000,
            "dt": 1e-7,
            "output_every": 50,
            "reverse": True,
            "stop_when": None,
        }
    ]
    assert summary["comparison"]["reversible"] is True


def test_a_restart_shows_its_step_and_trajectory(smoke_run):
    result = info(smoke_run / "collision_smoke.restart.h5", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["kind"] == "restart" and summary["step"] == 1000
    assert summary["trajectory"].endswith("collision_smoke.forward.h5")
    assert "comparison" not in summary


def test_other_files_exit_2_with_one_line(smoke_run, tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("not hdf5")
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["data"] = [1, 2, 3]
    damaged = tmp_path / "damaged.h5"
    with h5py.File(damaged, "w") as f:
        f.create_group("parameters/revdem")
        f["particles/all/position/value"] = [[[0.0, 0.0, 0.0]]]
    for path, message in (
        (text, "not a readable HDF5 file"),
        (foreign, "not a revdem trajectory, restart, tape or sweep table"),
        (damaged, "damaged revdem file"),
        (tmp_path / "missing.h5", "not a readable HDF5 file"),
    ):
        result = info(path)
        assert result.exit_code == 2, result.output
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {path}: {message}"), lines


def test_each_stage_shows_its_own_time_step():
    """The oedometer's first three stages run at 1e-5 s, the last at integrator.dt, 1e-6 s."""
    from revdem_cli.config import load_scenario
    from revdem_cli.report.info import _scenario, info_lines

    scenario, _ = load_scenario("configs/smoke/oedometer.toml")
    summary = _scenario(scenario.model_dump_json())
    assert [stage["dt"] for stage in summary["stages"]] == [1e-5, 1e-5, 1e-5, 1e-6]
    lines = info_lines(
        summary | {"file": "x.h5", "kind": "restart", "particles": 300, "step": 1, "stage": "pour",
                   "stage_dt": 1e-5, "trajectory": "x.forward.h5", "direction": "forward"}
    )  # fmt: skip
    shown = "\n".join(lines)  # a stage with a stop condition may end early: says so
    assert "pour (at most 200000 steps of 1e-05 s, until kinetic_energy_below 1e-06)" in shown
    assert "close (at most 60000 steps of 1e-05 s, until solid_fraction_above 0.606)" in shown
    assert "step:       1 (end of stage pour, dt 1e-05 s)" in lines


def test_a_stage_of_automatic_time_step_says_so():
    from revdem_cli.config import load_scenario
    from revdem_cli.report.info import _scenario, info_lines

    scenario, _ = load_scenario("configs/smoke/oedometer.toml", ["stages.3.dt=auto"])
    summary = _scenario(scenario.model_dump_json())
    lines = info_lines(
        summary | {"file": "x.h5", "kind": "trajectory", "direction": "forward", "particles": 300,
                   "frames": 2, "first_step": 0, "last_step": 1}
    )  # fmt: skip
    assert "compress (" in lines[3] and "steps of dt chosen at its start, reversed)" in lines[3]


def test_frames_read_at_once_are_the_frames_read_one_by_one(smoke_run):
    """`read_frames`, which the comparison reads a block of frames with, in any order, dense
    (one slab) or sparse (the rows alone), gives each frame `read_frame` gives."""
    from revdem_cli.io.h5md import open_trajectory, read_frame, read_frames

    with open_trajectory(smoke_run / "collision_smoke.forward.h5") as f:
        count = len(f["particles/all/position/step"])
        for indices in ([3, 4, 5, 6], [6, 5, 4, 3], [0, count - 1], [count - 1, 2, 7], []):
            got = read_frames(f, "velocity", np.array(indices, dtype=np.int64))
            assert got.shape == (len(indices), 2, 3)
            for row, index in zip(got, indices, strict=True):
                assert np.array_equal(row, read_frame(f, "velocity", index))


def test_a_fixed_point_trajectory_shows_its_grids(tmp_path, smoke_run):
    """The grids come from the whole run's duration, so shortening a later stage can change
    an earlier one's rounding; `info` did not show them. Each step is the trajectory's own,
    and a floating-point run has none."""
    from tests.conftest import CONFIGS

    out = tmp_path / "fixed"
    args = ["run", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(out), "-q"]
    fixed = runner.invoke(app, [*args, "--no-reverse", "--set", "integrator.arithmetic=fixed"])
    assert fixed.exit_code == 0, fixed.output
    path = out / "collision_smoke.forward.h5"
    with h5py.File(path) as f:
        x, _, _, v, w, force, moment, edge, rate = f["parameters/revdem"].attrs["fixed_grid"]
    shown = info(path).output
    assert (
        f"grids:      position {x:.3g} {x:.3g} {x:.3g} (m, or of the edge in a deforming "
        f"cell), velocity {v:.3g} m/s, angular velocity {w:.3g} rad/s, force {force:.3g} N, "
        f"moment {moment:.3g} N m, edge {edge:.3g} m, edge rate {rate:.3g} m/s"
    ) in shown
    assert json.loads(info(path, "--json").stdout)["grids"][3] == v
    assert "grids:" not in info(smoke_run / "collision_smoke.forward.h5").output


def test_a_moving_cell_is_shown_where_each_file_has_it(tmp_path):
    """`info` of a trajectory or restart gave the cell the scenario starts with, though the
    servo had moved it (0.06 m against the frames' 0.046 m): a trajectory's at its first
    and last frames, a restart's as its state has it."""
    from tests.conftest import CONFIGS

    out = tmp_path / "shear"
    args = ["run", str(CONFIGS / "smoke" / "critical_state.toml"), "--out", str(out), "-q"]
    sets = [f"stages.{k}.steps=400" for k in range(3)] + ["stages.2.output_every=200"]
    ran = runner.invoke(app, [*args, *(part for item in sets for part in ("--set", item))])
    assert ran.exit_code == 0, ran.output
    name = "critical_state_smoke"
    with h5py.File(out / f"{name}.reverse.h5") as f:
        edges = f["particles/all/box/edges/value"][:]
        steps = f["particles/all/position/step"][:]
    assert not np.array_equal(edges[0], edges[-1])  # the cell moved in the reversed stage

    def shown(values):
        return " x ".join(f"{e:.6g}" for e in values)

    line = f"cell:       periodic, {shown(edges[0])} m at step {steps[0]}, {shown(edges[-1])} m "
    assert line + f"at step {steps[-1]}" in info(out / f"{name}.reverse.h5").output
    from revdem_cli.io.restart import read_restart

    state = read_restart(out / f"{name}.restart.h5").state
    restart = info(out / f"{name}.restart.h5").output
    assert f"cell:       periodic, {shown(state.cell.length)} m\n" in restart
    assert np.array_equal(state.cell.length, edges[0])  # the reversal starts from it


def test_a_trajectory_whose_run_did_not_end_says_so(tmp_path):
    """A reversal that blew up (the damped settle stage reversed without a tape) left a
    trajectory that `info` showed as a whole run's: its frames, no word that the run
    failed. The forward run, which ended, is not called unfinished."""
    from tests.conftest import CONFIGS

    args = ["run", str(CONFIGS / "trvp" / "oedometer_settle.toml"), "--out", str(tmp_path), "-q"]
    assert runner.invoke(app, args).exit_code == 1
    reverse = info(tmp_path / "oedometer_settle.reverse.h5").output
    assert "unfinished: its run did not reach its end and left no checkpoint" in reverse
    assert "unfinished" not in info(tmp_path / "oedometer_settle.forward.h5").output
    summary = json.loads(info(tmp_path / "oedometer_settle.forward.h5", "--json").stdout)
    assert summary["ended"] is True
