"""`revdem sweep`: a grid of variants on a local dask cluster, one table of results."""

import csv
import json
import math

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.errors import InputError
from revdem_cli.sweep import parse_sets, read_sweep
from tests.conftest import CONFIGS

runner = CliRunner()
MASS = 1000.0 * 4.0 / 3.0 * math.pi * 0.005**3  # each sphere of configs/smoke/collision.yaml
VELOCITIES = ("[0.9,0.1,0.0]", "[0.5,0.0,0.0]", "[0.2,0.2,0.2]")


def test_six_variants_on_two_workers_give_one_table(tmp_path):
    result = runner.invoke(
        app,
        [
            "sweep",
            str(CONFIGS / "smoke" / "collision.yaml"),
            "--set",
            "stages.0.steps=100,200",
            "--set",
            "particles.0.velocity=" + ",".join(VELOCITIES),
            "--set",
            "stages.0.output_every=50",
            "--out",
            str(tmp_path),
            "--workers",
            "2",
            "-q",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "6 variants, 0 failed" in result.output
    with (tmp_path / "sweep.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [(row["stages.0.steps"], row["particles.0.velocity"]) for row in rows] == [
        (steps, velocity) for steps in ("100", "200") for velocity in VELOCITIES
    ]
    for row in rows:
        # no contact within 200 steps: the kinetic energy is the one set, and constant
        v = np.array(json.loads(row["particles.0.velocity"]))
        expected = 0.5 * MASS * (v @ v + 0.1**2)
        assert float(row["kinetic_energy"]) == pytest.approx(expected, rel=1e-12)
        assert float(row["total_energy"]) == pytest.approx(expected, rel=1e-12)
        assert row["reversible"] == "True" and float(row["max_position_error_rel"]) <= 1e-10
        assert row["first_divergence_step"] == "" and row["error"] == ""
        folder = tmp_path / row["folder"]
        assert (folder / "collision_smoke.compare.json").exists()
    assert rows[4]["folder"] == "004_steps=200_velocity=0.5+0.0+0.0"
    with h5py.File(tmp_path / "sweep.h5", "r") as f:
        table = f["sweep"]
        assert list(table.attrs["columns"])[:3] == [
            "folder",
            "stages.0.steps",
            "particles.0.velocity",
        ]
        np.testing.assert_array_equal(table["reversible"][:], np.ones(6))
        np.testing.assert_allclose(
            table["kinetic_energy"][:], [float(row["kinetic_energy"]) for row in rows]
        )
        assert table["folder"].asstr()[0] == rows[0]["folder"]


def test_values_split_at_commas_outside_brackets():
    assert parse_sets(["a.b=1,2", "c=[0,1],[2,3]", "d='x,y'", "a.b=3"]) == {
        "a.b": ["3"],
        "c": ["[0,1]", "[2,3]"],
        "d": ["'x,y'"],
    }
    for bad in ("novalue", "a=", "a=1,,2", "=1"):
        with pytest.raises(InputError, match="expected key=value"):
            parse_sets([bad])


@pytest.mark.parametrize("name", ["collision_friction.toml", "drop_drag_height.toml"])
def test_shipped_sweep_files_name_valid_variants(name):
    from revdem_cli.config import load_scenario

    sweep = read_sweep(CONFIGS / "sweeps" / name, [])
    variants = sweep.variants()
    assert len(variants) >= 5
    for variant in variants:
        scenario, _ = load_scenario(sweep.scenario, [f"{k}={v}" for k, v in variant.items()])
        assert sum(stage.steps for stage in scenario.stages) <= 600_000


@pytest.mark.parametrize(
    ("values", "message"), [("1e-7,-1", "greater than 0"), ("1e-7,1e-3", "critical time step")]
)
def test_a_bad_variant_stops_the_sweep_before_it_starts(tmp_path, values, message):
    smoke = str(CONFIGS / "smoke" / "collision.yaml")
    out = tmp_path / "out"
    result = runner.invoke(app, ["sweep", smoke, "--set", f"integrator.dt={values}", "--out", out])
    assert result.exit_code == 2 and message in result.output, result.output
    assert not out.exists()


def test_a_variant_that_fails_is_recorded_not_raised(tmp_path):
    from revdem_cli.config import load_scenario
    from revdem_cli.sweep import run_variant

    scenario, text = load_scenario(CONFIGS / "smoke" / "collision.yaml", ["stages.0.steps=100"])
    taken = tmp_path / "taken"
    taken.write_text("")
    row = run_variant(scenario.model_dump_json(), text, ".yaml", taken)
    assert row["error"].startswith("FileExistsError")
    assert row["reversible"] is None and row["kinetic_energy"] is None
