"""`revdem sweep`: a grid of variants on a local dask cluster, one table of results."""

import csv
import json
import math
import re

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.errors import InputError
from revdem_cli.sweep import parse_sets, read_sweep
from tests.conftest import CONFIGS, assert_one_line_error

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
        # a column of numbers holds numbers, one of lists their text, as the CSV has them
        np.testing.assert_array_equal(table["stages.0.steps"][:], [100.0] * 3 + [200.0] * 3)
        assert list(table["particles.0.velocity"].asstr()[:3]) == list(VELOCITIES)
        assert list(table["status"].asstr()[:]) == ["done"] * 6
    shown = runner.invoke(app, ["info", str(tmp_path / "sweep.h5")])  # was "not a revdem file"
    assert shown.exit_code == 0, shown.output
    lines = shown.output.splitlines()
    assert lines[1] == "kind:       sweep table of 6 variants (6 done)"
    assert lines[6].split() == [
        "004_steps=200_velocity=0.5+0.0+0.0", "done", "reversible", "(max", "position", "error",
        "/", "diameter", f"{float(rows[4]['max_position_error_rel']):.3g})",
    ]  # fmt: skip
    # --json: each variant's values and every result, where it gave four of them
    shown = json.loads(runner.invoke(app, ["info", str(tmp_path / "sweep.h5"), "--json"]).stdout)
    fifth = shown["variants"][4]
    assert fifth["values"] == {
        "stages.0.steps": 200,
        "particles.0.velocity": json.loads(VELOCITIES[1]),
        "stages.0.output_every": 50,
    }
    assert fifth["kinetic_energy"] == float(rows[4]["kinetic_energy"])
    assert fifth["seconds"] > 0.0 and fifth["first_divergence_step"] is None


def test_values_split_at_commas_outside_brackets():
    assert parse_sets(["a.b=1,2", "c=[0,1],[2,3]", "d='x,y'"]) == {
        "a.b": ["1", "2"],
        "c": ["[0,1]", "[2,3]"],
        "d": ["'x,y'"],
    }
    for bad in ("novalue", "a=", "a=1,,2", "=1"):
        with pytest.raises(InputError, match="expected key=value"):
            parse_sets([bad])


def sweep_file(tmp_path, text: str):
    """A sweep file in tmp_path of the shear collision, its other lines `text`."""
    path = tmp_path / "sweep.toml"
    scenario = CONFIGS / "collision_shear.toml"
    path.write_text(f'kind = "sweep"\nscenario = "{scenario}"\n{text}\n')
    return path


def test_a_field_set_twice_is_refused_not_cut_to_its_last_values(tmp_path):
    sets = ["--set", "contact.friction=0.1", "--set", "contact.friction=0.2"]
    out = ["--out", str(tmp_path / "out")]
    result = runner.invoke(app, ["sweep", str(CONFIGS / "collision_shear.toml"), *sets, *out])
    assert_one_line_error(
        result, "--set contact.friction=0.2: contact.friction is given twice (also in --set "
    )


@pytest.mark.parametrize("command", ["sweep", "validate"])
def test_a_field_set_twice_in_a_sweep_file_is_refused(command, tmp_path):
    path = sweep_file(tmp_path, 'set = ["contact.friction=0.1", "contact.friction=0.2"]')
    out = ["--out", str(tmp_path / "out")] if command == "sweep" else []
    assert_one_line_error(
        runner.invoke(app, [command, str(path), *out]),
        f"{path}: set[1] = 'contact.friction=0.2': contact.friction is given twice (also in set[0]",
    )


def test_a_set_option_replaces_the_sweep_files_values_of_its_field(tmp_path):
    path = sweep_file(tmp_path, 'set = ["contact.friction=0.1,0.3", "stages.0.steps=100"]')
    sweep = read_sweep(path, ["contact.friction=inf"])
    assert sweep.grid == {"contact.friction": ["inf"], "stages.0.steps": ["100"]}


