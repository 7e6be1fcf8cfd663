"""One revdem process at a time writes into a folder (`io.lock.sole_writer`): a run, a
resumption, a reversal, a time-step study or a sweep into a folder another holds is refused
before it reads or writes anything there; a lock its holder left, killed, blocks nothing."""

import signal
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from revdem_cli import api as revdem
from revdem_cli.cli import app
from revdem_cli.errors import InputError
from revdem_cli.io.lock import LOCK_FILE, sole_writer
from tests.conftest import CONFIGS, ROOT, assert_one_line_error

runner = CliRunner()
SMOKE = CONFIGS / "smoke" / "collision.yaml"
SHORT = ["--set", "stages.0.steps=200", "--set", "stages.0.output_every=100"]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def held_by_another(folder):
    """What is in `folder`, by name and content, with the other run's files (as a run that
    has written its first frames) and its lock."""
    return sorted((p.name, p.read_bytes()) for p in folder.iterdir())


def test_a_run_into_a_folder_another_run_writes_is_refused_and_touches_nothing(tmp_path):
    """Two `revdem run --out DIR --force` at once each removed and replaced the other's
    files: nothing stopped the second. Now the first holds DIR, and the second, forced or
    not, from the command line or from Python, is refused with one line that names DIR,
    leaving every file there as the first wrote it."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "collision_smoke.forward.h5").write_bytes(b"the first run's trajectory")
    (out / "collision_smoke.checkpoint.h5").write_bytes(b"the first run's checkpoint")
    with sole_writer(out):
        before = held_by_another(out)
        result = invoke("run", SMOKE, *SHORT, "--out", out, "--force", "-q", "--threads", 1)
        assert_one_line_error(result, f"--out {out}: another revdem run holds it")
        result = invoke("run", "--resume", out, "-q", "--threads", 1)
        assert_one_line_error(result, f"--resume {out}: another revdem run holds it")
        with pytest.raises(InputError, match="another revdem run holds it"):
            revdem.run(SMOKE, out, force=True, threads=1)
        assert held_by_another(out) == before
    assert sorted(p.name for p in out.iterdir()) == [
        "collision_smoke.checkpoint.h5",
        "collision_smoke.forward.h5",
    ]  # the lock goes with its holder


def test_a_reversal_or_a_study_into_a_folder_another_run_writes_is_refused(tmp_path):
    """`revdem reverse` writes beside its restart unless --out says where, and a time-step
    study writes its figures into --out: each is refused where another run writes."""
    out = tmp_path / "out"
    ran = invoke("run", SMOKE, *SHORT, "--no-reverse", "--out", out, "-q", "--threads", 1)
    assert ran.exit_code == 0, ran.output
    restart = out / "collision_smoke.restart.h5"
    elsewhere = tmp_path / "elsewhere"
    with sole_writer(out), sole_writer(elsewhere):
        before = held_by_another(out)
        result = invoke("reverse", restart, "--force", "-q", "--threads", 1)
        assert_one_line_error(result, f"{out} (beside the restart): another revdem run holds it")
        result = invoke("reverse", restart, "--out", elsewhere, "-q", "--threads", 1)
        assert_one_line_error(result, f"--out {elsewhere}: another revdem run holds it")
        result = invoke("run", CONFIGS / "ellipsoid_dt.toml", "--out", out)
        assert_one_line_error(result, f"--out {out}: another revdem run holds it")
        assert held_by_another(out) == before
        assert [p.name for p in elsewhere.iterdir()] == [LOCK_FILE]
    reversed_ = invoke("reverse", restart, "-q", "--threads", 1)  # free again
    assert reversed_.exit_code == 0, reversed_.output


def test_a_lock_left_by_a_killed_run_blocks_nothing(tmp_path):
    """The lock is the system's: a run killed with SIGKILL leaves its lock file behind but
    holds it no more, and the next run into the folder goes on (and takes it away)."""
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", "from revdem_cli.io.lock import sole_writer\n"
         f"with sole_writer({str(out)!r}):\n    print('held', flush=True)\n    input()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT,
    )  # fmt: skip
    assert holder.stdout.readline() == "held\n"
    result = invoke("run", SMOKE, *SHORT, "--out", out, "-q", "--threads", 1)
    assert_one_line_error(result, f"--out {out}: another revdem run holds it")
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    holder.stdout.close()
    holder.stdin.close()
    assert (out / LOCK_FILE).exists()  # left behind by the killed holder
    result = invoke("run", SMOKE, *SHORT, "--out", out, "-q", "--threads", 1)
    assert result.exit_code == 0, result.output
    assert (out / "collision_smoke.compare.json").exists() and not (out / LOCK_FILE).exists()
