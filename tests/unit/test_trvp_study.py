"""benchmarks/trvp_study.py writes its tables and figure where its command line says, and
the results shipped in scenarios/kolafa2011 (which the README quotes) only when named."""

import csv
import hashlib
import os
import subprocess
import sys
from pathlib import Path

from benchmarks.trvp_study import ROOT

SHIPPED = ROOT / "scenarios/kolafa2011"


def _study(*options: str) -> subprocess.CompletedProcess:
    """`python -m benchmarks.trvp_study OPTIONS` on one thread, from the repository root."""
    return subprocess.run(
        [sys.executable, "-m", "benchmarks.trvp_study", *options],
        cwd=ROOT,
        env=os.environ | {"NUMBA_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=900,
    )


def _digests(folder: Path) -> dict[str, str]:
    return {path.name: hashlib.sha256(path.read_bytes()).hexdigest() for path in folder.iterdir()}


def test_the_smallest_case_writes_beside_its_runs_not_into_the_shipped_results(tmp_path):
    shipped = _digests(SHIPPED)
    done = _study("--cases", "collision", "--out", str(tmp_path))
    assert _digests(SHIPPED) == shipped
    assert done.returncode == 0, done.stderr
    tables = {"study.csv", "errors.csv", "study.png", "restitution.csv", "collision_dt.csv"}
    assert tables | {"critical_dt.csv"} <= {path.name for path in tmp_path.iterdir()}
    with (tmp_path / "study.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [row["case"] for row in rows] == ["collision"] * 10  # 5 schemes, 2 arithmetics
    assert "rebounds.csv: not written, the drop is not among --cases" in done.stdout


def test_accuracy_without_the_drops_runs_is_refused_before_writing(tmp_path):
    into = tmp_path / "tables"
    done = _study("--accuracy", "--out", str(tmp_path / "runs"), "--into", str(into))
    assert done.returncode == 2
    error = done.stderr.splitlines()[-1]
    assert "drop-verlet-float/drop_viscous.forward.h5: the drop's runs come from the study" in error
    assert not into.exists()


def test_an_unknown_case_is_refused_naming_it_before_any_run(tmp_path):
    """A misspelt case ran the cases before it, then ended in a KeyError traceback."""
    done = _study("--cases", "collision,drip", "--out", str(tmp_path / "runs"))
    assert done.returncode == 2
    error = done.stderr.splitlines()[-1]
    assert error.endswith("--cases collision,drip: no case drip; of collision, drop, "
                          "oedometer, oedometer_viscous")  # fmt: skip
    assert not (tmp_path / "runs").exists()