@pytest.mark.parametrize("command", ["sweep", "validate"])
def test_a_sweep_file_is_checked_with_the_set_options_given(command, tmp_path):
    path = sweep_file(tmp_path, 'set = ["contact.friction=0.1,0.3"]')
    out = ["--out", str(tmp_path / "out")] if command == "sweep" else []
    result = runner.invoke(app, [command, str(path), "--set", "stages.0.steps=abc", *out])
    assert_one_line_error(result, "stages[0].steps: Input should be a valid number")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            'set = "contact.friction=0.1"',
            "set: expected a list of \"field=v1,v2,...\" strings, got 'contact.friction=0.1'",
        ),
        ('set = ["stages.0.steps=100", 3]', 'set: expected a list of "field=v1,v2,..." strings'),
        ('set = ["contact.friction"]', "set[0] = 'contact.friction': expected key=value"),
        ('set = ["contact.friction=0.1,[x"]', "set[0] = 'contact.friction=0.1,[x': cannot read [x"),
    ],
)
def test_a_bad_set_of_a_sweep_file_names_the_file_and_its_entry(tmp_path, text, message):
    path = sweep_file(tmp_path, text)
    result = runner.invoke(app, ["validate", str(path)])
    assert_one_line_error(result, f"{path}: {message}")
    assert "--set" not in result.output


def test_a_missing_scenario_or_an_out_that_is_a_file_is_named_as_such(tmp_path):
    """A scenario file that is not there was blamed on the first variant ("variant a=1:
    nofile.toml: cannot read"), and --out naming a file on the sweep's own stop file
    (".../afile/.stop: ... is a file")."""
    missing = tmp_path / "nofile.toml"
    result = runner.invoke(app, ["sweep", str(missing), "--set", "a=1,2", "-q"])
    assert_one_line_error(result, f"error: {missing}: cannot read scenario file")
    afile = tmp_path / "afile"
    afile.write_text("mine")
    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    args = ["sweep", scenario, "--set", "stages.0.steps=10,20", "--out", str(afile), "-q"]
    assert_one_line_error(runner.invoke(app, args), f"error: --out {afile}: a file, not a folder")
    assert afile.read_text() == "mine"


def test_the_scenario_of_a_sweep_cannot_be_a_sweep(tmp_path):
    sweep_file(tmp_path, 'set = ["contact.friction=0.1"]')
    path = tmp_path / "outer.toml"
    path.write_text('kind = "sweep"\nscenario = "sweep.toml"\nset = []\n')
    result = runner.invoke(app, ["sweep", str(path), "--out", str(tmp_path / "out")])
    assert_one_line_error(result, f"{path}: scenario: sweep.toml is a sweep file")


@pytest.mark.parametrize("command", ["validate", "run", "sweep"])
def test_a_misspelt_kind_is_named_with_the_kinds_known(command, tmp_path):
    path = sweep_file(tmp_path, 'set = ["contact.friction=0.1"]')
    path.write_text(path.read_text().replace('"sweep"', '"sweeps"'))
    out = ["--out", str(tmp_path / "out")] if command != "validate" else []
    result = runner.invoke(app, [command, str(path), *out])
    assert_one_line_error(
        result, f"{path}: kind: unknown kind 'sweeps' (known: 'critical_time_step', 'sweep'"
    )


@pytest.mark.parametrize("command", ["sweep", "validate", "run"])
def test_a_sweep_file_in_yaml_is_told_that_a_sweep_file_is_toml(command, tmp_path):
    """A sweep file written in YAML was taken for a scenario: `revdem sweep` said "variant
    : sw.yaml: kind: 'sweep' is a sweep file, not a scenario; run it with revdem sweep"."""
    path = tmp_path / "sw.yaml"
    scenario = CONFIGS / "smoke" / "collision.yaml"
    path.write_text(f"kind: sweep\nscenario: {scenario}\nset: [stages.0.steps=200,300]\n")
    out = ["--out", str(tmp_path / "out")] if command != "validate" else []
    for sets in ([], ["--set", "contact.friction=0.1,0.2"]):
        result = runner.invoke(app, [command, str(path), *out, *sets])
        assert_one_line_error(result, f"error: {path}: a sweep file is TOML, not .yaml; write ")
    assert not (tmp_path / "out").exists()


