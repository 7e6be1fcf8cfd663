"""What a run shows while it works: its progress from each stage's start, and a line before a
run whose kernels numba has yet to compile (minutes that would otherwise pass in silence)."""

import os
import subprocess
import sys

from typer.testing import CliRunner

from revdem_cli import api
from revdem_cli.cli import app
from revdem_cli.report import progress
from tests.conftest import CONFIGS, ROOT


def test_a_run_reports_each_stage_from_its_start_then_at_every_frame(tmp_path):
    calls = []
    experiment = api.load(CONFIGS / "collision.toml", overrides=["stages.0.steps=3000"])
    from revdem_cli.engine import run_scenario

    run_scenario(
        experiment.scenario, experiment.text, experiment.suffix, tmp_path, True,
        lambda *call: calls.append(call),
    )  # fmt: skip
    labels = list(dict.fromkeys(label for label, *_ in calls))
    assert len(labels) == 2, labels  # forward, then reversed
    for label in labels:
        done = [d for name, d, total, particles in calls if name == label]
        assert done[0] == 0, f"{label}: first shown at {done[0]} steps, not at its start"
        assert done == sorted(done) and done[-1] == 3000, (label, done)
        assert len(done) > 2, f"{label}: shown {len(done)} times, not at each frame"


def test_the_stage_loop_is_found_in_the_kernel_cache_once_compiled(tmp_path):
    api.run(api.load(CONFIGS / "collision.toml", overrides=["stages.0.steps=10"]), tmp_path)
    assert progress.kernels_compiled()


def test_an_empty_kernel_cache_is_seen_as_one_to_compile(tmp_path):
    check = "from revdem_cli.report.progress import kernels_compiled; print(kernels_compiled())"
    env = os.environ | {"NUMBA_CACHE_DIR": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", check], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_a_local_sweep_says_its_workers_compile_the_kernels_when_they_will(tmp_path, monkeypatch):
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--workers", "1"]
    args += ["--set", "stages.0.steps=50,100"]
    said = {}
    for compiled in (True, False):
        monkeypatch.setattr(progress, "kernels_compiled", lambda compiled=compiled: compiled)
        result = CliRunner().invoke(app, [*args, "--out", str(tmp_path / str(compiled))])
        assert result.exit_code == 0, result.output
        said[compiled] = progress.COMPILING in result.output
    assert said == {True: False, False: True}


def test_a_run_says_it_compiles_its_kernels_only_when_it_will(tmp_path, monkeypatch):
    args = ["run", str(CONFIGS / "collision.toml"), "--set", "stages.0.steps=300"]
    said = {}
    for compiled in (True, False):
        monkeypatch.setattr(progress, "kernels_compiled", lambda compiled=compiled: compiled)
        out = tmp_path / str(compiled)
        result = CliRunner().invoke(app, [*args, "--out", str(out)])
        assert result.exit_code == 0, result.output
        said[compiled] = progress.COMPILING in result.output
    assert said == {True: False, False: True}


def test_an_export_reports_each_frame_it_writes(smoke_run, tmp_path):
    """Every format: the frames written so far, each once, to the last (lammps-data: the
    last frame alone, the only one it reads, 1 of 1, where its bar showed 21/21)."""
    from revdem_cli.io import particles
    from revdem_cli.io.vtk import export_vtk

    trajectory = smoke_run / "collision_smoke.forward.h5"
    exporters = {
        "vtk": (export_vtk, tmp_path / "vtk"),
        "gsd": (particles.export_gsd, tmp_path / "x.gsd"),
        "lammps-dump": (particles.export_lammps_dump, tmp_path / "x.dump"),
        "lammps-data": (particles.export_lammps_data, tmp_path / "x.data"),
    }
    for name, (exporter, target) in exporters.items():
        calls = []
        exporter(trajectory, target, lambda *call, calls=calls: calls.append(call))
        done = [d for _, d, _ in calls]
        totals = {total for *_, total in calls}
        exported = 21 if name != "lammps-data" else 1  # the smoke run's frames, or its last
        assert totals == {exported}, (name, totals)
        assert done == list(range(1, exported + 1)), (name, done)
    shown = CliRunner().invoke(app, ["export", str(trajectory), "--format", "gsd",
                                     "--out", str(tmp_path / "y.gsd")])  # fmt: skip
    assert shown.exit_code == 0 and "21/21 frames" in shown.output, shown.output


def test_a_display_written_to_a_log_is_wide_enough_for_its_columns(tmp_path):
    """A batch job's log is not a terminal: rich took 80 columns and cut the times and rates
    to '0…'. Written to a file, the bar's line keeps its rate and both times whole."""
    script = (
        "from revdem_cli.report.progress import RunProgress\n"
        "with RunProgress() as shown:\n"
        "    shown('oedometer_smoke settle (forward)', 1000, 60000, 300)\n"
        "    shown('oedometer_smoke settle (forward)', 30000, 60000, 300)\n"
    )
    log = tmp_path / "job.log"
    environment = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    with log.open("w") as stderr:
        subprocess.run([sys.executable, "-c", script], stderr=stderr, env=environment, check=True)
    line = log.read_text().splitlines()[-1]
    assert "…" not in line and "particle-steps/s" in line, line
    assert len(line) <= progress.LOG_WIDTH
