"""Interrupted runs: killed with SIGKILL at random moments, stopped by SIGINT or SIGTERM, then
continued with `revdem run --resume`. Every continued run must write the files an
uninterrupted run writes, dataset for dataset, bit for bit; what a killed run leaves must be
readable up to its last checkpoint."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.engine import _writer
from revdem_cli.errors import InputError
from revdem_cli.io import h5md
from revdem_cli.io.h5md import open_trajectory
from revdem_cli.io.restart import read_restart
from revdem_cli.stage import Model
from revdem_cli.state import empty_events, initial_state
from tests.conftest import CONFIGS, assert_one_line_error, two_spheres

KILLS = 12
"""SIGKILLs sent at random moments, each followed by a resume, over the cases below."""

CASES = {
    # two spheres forward then reversed: kills land in either phase
    "collision": (
        CONFIGS / "smoke" / "collision.yaml",
        ["stages.0.steps=60000", "stages.0.output_every=1500"],
    ),
    # the same in fixed-point arithmetic, whose round trip is bit for bit
    "collision_fixed": (
        CONFIGS / "smoke" / "collision.yaml",
        ["stages.0.steps=60000", "stages.0.output_every=1500", "integrator.arithmetic=fixed"],
    ),
    # 4 stages: packing, pour with local damping and a stop condition, moving platen, reversal
    "oedometer": (CONFIGS / "smoke" / "oedometer.toml", []),
}

EVERY_FRAME = ["--set", "output.checkpoint_interval=0"]


def _command(case: str, out: Path) -> list[str]:
    scenario, sets = CASES[case]
    overrides = [arg for value in sets for arg in ("--set", value)]
    return [sys.executable, "-m", "revdem_cli.cli", "run", str(scenario), "--out", str(out)] + [
        "-q",
        *overrides,
        *EVERY_FRAME,
    ]


def _resume(out: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "revdem_cli.cli", "run", "--resume", str(out), "-q"],
        capture_output=True,
        text=True,
    )


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict[str, tuple[Path, float]]:
    """Each case run whole: its output directory, and the seconds from its first checkpoint
    to its end (the window the kills are spread over)."""
    done = {}
    for case in CASES:
        out = tmp_path_factory.mktemp(f"whole_{case}")
        process = subprocess.Popen(_command(case, out), stderr=subprocess.PIPE)
        assert _started(process, out), process.communicate()[1]
        started = time.monotonic()
        assert process.wait() == 0, process.communicate()[1]
        done[case] = (out, time.monotonic() - started)
    return done


def _contents(path: Path) -> tuple[dict, dict]:
    """Every dataset of an HDF5 file, and the attributes that do not name a path (nor the
    digest of a group's attributes, which covers its paths)."""
    datasets, attrs = {}, {}

    def visit(name, item):
        paths = ("source_restart", "trajectory")
        for key, value in item.attrs.items():
            digest_of_paths = key == "sha256" and isinstance(item, h5py.Group)
            if key not in paths and not digest_of_paths:
                attrs[f"{name}@{key}"] = value
        if isinstance(item, h5py.Dataset):
            datasets[name] = item[()]

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return datasets, attrs


def assert_same_files(expected: Path, got: Path) -> None:
    """The HDF5 files and the comparison of `got` hold what those of `expected` hold."""
    names = sorted(p.name for p in expected.iterdir() if p.suffix in (".h5", ".json"))
    assert names == sorted(p.name for p in got.iterdir() if p.suffix in (".h5", ".json"))
    for name in names:
        if name.endswith(".json"):
            assert (expected / name).read_text() == (got / name).read_text(), name
            continue
        (data, attrs), (data2, attrs2) = _contents(expected / name), _contents(got / name)
        assert data.keys() == data2.keys(), name
        for key, value in data.items():
            assert value.dtype == data2[key].dtype and value.shape == data2[key].shape, key
            assert np.array_equal(value, data2[key], equal_nan=True), f"{name}: {key} differs"
        assert attrs.keys() == attrs2.keys(), name
        for key, value in attrs.items():
            assert np.array_equal(np.asarray(value), np.asarray(attrs2[key])), f"{name}@{key}"


def _started(process: subprocess.Popen, out: Path) -> bool:
    """Wait for the first checkpoint; False if the run ended first."""
    while not list(out.glob("*.checkpoint.h5")):
        if process.poll() is not None:
            return False
        time.sleep(0.005)
    return True


def _check_killed_trajectory(out: Path, whole: Path) -> None:
    """What a killed run left: its trajectory being written at the checkpoint opens, holds
    at least the frames the checkpoint counts, and they are the uninterrupted run's."""
    (checkpoint,) = out.glob("*.checkpoint.h5")
    place = read_restart(checkpoint, checkpoint=True).resumption
    name = checkpoint.name.removesuffix(".checkpoint.h5")
    kind = "forward" if place.phase == "forward" else "reverse"
    with open_trajectory(out / f"{name}.{kind}.h5") as f:
        frames = f["particles/all/position/value"]
        assert frames.shape[0] >= place.frames
        with h5py.File(whole / f"{name}.{kind}.h5") as g:
            expected = g["particles/all/position/value"][: place.frames]
        assert np.array_equal(frames[: place.frames], expected)


class _Killed(Exception):
    pass


def test_a_flush_cut_short_at_any_dataset_leaves_a_trajectory_that_opens(tmp_path, monkeypatch):
    """A kill in the middle of a flush leaves some datasets extended and others not. Cut
    after each dataset in turn, the trajectory still opens, with its frames and observables
    rows either all of the last flush or none of them."""
    scenario = two_spheres()
    model, state = Model.of(scenario), initial_state(scenario)
    width = model.layout.width
    real = h5md._append
    datasets = None
    cut = 0
    while datasets is None or cut < datasets:
        path = tmp_path / f"cut{cut}.h5"
        writer = _writer(path, state, model, "", "forward")
        for step in (0, 1):
            writer.frame(step, float(step), state.particles, empty_events())
            writer.observables(np.array([step]), np.array([float(step)]), np.zeros((1, width)))
            if step == 0:
                writer.flush()
        datasets = sum(1 for _ in writer._appenders())
        written = []

        def cut_short(dataset, values, written=written, cut=cut):
            if len(written) == cut:
                raise _Killed
            written.append(dataset.name)
            real(dataset, values)

        monkeypatch.setattr(h5md, "_append", cut_short)
        with pytest.raises(_Killed):
            writer.flush()
        monkeypatch.setattr(h5md, "_append", real)
        writer.file.close()  # what reached the file, and nothing more
        with open_trajectory(path) as f:
            frames = f["particles/all/position/step"].shape[0]
            rows = f["observables/kinetic_energy/step"].shape[0]
        assert frames in (1, 2) and rows in (1, 2), written
        cut += 1
    assert datasets > 10


def test_a_flush_writes_no_step_before_the_file_holds_its_values(tmp_path, monkeypatch):
    """SIGKILL leaves whatever HDF5's metadata cache had written, in any order, since the
    last H5Fflush. So between two flushes a step dataset must never grow beside a value or
    time dataset: then a killed run leaves either values past the last step, or steps whose
    values already reached the file. (A random kill found this in CI: a coordination
    number's values shorter than its steps.)"""
    scenario = two_spheres()
    model, state = Model.of(scenario), initial_state(scenario)
    writer = _writer(tmp_path / "t.h5", state, model, "", "forward")
    since_flush: list[list[str]] = [[]]
    real_append, real_flush = h5md._append, writer.file.flush

    def append(dataset, values):
        since_flush[-1].append(dataset.name)
        real_append(dataset, values)

    def flush():
        since_flush.append([])
        real_flush()

    monkeypatch.setattr(h5md, "_append", append)
    monkeypatch.setattr(writer.file, "flush", flush)
    for step in range(3):
        writer.frame(step, float(step), state.particles, empty_events())
        writer.observables(
            np.array([step]), np.array([float(step)]), np.zeros((1, model.layout.width))
        )
        writer.flush()
    writer.close()
    written = [names for names in since_flush if names]
    assert sum(map(len, written)) > 10
    for names in written:
        steps = [name.endswith("/step") for name in names]
        assert all(steps) or not any(steps), names


@pytest.mark.parametrize("case", list(CASES))
def test_a_run_killed_at_random_moments_resumes_to_the_uninterrupted_files(
    case, uninterrupted, tmp_path, kills
):
    whole, seconds = uninterrupted[case]
    rng = random.Random(f"kill {case}")
    wanted = KILLS // len(CASES)
    done = 0
    for attempt in range(3 * wanted):
        if done == wanted:
            break
        out = tmp_path / f"kill{attempt}"
        process = subprocess.Popen(
            _command(case, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        if not _started(process, out):
            continue
        time.sleep(rng.uniform(0.0, 0.8 * seconds))
        if process.poll() is not None:  # finished before the kill: not a kill
            continue
        process.send_signal(signal.SIGKILL)
        process.wait()
        if not list(out.glob("*.checkpoint.h5")):  # killed while exiting, its work all done
            assert_same_files(whole, out)
            continue
        _check_killed_trajectory(out, whole)
        resumed = _resume(out)
        assert resumed.returncode == 0, resumed.stderr
        assert not list(out.glob("*.checkpoint.h5")), "a finished run keeps no checkpoint"
        assert_same_files(whole, out)
        done += 1
        kills[case] = kills.get(case, 0) + 1
    assert done == wanted, f"only {done} of {wanted} runs were still running when killed"


EVERY = 100000
SPARSE = ["stages.0.steps=300000", f"stages.0.output_every={EVERY}"]
"""The smoke collision with frames far apart: a signal lands between two of them."""


def _sparse_command(out: Path) -> list[str]:
    scenario, _ = CASES["collision"]
    overrides = [arg for value in SPARSE for arg in ("--set", value)]
    return [sys.executable, "-m", "revdem_cli.cli", "run", str(scenario), "--out", str(out)] + [
        "-q",
        *overrides,
    ]


def _stepping(process: subprocess.Popen, out: Path) -> bool:
    """Wait for the forward trajectory's first frame; False if the run ended first."""
    while True:
        try:
            with open_trajectory(out / "collision_smoke.forward.h5") as f:
                if f["particles/all/position/step"].shape[0] > 0:
                    return True
        except (InputError, KeyError):  # not yet there, or not yet whole
            pass
        if process.poll() is not None:
            return False
        time.sleep(0.01)


@pytest.fixture(scope="module")
def sparse_whole(tmp_path_factory) -> tuple[Path, float]:
    """The sparse collision run whole, and its seconds of stepping."""
    out = tmp_path_factory.mktemp("whole_sparse")
    process = subprocess.Popen(_sparse_command(out), stderr=subprocess.PIPE)
    assert _stepping(process, out), process.communicate()[1]
    started = time.monotonic()
    assert process.wait() == 0, process.communicate()[1]
    return out, time.monotonic() - started


@pytest.mark.parametrize(("signum", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_stops_at_a_whole_step_with_a_checkpoint_from_which_the_run_resumes(
    signum, status, sparse_whole, tmp_path, kills
):
    """Each signal stops the run with one line and a checkpoint from which it resumes to the
    uninterrupted run's files. A signal that arrives while Python writes a frame stops at
    that frame's step, as it should; one that arrives while the compiled loop steps must stop
    it between frames. The signal goes out at a few moments until one lands while stepping."""
    whole, seconds = sparse_whole
    stops = []
    for attempt, fraction in enumerate((0.3, 0.2, 0.4)):
        out = tmp_path / f"try{attempt}"
        process = subprocess.Popen(
            _sparse_command(out), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL
        )
        assert _stepping(process, out)
        time.sleep(fraction * seconds)
        process.send_signal(signum)
        _, stderr = process.communicate()
        lines = stderr.decode().strip().splitlines()
        assert process.returncode == status, stderr
        assert len(lines) == 1 and "Traceback" not in lines[0]
        assert signal.Signals(signum).name in lines[0]
        assert f"revdem run --resume {out}" in lines[0]
        (checkpoint,) = out.glob("*.checkpoint.h5")
        stopped = read_restart(checkpoint, checkpoint=True).state.step
        assert f"at step {stopped}:" in lines[0]
        resumed = _resume(out)
        assert resumed.returncode == 0, resumed.stderr
        assert_same_files(whole, out)
        stops.append(stopped)
        if stopped % EVERY != 0:
            break
    assert stops[-1] % EVERY != 0, f"stopped only at frames' steps {stops}, never between"
    kills[signal.Signals(signum).name] = kills.get(signal.Signals(signum).name, 0) + 1


def test_a_signal_halts_the_compiled_loop_in_the_main_thread_within_a_step(tmp_path):
    """The stage loop steps in the main thread, where Python's handler cannot run until the
    loop returns: the watcher thread (`checkpoint.watching`) must set the halt flag as the
    signal arrives. Two spheres asked for 10^6 steps in one call (seconds of stepping); a
    SIGTERM 0.2 s in must halt it within a second."""
    import os
    import threading

    from revdem_cli.checkpoint import Checkpoints
    from revdem_cli.io.tape import no_tape
    from revdem_cli.kernels.integrate import HALTED, advance
    from revdem_cli.stage import stepping_bundles

    scenario = two_spheres()
    model, state = Model.of(scenario), initial_state(scenario)
    checkpoints = Checkpoints(tmp_path / "pair.checkpoint.h5", interval=1e9)
    steps = 10**6
    stepping = model.stepping(1e-9, 0, steps, steps, checkpoints.stepper.halt)
    obs, obs_steps = model.buffers(2)
    bundles = stepping_bundles(state, model, model.dynamics, model.law)
    advance(*bundles, empty_events(), no_tape(), stepping, 0, 10, 10, obs, obs_steps)  # compiled
    with checkpoints.on_signals():
        sender = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGTERM))
        started = time.monotonic()
        sender.start()
        status, reached, _, _ = advance(
            *bundles, empty_events(), no_tape(), stepping, 10, steps, steps, obs, obs_steps
        )
        seconds = time.monotonic() - started
        sender.join()
    assert status == HALTED and reached < steps, (status, reached)
    assert seconds < 1.2, f"halted {seconds - 0.2:.2f} s after the signal"
    assert checkpoints.signal == signal.SIGTERM


def _unfinished(tmp_path: Path) -> Path:
    """An output directory with a checkpoint, as a killed collision leaves it."""
    process = subprocess.Popen(
        _command("collision", tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    assert _started(process, tmp_path)
    process.send_signal(signal.SIGKILL)
    process.wait()
    return tmp_path


def test_a_new_run_over_an_unfinished_one_is_refused_unless_forced(tmp_path):
    out = _unfinished(tmp_path)
    scenario, sets = CASES["collision"]
    args = ["run", str(scenario), "--out", str(out), "-q", "--set", sets[0], "--set", sets[1]]
    result = CliRunner().invoke(app, args)
    assert_one_line_error(result, "an unfinished run", f"revdem run --resume {out}")
    assert list(out.glob("*.checkpoint.h5"))
    assert CliRunner().invoke(app, [*args, "--force"]).exit_code == 0
    assert not list(out.glob("*.checkpoint.h5"))


def test_a_checkpoint_shows_as_one_and_is_not_a_restart(tmp_path):
    out = _unfinished(tmp_path)
    (checkpoint,) = out.glob("*.checkpoint.h5")
    shown = CliRunner().invoke(app, ["info", str(checkpoint)])
    assert shown.exit_code == 0, shown.output
    assert "kind:       checkpoint (forward)" in shown.output
    assert f"resume:     revdem run --resume {out}" in shown.output
    trajectory = CliRunner().invoke(app, ["info", str(out / "collision_smoke.forward.h5")])
    assert trajectory.exit_code == 0 and "frames:" in trajectory.output  # a killed run's
    elsewhere = tmp_path / "elsewhere"
    result = CliRunner().invoke(app, ["reverse", str(checkpoint), "-q", "--out", str(elsewhere)])
    assert_one_line_error(result, "a checkpoint of an unfinished run", "--resume")


def test_a_resumed_run_names_the_exports_made_before_it_ended(tmp_path):
    """An export of a stopped run's trajectory holds the frames up to its checkpoint; resumed,
    the run wrote on and said nothing of it, as `run --force` now does of the exports of the
    trajectories it replaces."""
    out = _unfinished(tmp_path)
    forward = out / "collision_smoke.forward.h5"
    made = CliRunner().invoke(app, ["export", str(forward), "--format", "lammps-dump", "-q"])
    assert made.exit_code == 0, made.output
    resumed = CliRunner().invoke(app, ["run", "--resume", str(out)], env={"COLUMNS": "500"})
    assert resumed.exit_code == 0, resumed.output
    stale = [" ".join(line.split()) for line in resumed.output.splitlines() if "stale" in line]
    dump = out / "collision_smoke.forward.dump"
    said = "(made before this run wrote its trajectory; export again)"
    assert stale == [f"stale export {dump} {said}"]


def test_resume_needs_a_checkpoint_and_nothing_else(tmp_path):
    result = CliRunner().invoke(app, ["run", "--resume", str(tmp_path)])
    assert_one_line_error(result, "no checkpoint")
    result = CliRunner().invoke(app, ["run", "--resume", str(tmp_path / "absent")])
    assert_one_line_error(result, "no such directory")
    scenario = str(CASES["collision"][0])
    result = CliRunner().invoke(app, ["run", scenario, "--resume", str(tmp_path)])
    assert_one_line_error(result, "give no scenario")
    assert_one_line_error(CliRunner().invoke(app, ["run"]), "give a scenario file")
    for option in (["--out", "out"], ["--no-reverse"], ["--force"], ["--allow-unstable-dt"]):
        result = CliRunner().invoke(app, ["run", "--resume", str(tmp_path), *option])
        assert_one_line_error(result, f"into DIR: {option[0]} cannot change it")


def test_resume_refuses_a_trajectory_the_checkpoints_run_did_not_write(tmp_path):
    """A resumed run copies the rows its checkpoint counts by their number: another run's
    trajectory put in the folder was spliced into its own, frames of one output interval
    then those of another, and said reversible. Refused now, naming what sets them apart,
    the folder as it was."""
    out = _unfinished(tmp_path / "stopped")
    forward = out / "collision_smoke.forward.h5"
    (checkpoint,) = out.glob("*.checkpoint.h5")
    other = tmp_path / "other"
    scenario, sets = CASES["collision"]
    args = ["run", str(scenario), "--out", str(other), "-q", "--set", "stages.0.steps=3000"]
    assert CliRunner().invoke(app, [*args, "--set", sets[1], *EVERY_FRAME]).exit_code == 0
    forward.write_bytes((other / forward.name).read_bytes())

    def files() -> dict:  # but the lock file the killed run left, which the next takes away
        return {path.name: path.read_bytes() for path in out.iterdir() if path.name != ".lock"}

    before = files()
    result = CliRunner().invoke(app, ["run", "--resume", str(out), "-q"])
    assert_one_line_error(
        result,
        f"{forward}: not the trajectory the run of {checkpoint} was writing: runs of different "
        "scenarios (or of other --set): stages.0.steps = 60000 and 3000",
    )
    assert files() == before
    again = tmp_path / "again"  # the run made again, its frames then moved on or cut short
    args = ["run", str(scenario), "--out", str(again), "-q", "--no-reverse", *EVERY_FRAME]
    assert CliRunner().invoke(app, [*args, "--set", sets[0], "--set", sets[1]]).exit_code == 0
    forward.write_bytes((again / forward.name).read_bytes())
    frames = read_restart(checkpoint, checkpoint=True).resumption.frames
    with h5py.File(forward, "r+") as f:
        f["particles/all/position/step"][:] *= 2
    result = CliRunner().invoke(app, ["run", "--resume", str(out), "-q"])
    assert_one_line_error(result, f"that run had written frames 1 to {frames} by step")
    with h5py.File(forward, "r+") as f:
        f["particles/all/position/step"].resize((frames - 1,))
    result = CliRunner().invoke(app, ["run", "--resume", str(out), "-q"])
    assert_one_line_error(result, f"that run had written {frames} frames", f"holds {frames - 1}")


SWEEP = [
    "sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--workers", "1", "-q",
    "--set", "stages.0.steps=2000,400000", "--set", "particles.0.velocity=[0.9,0.1,0.0],[0.5,0,0]",
    "--set", "stages.0.output_every=1000",
]  # fmt: skip
"""Two short variants, then two long ones, one at a time: Ctrl-C lands in the third."""


def _sweep_rows(out: Path) -> list[dict]:
    import csv

    with (out / "sweep.csv").open() as f:
        return [row | {"seconds": ""} for row in csv.DictReader(f)]


def _stopped_sweep(out: Path, signum: int, twice: bool = False) -> str:
    """Run SWEEP into `out` as a job of its own process group, and send `signum` to the
    whole group (as Ctrl-C does SIGINT, and SLURM's scancel or systemd SIGTERM) once the
    third variant has begun, `twice` to the sweep first and 0.1 s later to the group, as
    GNU `timeout` does (the sweep then gets it twice); its standard error, once it has
    exited with 128 + signum within 10 s."""
    command = [sys.executable, "-m", "revdem_cli.cli", *SWEEP, "--out", str(out)]
    process = subprocess.Popen(command, start_new_session=True, stderr=subprocess.PIPE, text=True)
    third = out / "002_steps=400000_velocity=0.9+0.1+0.0" / "collision_smoke.forward.h5"
    while not third.exists():
        assert process.poll() is None, process.communicate()[1]
        time.sleep(0.01)
    if twice:
        os.kill(process.pid, signum)
        time.sleep(0.1)  # past the sweep's handler, which ran for the first at once
    os.killpg(process.pid, signum)
    started = time.monotonic()
    try:
        _, err = process.communicate(timeout=60)
    finally:  # the workers too, should the sweep not end
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 128 + signum, err
    assert time.monotonic() - started < 10, err
    name = signal.Signals(signum).name
    assert err.strip().splitlines()[-1] == (
        f"stopped: {name}: 2 variants done, 1 stopped with a checkpoint, 1 not started; "
        "continue with the same command and --resume"
    ), err
    rows = _sweep_rows(out)
    assert [row["status"] for row in rows] == ["done", "done", "stopped", "not started"]
    assert rows[2]["error"].startswith(f"stopped: {name} at step ")
    assert list(third.parent.glob("*.checkpoint.h5"))
    return err


def test_ctrl_c_stops_a_sweep_with_its_table_and_resume_ends_it_as_an_uninterrupted_one(
    tmp_path,
):
    """Ctrl-C reaches every process of the terminal's group, the sweep's workers too: the
    running variant stops at a whole step with a checkpoint, none begins after, the table
    says so and the sweep exits 130; `--resume` keeps the variants done, continues the
    stopped one and runs the last, to the rows and files of a sweep never stopped."""
    cut = tmp_path / "cut"
    _stopped_sweep(cut, signal.SIGINT)
    resumed = CliRunner().invoke(app, [*SWEEP, "--out", str(cut), "--resume"])
    assert resumed.exit_code == 0, resumed.output
    whole = tmp_path / "whole"
    assert CliRunner().invoke(app, [*SWEEP, "--out", str(whole)]).exit_code == 0
    assert _sweep_rows(cut) == _sweep_rows(whole)
    assert [row["status"] for row in _sweep_rows(cut)] == ["done"] * 4
    for row in _sweep_rows(whole):
        assert_same_files(whole / row["folder"], cut / row["folder"])
    assert sorted(p.name for p in cut.iterdir()) == sorted(p.name for p in whole.iterdir())


def test_sigterm_to_the_whole_job_stops_a_sweep_as_ctrl_c_does(tmp_path):
    """SLURM's scancel and systemd send SIGTERM to every process of the job: the workers
    died of it, their variants unsaved, and dask restarted them. GNU `timeout` sends it to
    the sweep, then to its group: the second, taken as a second request, killed the sweep
    with no table. A variant then finished on its own (`revdem run --resume FOLDER`, as
    `revdem info` of its checkpoint says) is kept by `sweep --resume`, its row read from
    its files; it was run again from its start."""
    err = _stopped_sweep(tmp_path, signal.SIGTERM, twice=True)
    assert "Restarting worker" not in err
    third = tmp_path / _sweep_rows(tmp_path)[2]["folder"]
    assert CliRunner().invoke(app, ["run", "--resume", str(third), "-q"]).exit_code == 0
    finished = snapshot_files(third)
    resumed = CliRunner().invoke(app, [*SWEEP, "--out", str(tmp_path), "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert snapshot_files(third) == finished
    rows = _sweep_rows(tmp_path)
    assert [row["status"] for row in rows] == ["done"] * 4
    assert rows[2]["reversible"] == "True" and rows[2]["kinetic_energy"]


def test_a_signal_delivered_twice_is_one_request_and_a_later_one_stops_at_once(monkeypatch):
    """GNU `timeout` signals its child and then the child's group, so one request arrives
    twice: the second within SAME_SIGNAL is the same request. One after that does what the
    handlers before did (here Python's: KeyboardInterrupt)."""
    from revdem_cli import checkpoint

    taken = []
    given = signal.signal(signal.SIGINT, signal.default_int_handler)  # a test worker ignores it
    try:
        with checkpoint.first_signal(taken.append):
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            assert taken == [signal.SIGINT]
            monkeypatch.setattr(checkpoint, "SAME_SIGNAL", 0.0)
            with pytest.raises(KeyboardInterrupt):
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, given)
    assert taken == [signal.SIGINT]


def test_a_resumed_run_says_what_the_stages_before_its_checkpoint_did(tmp_path):
    """The smoke oedometer, every stage reversed with the tape, stopped once its pour has
    ended: resumed, its summary listed only the stages after the checkpoint (not the pour's
    stop, tape and restart), and named the forward run and restart by absolute paths."""
    out = tmp_path / "cut"
    args = [
        "run", str(CONFIGS / "smoke" / "oedometer.toml"), "--out", str(out), "-q",
        "--set", "reversal.all_stages=true", "--set", "reversal.tape=true",
        "--set", "integrator.arithmetic=fixed",
    ]  # fmt: skip
    command = [sys.executable, "-m", "revdem_cli.cli", *args]
    process = subprocess.Popen(command, start_new_session=True, stderr=subprocess.PIPE)
    poured = out / "oedometer_smoke.stage-0.restart.h5"
    while not poured.exists():
        assert process.poll() is None, process.communicate()[1]
        time.sleep(0.01)
    time.sleep(0.5)
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(timeout=60) == 130, process.communicate()[1]
    resumed = CliRunner().invoke(app, ["run", "--resume", str(out)], env={"COLUMNS": "500"})
    assert resumed.exit_code == 0, resumed.output
    said = [" ".join(line.split()) for line in resumed.output.splitlines()]
    for line in (
        "stopped stage pour after 140000 of 200000 steps",
        f"information tape {out / 'oedometer_smoke.stage-0.tape.h5'}",
        f"restart of pour {poured}",
        f"forward trajectory {out / 'oedometer_smoke.forward.h5'}",
        f"restart {out / 'oedometer_smoke.restart.h5'}",
    ):
        assert line in said, resumed.output


def snapshot_files(folder: Path) -> dict[str, int]:
    """Each file in `folder` and the time it was last written (ns)."""
    return {p.name: p.stat().st_mtime_ns for p in sorted(folder.iterdir())}


def test_resume_keeps_a_finished_sweep_and_refuses_one_of_other_values(tmp_path):
    """A sweep all done is kept as its table has it. A variant's files are that variant's:
    a sweep given other values (here another velocity in the folder of the same name) is
    refused before any variant runs."""
    args = [
        "sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--workers", "1", "-q",
        "--out", str(tmp_path), "--set", "stages.0.steps=200,300",
    ]  # fmt: skip
    assert CliRunner().invoke(app, args).exit_code == 0
    table = (tmp_path / "sweep.csv").read_text()
    again = CliRunner().invoke(app, [*args, "--resume"])  # every variant done: kept as it was
    assert again.exit_code == 0 and "2 variants, 0 failed" in again.output, again.output
    assert (tmp_path / "sweep.csv").read_text() == table
    other = [*args, "--set", "particles.0.velocity=[0.5,0,0]", "--resume"]
    assert_one_line_error(
        CliRunner().invoke(app, other), f"{tmp_path / '000_steps=200'}", "another scenario"
    )
    assert (tmp_path / "sweep.csv").read_text() == table
    # other values in other folders: it ran them and wrote their table over the finished
    # sweep's, whose runs then stood in no table
    values = [*args[:-1], "stages.0.steps=400,300", "--resume"]
    assert_one_line_error(
        CliRunner().invoke(app, values),
        f"--resume {tmp_path}: its sweep has other variants (000_steps=200, 001_steps=300) "
        "than these",
    )
    assert (tmp_path / "sweep.csv").read_text() == table
    assert not (tmp_path / "000_steps=400").exists()
    fresh = [*args[:-4], "--out", str(tmp_path / "none"), "--resume"]
    assert_one_line_error(CliRunner().invoke(app, fresh), "no sweep there")


def test_a_signal_after_the_last_step_stops_the_run_at_once(tmp_path):
    """After its last step a run compares and draws (24 s for the 30 001 frames of a long
    collision, before the comparison read frames in blocks); a signal then was only noted,
    and the run went on to exit 0. Now it stops at once, as `Unfinished`, whether it comes
    during that work or came after the last halt check."""
    from revdem_cli.checkpoint import Checkpoints, Unfinished

    checkpoints = Checkpoints(tmp_path / "x.checkpoint.h5", 60.0)
    with checkpoints.on_signals():
        checkpoints.finish("its comparison was written")
        with pytest.raises(Unfinished, match="^SIGINT after the last step, before its compar"):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)  # Python runs the handler, which raises, at once
    late = Checkpoints(tmp_path / "y.checkpoint.h5", 60.0)
    with late.on_signals():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.1)
        with pytest.raises(Unfinished, match="^SIGTERM after the last step") as stopped:
            late.finish("its figures were drawn")
    assert stopped.value.exit_code == 143
    assert not list(tmp_path.iterdir())  # no checkpoint: the run's files are whole


def test_a_signal_while_the_sweeps_cluster_starts_stops_it_before_any_variant_begins(
    tmp_path, monkeypatch
):
    """Ctrl-C while the local cluster's workers start (a second or more) raised
    KeyboardInterrupt out of dask's start-up, waited seconds for the workers and wrote no
    table. The first signal now writes the stop file from before the cluster starts: no
    variant begins, the table says so and the sweep exits 130, as it does when stopped
    later."""
    _signal_while_the_cluster_starts(monkeypatch)
    result = CliRunner().invoke(app, [*SWEEP, "--out", str(tmp_path)])
    assert result.exit_code == 130, result.output
    assert result.output.strip().splitlines()[-1] == (
        "stopped: SIGINT: 0 variants done, 0 stopped with a checkpoint, 4 not started; "
        "continue with the same command and --resume"
    )
    assert [row["status"] for row in _sweep_rows(tmp_path)] == ["not started"] * 4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.csv", "sweep.h5"]


def _signal_while_the_cluster_starts(monkeypatch) -> None:
    """Have the next sweep's local cluster send SIGINT to this process as it starts."""
    from revdem_cli import sweep

    starting = sweep._client

    @contextmanager
    def signalled_while_starting(*cluster):
        os.kill(os.getpid(), signal.SIGINT)
        with starting(*cluster) as client:
            yield client

    monkeypatch.setattr(sweep, "_client", signalled_while_starting)


def test_a_signal_stops_a_script_at_the_sweep_or_run_it_came_in(tmp_path, monkeypatch):
    """A script's `revdem.sweep` stopped by Ctrl-C returned its rows, and the script went
    on to its next sweep; and Interrupted, an Exception, was taken for a failure by the
    `except Exception:` a script puts round a run to go on with the next. The sweep now
    raises Interrupted once its table is written, and neither is an Exception."""
    from revdem_cli import api as revdem
    from revdem_cli.checkpoint import Interrupted
    from revdem_cli.engine import run_scenario

    _signal_while_the_cluster_starts(monkeypatch)
    values = {"stages.0.steps": [200, 300]}
    scenario = CONFIGS / "smoke" / "collision.yaml"
    with pytest.raises(Interrupted) as stopped:
        try:
            revdem.sweep(scenario, values, tmp_path / "sweep", workers=1, threads=1)
        except Exception:  # noqa: BLE001  (a script's guard against a failed variant)
            pytest.fail("Ctrl-C taken for a failure")
    assert stopped.value.exit_code == 130
    assert str(stopped.value).startswith(
        "SIGINT: 0 variants done, 0 stopped with a checkpoint, 2 not started; the table "
    )
    assert stopped.value.rows == revdem.sweep_table(tmp_path / "sweep")
    assert [row["status"] for row in stopped.value.rows] == ["not started"] * 2
    assert stopped.value.path == tmp_path / "sweep" / "sweep.h5"

    experiment = revdem.load(scenario, {"stages.0.steps": 2000, "stages.0.output_every": 100})
    experiment = experiment.changed({"output.checkpoint_interval": 0.0})

    def interrupt(label, done, total, particles):
        if done == 300:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(Interrupted):
        try:
            run_scenario(experiment.scenario, experiment.text, experiment.suffix,
                         tmp_path / "run", True, interrupt)  # fmt: skip
        except Exception:  # noqa: BLE001
            pytest.fail("Ctrl-C taken for a failure")


def _spawned_in_group(group: int) -> bool:
    """Whether a process of multiprocessing's spawn (a dask nanny or worker) runs in the
    process group `group`."""
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and os.getpgid(int(entry.name)) == group:
                if b"spawn_main" in (entry / "cmdline").read_bytes():
                    return True
        except (OSError, ProcessLookupError):
            continue
    return False


def test_ctrl_c_as_the_local_clusters_workers_start_stops_the_sweep_with_its_table(tmp_path):
    """Ctrl-C reaches every process of the terminal's group: the sweep's workers too, while
    their nanny starts them, before they ignore it. dask then failed ("Nanny failed to
    start", exit 1, no table) or waited for a worker that never came, for minutes. Workers
    are now born with both signals blocked; the sweep takes the signal once its cluster is
    up, and stops with every variant not started, its table written."""
    command = [sys.executable, "-m", "revdem_cli.cli", *SWEEP, "--out", str(tmp_path)]
    process = subprocess.Popen(command, start_new_session=True, stderr=subprocess.PIPE, text=True)
    while not _spawned_in_group(process.pid):
        assert process.poll() is None, process.communicate()[1]
        time.sleep(0.002)
    os.killpg(process.pid, signal.SIGINT)
    try:
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == (
        "stopped: SIGINT: 0 variants done, 0 stopped with a checkpoint, 4 not started; "
        "continue with the same command and --resume"
    ), err
    assert [row["status"] for row in _sweep_rows(tmp_path)] == ["not started"] * 4


def test_a_signal_while_the_figures_are_drawn_says_what_is_whole(tmp_path, monkeypatch):
    """A signal after the comparison was written said the run stopped "before its
    comparison and figures were written", though compare.json was there. The line now says
    what is whole, and a figure is whole or absent (drawn under a temporary name)."""
    from revdem_cli import engine
    from revdem_cli.report import figures

    drawing = figures._save

    def signalled(fig, png):  # the signal comes while the figure is saved
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5.0)
        return drawing(fig, png)

    monkeypatch.setattr(figures, "_save", signalled)
    args = ["run", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(tmp_path), "-q"]
    result = CliRunner().invoke(app, [*args, "--set", "output.figures=['speed']"])
    assert result.exit_code == 143, result.output
    assert result.output.strip().splitlines()[-1] == (
        "stopped: SIGTERM after the last step, before its figures were drawn; its "
        "trajectories, restart and comparison collision_smoke.compare.json are whole"
    )
    assert (tmp_path / "collision_smoke.compare.json").exists()
    assert not list(tmp_path.glob("*.png*"))  # no figure cut short
    assert engine.read_restart(tmp_path / "collision_smoke.restart.h5").state.step == 5000