def test_a_sweep_file_given_to_run_is_sent_to_revdem_sweep(tmp_path):
    path = sweep_file(tmp_path, 'set = ["contact.friction=0.1"]')
    result = runner.invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert_one_line_error(result, f"{path}: kind: 'sweep' is a sweep file", "revdem sweep")


@pytest.mark.parametrize(("allowed", "error"), [(False, "InputError: "), (True, "BlownUp: ")])
def test_a_variant_runs_at_an_unstable_time_step_only_where_allowed(tmp_path, allowed, error):
    """A variant's time step is checked on its worker as `revdem run` checks it; allowed
    (`revdem sweep --allow-unstable-dt`), the variant runs, and dt = 2.6 times the critical
    step drives the colliding pair through each other in its first step."""
    from revdem_cli.config import load_scenario
    from revdem_cli.sweep import run_variant

    overrides = ["integrator.dt=1e-3", "stages.0.steps=5"]
    scenario, text = load_scenario(CONFIGS / "smoke" / "collision.yaml", overrides)
    row = run_variant(scenario.model_dump_json(), text, ".yaml", tmp_path, allowed)
    assert row["error"].startswith(error), row["error"]
    assert "times the critical time step" in row["error"]


def test_a_variant_whose_reversal_fails_keeps_its_forward_runs_results(tmp_path):
    """The damped settle stage reversed without a tape blows up (Hanley 2020 §5.2): the row
    was failed and empty, although the forward run had ended; it keeps that run's final
    energies and seconds, the reversal's error beside them. A variant failed before its
    forward run ended keeps none (above)."""
    from revdem_cli.config import load_scenario
    from revdem_cli.io.h5md import open_trajectory, read_observable
    from revdem_cli.sweep import FAILED, run_variant

    scenario, text = load_scenario(CONFIGS / "trvp" / "oedometer_settle.toml", [])
    row = run_variant(scenario.model_dump_json(), text, ".toml", tmp_path)
    assert row["status"] == FAILED and row["error"].startswith("BlownUp: "), row["error"]
    with open_trajectory(tmp_path / "oedometer_settle.forward.h5") as f:
        assert row["kinetic_energy"] == read_observable(f, "kinetic_energy")[1][-1]
        assert row["total_energy"] == read_observable(f, "total_energy")[1][-1]
    assert row["seconds"] > 0.0 and row["reversible"] is None


def test_an_earlier_sweep_in_the_folder_is_kept_unless_forced(tmp_path):
    """As `revdem run` keeps a run's outputs: its tables and every variant's files."""
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--set", "stages.0.steps=10,20"]
    args += ["--out", str(tmp_path), "--workers", "1", "-q"]
    assert runner.invoke(app, args).exit_code == 0
    table = (tmp_path / "sweep.csv").read_bytes()
    refused = runner.invoke(app, args)
    assert_one_line_error(
        refused,
        f"{tmp_path / 'sweep.csv'}: exists (and 9 more outputs of the earlier sweep); use --force",
    )
    assert (tmp_path / "sweep.csv").read_bytes() == table
    forced = runner.invoke(app, [*args, "--force"])
    assert forced.exit_code == 0 and "2 variants, 0 failed" in forced.output, forced.output


def test_a_sweep_forced_over_another_of_other_values_leaves_none_of_its_runs(tmp_path):
    """`--force` with other values left the earlier sweep's variant folders, whole runs
    that the new table does not list. Their files go; a file of the user's in one stays."""
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(tmp_path)]
    args += ["--workers", "1", "-q"]
    assert runner.invoke(app, [*args, "--set", "stages.0.steps=10,20"]).exit_code == 0
    (tmp_path / "001_steps=20" / "notes.txt").write_text("mine")
    forced = runner.invoke(app, [*args, "--set", "stages.0.steps=30,40", "--force"])
    assert forced.exit_code == 0, forced.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "000_steps=30", "001_steps=20", "001_steps=40", "sweep.csv", "sweep.h5"
    ]  # fmt: skip
    assert [p.name for p in (tmp_path / "001_steps=20").iterdir()] == ["notes.txt"]


