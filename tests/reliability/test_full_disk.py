"""A full disk, as a file-size limit (RLIMIT_FSIZE: writes past it fail with EFBIG, as they
fail with ENOSPC on a full disk): every writer fails with one line and exit status 1 naming
its file, removes its temporary, and leaves earlier files as they were."""

import resource
import subprocess
import sys
from pathlib import Path

from tests.conftest import CONFIGS


def limited(size: int, *arguments: str, script: str | None = None) -> subprocess.CompletedProcess:
    """`revdem ARGUMENTS` (or a Python script) in a process whose files cannot grow past
    `size` bytes."""

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))

    command = [sys.executable, "-c", script] if script else [sys.executable, "-m", "revdem_cli.cli"]
    return subprocess.run(
        [*command, *arguments], preexec_fn=limit, capture_output=True, text=True, timeout=600
    )


def test_a_run_whose_trajectory_cannot_grow_stops_with_one_line(tmp_path):
    """It once printed 123 lines of HDF5 tracebacks and died of a segmentation fault."""
    args = ["run", str(CONFIGS / "collision.toml"), "--out", str(tmp_path), "-q"]
    result = limited(300_000, *args)
    assert result.returncode == 1, result.stderr
    assert result.stderr.splitlines() == [
        f"failed: cannot write {tmp_path / 'collision.forward.h5'}: File too large (errno 27)"
    ]
    assert not list(tmp_path.glob("*.tmp"))


def test_a_restart_that_cannot_be_written_leaves_the_one_before(tmp_path):
    """The second, larger restart fails: the first stays whole, no temporary is left."""
    script = f"""
import resource
from revdem_cli.config import load_scenario
from revdem_cli.errors import WriteFailed
from revdem_cli.io.restart import Restart, write_restart
from revdem_cli.state import initial_state
scenario, text = load_scenario({str(CONFIGS / "collision.toml")!r})
state = initial_state(scenario)
place = ("collide", "x", 0, 0.0, 1e-7)
restart = Restart(state, scenario.model_dump_json(), text, ".toml", *place)
path = {str(tmp_path / "x.restart.h5")!r}
resource.setrlimit(resource.RLIMIT_FSIZE, (10**9, 10**9))
write_restart(path, restart)
resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))
try:
    bigger = Restart(state, restart.scenario_json, text * 100, ".toml", *place)
    write_restart(path, bigger)
except WriteFailed as exc:
    print(exc)
"""
    result = limited(10**9, script=script)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().startswith(f"cannot write {tmp_path / 'x.restart.h5'}: File too")
    from revdem_cli.io.restart import read_restart

    kept = read_restart(tmp_path / "x.restart.h5")
    assert kept.scenario_text == (CONFIGS / "collision.toml").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.restart.h5"]


def test_a_time_step_sweep_that_cannot_be_written_is_a_failure_not_bad_input(tmp_path):
    out = tmp_path / "sweep.csv"
    args = ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "1000"]
    result = limited(3_000, *args, "--sweep", "kn=1:2:10000", "--out", str(out))
    assert result.returncode == 1, result.stderr
    assert result.stderr.splitlines() == [f"failed: cannot write {out}: File too large (errno 27)"]
    assert not out.exists()


def test_the_message_names_the_reason_of_a_full_disk():
    from revdem_cli.errors import WriteFailed

    error = OSError("Unable to synchronously flush file (file write failed: errno = 28, ...)")
    assert str(WriteFailed(Path("a.h5"), error)) == (
        "cannot write a.h5: No space left on device (errno 28)"
    )