def test_a_bad_value_of_a_list_is_named_by_its_variant(tmp_path):
    """`--set contact.friction=0.1,-0.3`: the error said the friction must be ≥ 0, not
    which of the values was not."""
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(tmp_path)]
    sets = ["--set", "contact.tangential=mindlin", "--set", "contact.friction=0.1,-0.3"]
    result = CliRunner().invoke(app, [*args, *sets])
    assert_one_line_error(
        result, "error: variant contact.tangential=mindlin, contact.friction=-0.3: ", "greater than"
    )
    assert not list(tmp_path.iterdir())  # refused before any variant ran


def test_a_scheduler_address_that_is_none_is_one_line(tmp_path):
    """`--scheduler notanaddress` printed dask's traceback of 60 lines, exit 1."""
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--set", "stages.0.steps=10,20"]
    out = tmp_path / "out"
    result = runner.invoke(app, [*args, "--out", str(out), "--scheduler", "notanaddress", "-q"])
    assert_one_line_error(result, "error: --scheduler notanaddress: missing port number")
    assert not out.exists()


def test_a_value_given_twice_in_a_list_is_refused(tmp_path):
    """`contact.friction=0.1,0.1` ran the same variant twice."""
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(tmp_path)]
    result = runner.invoke(app, [*args, "--set", "contact.friction=0.1,0.3,0.1"])
    assert_one_line_error(result, "--set contact.friction=0.1,0.3,0.1: contact.friction: 0.1")
    assert "given twice" in result.output
    assert not list(tmp_path.iterdir())


def test_a_sweep_says_nothing_of_its_schedulers_http_port(tmp_path):
    """With 8787 taken (another cluster, a notebook's), dask warned "Port 8787 is already in
    use ... Hosting the HTTP server on port N instead" under -q: nothing a sweep's user
    asked for or can act on. (Run as a command: pytest would catch the warning itself.)"""
    import socket
    import subprocess
    import sys

    taken = socket.socket()
    try:
        taken.bind(("", 8787))
        taken.listen()
    except OSError:  # taken already: the same for the sweep
        pass
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--workers", "1", "-q"]
    args += ["--set", "stages.0.steps=10,20", "--out", str(tmp_path)]
    try:
        done = subprocess.run(
            [sys.executable, "-m", "revdem_cli.cli", *args], capture_output=True, text=True
        )
    finally:
        taken.close()
    assert done.returncode == 0, done.stderr
    assert "Port" not in done.stderr and "8787" not in done.stderr, done.stderr


def test_a_sweep_from_python_is_the_command_lines(tmp_path):
    """There was no Python function for a sweep, and its table was read back only by hand:
    `revdem.sweep` takes the values as Python values and gives the rows `sweep_table` reads
    (each variant's values and results); they are those of the same command's table."""
    from revdem_cli import api as revdem
    from revdem_cli.errors import InputError

    scenario = CONFIGS / "smoke" / "collision.yaml"
    values = {"stages.0.steps": [100, 200], "particles.0.velocity": [[0.9, 0.1, 0.0]]}
    rows = revdem.sweep(scenario, values, tmp_path / "api", workers=1, threads=1)
    args = ["sweep", str(scenario), "--set", "stages.0.steps=100,200", "--workers", "1"]
    args += ["--set", "particles.0.velocity=[0.9, 0.1, 0.0]", "--out", str(tmp_path / "cli")]
    assert runner.invoke(app, [*args, "-q", "--threads", "1"]).exit_code == 0
    cli = revdem.sweep_table(tmp_path / "cli")
    assert [row["folder"] for row in rows] == ["000_steps=100", "001_steps=200"]
    for got, expected in zip(rows, cli, strict=True):
        assert (
            got["values"]
            == expected["values"]
            == {
                "stages.0.steps": int(got["folder"][-3:]),
                "particles.0.velocity": [0.9, 0.1, 0.0],
            }
        )
        for key in ("status", "reversible", "max_position_error_rel", "kinetic_energy"):
            assert got[key] == expected[key], key
    assert revdem.read(tmp_path / "api" / rows[1]["folder"]).comparison["reversible"]
    for bad, message in (
        ({"stages.0.steps": 100}, "values['stages.0.steps']: a list of the values"),
        ({"stages.0.steps": [object()]}, "values: <object"),
        ([("stages.0.steps", [1])], "values: a mapping"),
    ):
        with pytest.raises(InputError, match=re.escape(message)):
            revdem.sweep(scenario, bad, tmp_path / "bad")
    for threads in (2.5, "2"):  # each variant's count, passed to workers unchecked before
        with pytest.raises(InputError, match=rf"^--threads {threads!r}: must be a whole number"):
            revdem.sweep(scenario, values, tmp_path / "bad", threads=threads)
    assert not (tmp_path / "bad").exists()
    with pytest.raises(InputError, match="no sweep table there"):
        revdem.sweep_table(tmp_path)


def test_a_tables_values_are_read_back_as_the_values_the_variants_took(tmp_path):
    """`sweep_table` gave each value that is not a number as the text `--set` was given,
    'true', '[0.9, 0.1, 0.0]', '"a, b"': they are the Python values the variant's scenario
    took, a bare word its text."""
    from revdem_cli import api as revdem
    from revdem_cli.sweep import RESULTS, write_table

    given = {
        "output.contacts": ("true", True),
        "particles.0.velocity": ("[0.9, 0.1, 0.0]", [0.9, 0.1, 0.0]),
        "description": ('"a, b"', "a, b"),
        "contact.model": ("hertz", "hertz"),
        "stages.0.stop_when": ("{kinetic_energy_below = 1e-09}", {"kinetic_energy_below": 1e-9}),
        "stages.0.steps": ("200", 200),
    }
    row = {"folder": "000", **{key: text for key, (text, _) in given.items()}}
    write_table([row | dict.fromkeys(RESULTS) | {"status": "done"}], tmp_path / "sweep")
    values = revdem.sweep_table(tmp_path)[0]["values"]
    assert values == {key: value for key, (_, value) in given.items()}
    assert type(values["stages.0.steps"]) is int


def test_a_sweep_into_the_folder_of_one_running_is_refused_before_it_writes(tmp_path):
    """Two sweeps started together into one --out each replaced and removed the other's
    files, and every variant of both failed; the second was refused only once the first
    had written its first files. A sweep now holds its folder from before it writes there
    (as this test holds it), and one into it meanwhile is refused, from the command line as
    from Python, leaving what is there as it was; the folder is free again after."""
    from revdem_cli import api as revdem
    from revdem_cli.io.lock import sole_writer

    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    args = ["sweep", scenario, "--set", "stages.0.steps=10,20", "--out", str(tmp_path)]
    (tmp_path / "sweep.csv").write_text("the running sweep's")
    with sole_writer(tmp_path):
        refused = runner.invoke(app, [*args, "--workers", "1", "-q", "--force"])
        assert_one_line_error(refused, f"--out {tmp_path}: another revdem run holds it")
        with pytest.raises(InputError, match="another revdem run holds it"):
            revdem.sweep(scenario, {"stages.0.steps": [10]}, tmp_path, workers=1, force=True)
        assert sorted(p.name for p in tmp_path.iterdir()) == [".lock", "sweep.csv"]
        assert (tmp_path / "sweep.csv").read_text() == "the running sweep's"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.csv"]
    with sole_writer(tmp_path):  # free again
        pass


def test_a_variant_holds_its_folder_and_fails_where_a_run_holds_it(tmp_path):
    """Each variant runs in a folder of its own under the sweep's, which holds its own
    folder: the variants take their folders' locks, not the sweep's, and run. One whose
    folder another revdem run holds (`revdem run --out` into it, say) fails, saying so, and
    leaves that run's files as they are; the others run."""
    from revdem_cli.io.lock import sole_writer

    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    args = ["sweep", scenario, "--set", "stages.0.steps=10,20", "--out", str(tmp_path)]
    held = tmp_path / "000_steps=10"
    held.mkdir()
    (held / "other.forward.h5").write_text("the other run's")
    with sole_writer(held):
        result = runner.invoke(app, [*args, "--workers", "1", "-q"])
        assert result.exit_code == 1, result.output
        assert f"failed: 000_steps=10: FolderHeld: {held}: another revdem run holds it" in (
            " ".join(result.output.split())
        )
        assert (held / "other.forward.h5").read_text() == "the other run's"
    rows = {row["folder"]: row for row in csv.DictReader(open(tmp_path / "sweep.csv"))}
    assert rows["000_steps=10"]["status"] == "failed"
    assert rows["000_steps=10"]["kinetic_energy"] == ""  # not the other run's
    assert rows["001_steps=20"]["status"] == "done"
    assert not (tmp_path / "001_steps=20" / ".lock").exists()


def test_a_thread_count_a_run_refuses_is_refused_for_a_sweeps_variants(tmp_path):
    """`revdem sweep --threads 64` on two cores set NUMBA_NUM_THREADS=64 on its workers,
    where `revdem run --threads 64` and `revdem.run(threads=64)` are refused: the count of
    each variant is checked as a run's is, from the command line and from Python."""
    from revdem_cli import api as revdem
    from revdem_cli.threads import most

    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    out = tmp_path / "out"
    for count in (most() + 1, 0):
        problem = f"--threads {count}: {count} threads: between 1 and {most()} (NUMBA_NUM_THREADS)"
        with pytest.raises(InputError, match=re.escape(problem)):
            revdem.run(scenario, out, threads=count)
        with pytest.raises(InputError, match=re.escape(problem)):
            revdem.sweep(scenario, {"stages.0.steps": [10]}, out, workers=1, threads=count)
    args = ["sweep", scenario, "--set", "stages.0.steps=10", "--out", str(out), "-q"]
    result = runner.invoke(app, [*args, "--workers", "1", "--threads", str(most() + 1)])
    assert_one_line_error(result, f"error: --threads {most() + 1}: {most() + 1} threads: between")
    assert not out.exists()


def test_a_file_in_the_way_of_a_variants_folder_is_refused_before_any_variant_runs(tmp_path):
    """A file where a variant's folder goes failed that variant as it ran, with a raw
    FileExistsError and exit status 1, the other variants run; `revdem run` refuses such an
    --out in one line, exit status 2, and so the sweep does now, before it starts."""
    blocking = tmp_path / "000_steps=200"
    blocking.write_text("mine")
    args = ["sweep", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(tmp_path)]
    result = runner.invoke(app, [*args, "--set", "stages.0.steps=200,300", "--workers", "1"])
    assert_one_line_error(result, f"error: {blocking}: a file, not a folder")
    assert [p.name for p in tmp_path.iterdir()] == [blocking.name]
    assert blocking.read_text() == "mine"


def test_a_sweep_from_python_takes_tables_as_set_does(tmp_path):
    """`--set 'stages.0.stop_when={kinetic_energy_below = 1e-9}'` sweeps a table; the API
    refused a dict ("a number, a bool, a text or a list, not dict"). Each variant takes it,
    and the table gives it back as the dict."""
    from revdem_cli import api as revdem

    stops = [{"kinetic_energy_below": 1e-9}, {"kinetic_energy_below": 1.0}]
    values = {"stages.0.stop_when": stops, "stages.0.steps": [300]}
    scenario = CONFIGS / "smoke" / "collision.yaml"
    rows = revdem.sweep(scenario, values, tmp_path, workers=1, threads=1)
    assert [row["values"]["stages.0.stop_when"] for row in rows] == stops
    assert [row["status"] for row in rows] == ["done", "done"]
    for row, stop in zip(rows, stops, strict=True):
        said = revdem.read(tmp_path / row["folder"]).outputs
        assert ("collide" in said.stopped) == (stop["kinetic_energy_below"] == 1.0), said


def test_what_a_sweep_from_python_is_given_wrongly_is_said_in_its_terms(tmp_path):
    """An empty list of values was refused in the command line's terms ("--set
    contact.friction=: expected key=value"), and force=True with resume=True on a new
    folder was "no sweep there", where the command line says to give one of them."""
    from revdem_cli import api as revdem

    scenario = CONFIGS / "smoke" / "collision.yaml"
    out = tmp_path / "new"
    with pytest.raises(InputError, match=r"^values\['contact.friction'\]: no values; give a"):
        revdem.sweep(scenario, {"contact.friction": []}, out)
    with pytest.raises(InputError, match="^--resume goes on .*--force starts it over: give one"):
        revdem.sweep(scenario, {"stages.0.steps": [10]}, out, force=True, resume=True)
    args = ["sweep", str(scenario), "--set", "stages.0.steps=10", "--out", str(out)]
    assert_one_line_error(runner.invoke(app, [*args, "--force", "--resume"]), "give one")
    assert not out.exists()


def test_the_variants_of_a_scheduler_take_threads_checked_as_a_local_sweeps(tmp_path):
    """`revdem sweep --scheduler ADDRESS --threads N` took any N and dropped it: its variants
    ran on their workers' default thread counts, where a local sweep's checks it and sets it.
    The count is now checked in one place (`api.check_threads`): before the sweep starts as
    a whole number 1 or more, then on each worker against its own pool, where it is set; a
    variant given more threads than its worker has fails, naming --threads."""
    import numba
    from distributed import Client, LocalCluster

    from revdem_cli import api as revdem
    from revdem_cli.threads import most

    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    for threads in (0, 2.5, "2"):  # refused before any scheduler is asked
        with pytest.raises(InputError, match=rf"^--threads {threads!r}: must be a whole number"):
            revdem.sweep(scenario, {"stages.0.steps": [10]}, tmp_path / "bad", threads=threads,
                         scheduler="tcp://127.0.0.1:9")  # fmt: skip
    assert not (tmp_path / "bad").exists()
    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        args = ["sweep", scenario, "--set", "stages.0.steps=10", "--scheduler",
                cluster.scheduler_address, "-q"]  # fmt: skip
        many = str(most() + 1)
        result = runner.invoke(app, [*args, "--out", str(tmp_path / "many"), "--threads", many])
        assert result.exit_code == 1, result.output
        said = " ".join(result.output.split())
        assert f"failed: 000: InputError: --threads {many}: {many} threads: between 1 and" in said
        result = runner.invoke(app, [*args, "--out", str(tmp_path / "one"), "--threads", "1"])
        assert result.exit_code == 0, result.output
        assert client.submit(numba.get_num_threads, pure=False).result() == 1  # its worker's


def test_workers_with_a_scheduler_are_refused_before_the_sweep_starts(tmp_path):
    """`--scheduler ADDRESS --workers 3` ran on the scheduler's workers, however many it had,
    and dropped the 3 without a word: a worker count sizes a local cluster, and a dask
    Client of an address starts none. The two together are refused, from the command line
    and from Python, before any scheduler is asked; each alone is taken."""
    from revdem_cli import api as revdem

    scenario = str(CONFIGS / "smoke" / "collision.yaml")
    address = "tcp://127.0.0.1:9"  # nothing answers there: asked, it would fail otherwise
    out = tmp_path / "out"
    args = ["sweep", scenario, "--set", "stages.0.steps=10", "--out", str(out)]
    result = runner.invoke(app, [*args, "--scheduler", address, "--workers", "3"])
    assert_one_line_error(
        result,
        f"error: --workers 3 sizes a local cluster; the variants run on the workers of "
        f"--scheduler {address}, as many as were started for it (e.g. `dask worker {address} "
        "--nworkers 3`): leave out --workers",
    )
    with pytest.raises(InputError, match=r"^--workers 1 sizes a local cluster; .*--scheduler"):
        revdem.sweep(scenario, {"stages.0.steps": [10]}, out, workers=1, scheduler=address)
    assert not out.exists()
    shown = runner.invoke(app, ["sweep", "--help"]).output.replace("│", " ")
    help_text = " ".join(shown.split())  # the option's help as one line, out of its box
    assert "(default 2); refused with --scheduler, whose workers are those started" in help_text
