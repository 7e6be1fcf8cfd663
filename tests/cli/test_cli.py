"""The command line as a user meets it: exit codes, one-line errors, files written."""

import json

import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()

GOOD = (CONFIGS / "collision.toml").read_text().replace("steps = 15000", "steps = 3000")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture
def scenario(tmp_path):
    def write(text=GOOD, suffix=".toml"):
        path = tmp_path / f"case{suffix}"
        path.write_text(text)
        return path

    return write


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ("[integrator]", "[integrator]\ncolour = 'red'", ["integrator.colour: unknown field"]),
        ("radius = 0.005", "radius = -0.005", ["particles[0].radius", "greater than 0"]),
        (
            'material = "sphere"',
            'material = "granite"',
            ["particles[0].material", "unknown material 'granite'"],
        ),
        ("dt = 1.0e-7", 'dt = "fast"', ["integrator.dt", "valid number"]),
        (  # said "particles[1].position[2]: missing required field"
            "position = [0.0101, 0.0, 0.0]",
            "position = [0.0101, 0.0]",
            ["particles[1].position: 3 values needed, 2 given"],
        ),
        ("[materials.sphere]", "[materials.glass]", ["particles[0].material"]),
    ],
)
def test_bad_scenario_fields_exit_2_naming_the_field(scenario, tmp_path, old, new, fragments):
    path = scenario(GOOD.replace(old, new, 1))
    result = invoke("run", path, "--out", tmp_path / "out")
    assert_one_line_error(result, str(path), *fragments)
    assert not (tmp_path / "out").exists()


def test_a_file_that_is_not_toml_exits_2(scenario):
    path = scenario("this is [not toml\n")
    assert_one_line_error(invoke("validate", path), str(path), "not valid TOML")


def test_a_file_that_is_not_yaml_exits_2(scenario):
    path = scenario("name: [unclosed\n", ".yaml")
    assert_one_line_error(invoke("validate", path), str(path), "not valid YAML")


def test_an_unknown_format_and_a_missing_file_exit_2(scenario, tmp_path):
    assert_one_line_error(invoke("validate", scenario(GOOD, ".ini")), "unknown scenario format")
    assert_one_line_error(invoke("run", tmp_path / "none.toml"), "cannot read scenario file")


def test_a_bad_override_exits_2(scenario):
    result = invoke("validate", scenario(), "--set", "integrator.dt=0")
    assert_one_line_error(result, "integrator.dt", "greater than 0")


@pytest.mark.parametrize("item", ["output.figures=[bogus]", "particles.0.position=[1,2"])
def test_a_set_value_toml_cannot_read_is_named_not_taken_for_text(scenario, item):
    result = invoke("validate", scenario(), "--set", item)
    value = item.partition("=")[2]
    assert_one_line_error(result, f"--set {item}: cannot read {value} as a TOML value")


@pytest.mark.parametrize(
    ("figure", "has", "needs"),
    [
        ("wall_forces", "oedometer", "a plane wall across z"),
        ("stress_ratios", "fcc_triaxial", "a periodic [cell]"),
        ("information", "tape/oedometer_pour", "reversal.tape = true"),
    ],
)
def test_a_figure_without_what_it_draws_is_refused_before_the_run(figure, has, needs):
    """The collision has no wall, no cell and no tape: each figure drawn from one of those
    was an empty plot or a traceback after the runs."""
    collision = CONFIGS / "collision.toml"
    result = invoke("validate", collision, "--set", f"output.figures=['{figure}']")
    assert_one_line_error(result, f"{collision}: output.figures: '{figure}' needs {needs}")
    result = invoke("validate", CONFIGS / f"{has}.toml", "--set", f"output.figures=['{figure}']")
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("field", ["contact.friction", "contact.normal_damping"])
def test_nan_in_a_number_is_refused_as_not_finite_where_inf_is_allowed_too(field):
    shear = CONFIGS / "collision_shear.toml"
    result = invoke("validate", shear, "--set", f"{field}=nan")
    assert_one_line_error(result, f"{shear}: {field}: Input should be a finite number")
    assert invoke("validate", shear, "--set", "contact.friction=inf").exit_code == 0


def test_run_writes_all_outputs_and_prints_the_comparison(scenario, tmp_path):
    out = tmp_path / "out"
    result = invoke("run", scenario(), "--out", out, "--quiet")
    assert result.exit_code == 0, result.output
    assert "forward vs reversed" in result.output and "reversible" in result.output
    for name in ("forward.h5", "restart.h5", "reverse.h5", "compare.json", "speed.png"):
        assert (out / f"collision.{name}").stat().st_size > 0
    verdict = json.loads((out / "collision.compare.json").read_text())
    assert verdict["reversible"] and verdict["max_position_error_rel"] <= 1e-10

    again = invoke(
        "reverse",
        out / "collision.restart.h5",
        "--out",
        tmp_path / "again",
        "-q",
        "--steps",
        "1000",
    )
    assert again.exit_code == 0, again.output
    partial = json.loads((tmp_path / "again" / "collision.compare.json").read_text())
    assert partial["frames_compared"] == 21  # steps 3000 down to 2000, every 50

    compared = invoke(
        "compare", out / "collision.forward.h5", out / "collision.reverse.h5", "--json"
    )
    assert compared.exit_code == 0
    assert json.loads(compared.stdout)["frames_compared"] == 61


def test_the_comparison_of_an_unfinished_reversal_says_it_is_unfinished(tmp_path):
    """A reversal stopped part-way was compared as "reversible: the reversed run retraces
    the forward run", as if whole, where `revdem info` called its trajectory unfinished.
    The comparison says so too now, as info finds it: in its table, its line and its JSON."""
    from revdem_cli import api as revdem
    from tests.conftest import crashed_after

    smoke = revdem.load(CONFIGS / "smoke" / "collision.yaml")
    shown = crashed_after(smoke.changed({"output.checkpoint_interval": 0.0}), tmp_path, 150)
    assert "reversed" in shown[-1]
    forward, reverse = (tmp_path / f"collision_smoke.{kind}.h5" for kind in ("forward", "reverse"))
    checkpoint = tmp_path / "collision_smoke.checkpoint.h5"

    def compare(*options):
        args = ["compare", str(forward), str(reverse), *options]
        result = runner.invoke(app, args, env={"COLUMNS": "500"})
        assert result.exit_code == 0, result.output
        return result.output

    said = " ".join(compare().split())
    assert "│ reversal │ unfinished: frames back to step" in said
    assert (
        "reversible so far: the reversed run retraces the forward run within tolerance, but "
        "the reversal is unfinished: its frames go back from step 5000 to step"
    ) in said
    assert f"{checkpoint} is beside it (the run stopped, or goes on)" in said
    verdict = json.loads(compare("--json"))
    assert verdict["reversal_finished"] is False and verdict["reversible"]
    assert f"{checkpoint} is beside it" in verdict["reversal_unfinished"]
    kept = checkpoint.read_bytes()
    checkpoint.unlink()  # a run stopped at once leaves none: its trajectory says it did not end
    verdict = json.loads(compare("--json"))
    assert "its run did not reach its end and left no checkpoint" in verdict["reversal_unfinished"]
    checkpoint.write_bytes(kept)
    assert invoke("run", "--resume", tmp_path, "-q").exit_code == 0
    written = json.loads((tmp_path / "collision_smoke.compare.json").read_text())
    assert written["reversal_finished"]  # compared while its checkpoint was still there
    verdict = json.loads(compare("--json"))
    assert verdict["reversal_finished"] and verdict["reversal_unfinished"] is None
    assert "unfinished" not in compare()


def test_a_reversal_that_would_meet_no_frame_but_its_first_is_refused(
    scenario, tmp_path, monkeypatch
):
    """`reverse --steps 7` of a run with frames every 50 steps shared only the frame it
    started from, which the restart makes the same, and was called reversible and bitwise
    identical, even where the run was not (a critical-state run that slipped, its energy
    43 % off at the end). It is refused before it runs; and `compare`, given such a pair,
    refuses it too."""
    out = tmp_path / "out"
    assert invoke("run", scenario(), "--out", out, "-q", "--no-reverse").exit_code == 0
    restart = out / "collision.restart.h5"
    short = tmp_path / "short"
    assert_one_line_error(
        invoke("reverse", restart, "--out", short, "--steps", "7"),
        f"--steps 7: the reversed run would end at step 2993, and {out / 'collision.forward.h5'}"
        " has no frame from there to step 3000, where it starts: nothing could be compared; "
        "give --steps 50 or more",
    )
    assert not short.exists()  # nothing run, and no empty folder left
    assert invoke("reverse", restart, "--out", short, "--steps", "50", "-q").exit_code == 0

    from revdem_cli import engine

    monkeypatch.setattr(engine, "refuse_nothing_to_compare", lambda *_: None)
    assert_one_line_error(
        invoke("reverse", restart, "--out", tmp_path / "unchecked", "--steps", "7", "-q"),
        "share only the frame the reversal starts from (step 3000), which its restart makes "
        "the same: nothing to compare",
    )


def test_reverse_of_a_file_that_is_not_a_restart_exits_2(tmp_path):
    path = tmp_path / "x.h5"
    path.write_bytes(b"nothing")
    assert_one_line_error(invoke("reverse", path), "not a readable HDF5 file")


def test_schema_describes_fields_with_units():
    result = invoke("schema")
    schema = json.loads(result.stdout)
    dt = schema["$defs"]["Integrator"]["properties"]["dt"]
    assert dt["description"].startswith("time step, s")


def test_every_bound_in_the_schema_has_json_schemas_keyword():
    """An optional field's bounds were written as pydantic names them, inside its anyOf
    (Contact.friction: {"ge": 0, "type": "number"}), keywords JSON Schema does not know;
    a field that must be given had "minimum". Every bound is a JSON Schema keyword now."""
    schema = json.loads(invoke("schema").stdout)
    unknown = []

    def walk(node, where: str) -> None:
        if isinstance(node, list):
            for k, item in enumerate(node):
                walk(item, f"{where}/{k}")
        elif isinstance(node, dict):
            for key, value in node.items():
                if key in ("ge", "gt", "le", "lt") and not where.endswith("/properties"):
                    unknown.append(f"{where}/{key}")
                walk(value, f"{where}/{key}")

    walk(schema, "")
    assert unknown == []
    defs = schema["$defs"]
    assert defs["Contact"]["properties"]["friction"]["anyOf"][0] == {"minimum": 0, "type": "number"}
    assert defs["Region"]["properties"]["radius"]["anyOf"][0]["exclusiveMinimum"] == 0
    assert defs["Material"]["properties"]["poisson_ratio"]["exclusiveMaximum"] == 0.5


def test_version():
    assert invoke("--version").output.startswith("revdem ")


def test_a_time_step_above_the_critical_estimate_is_refused_unless_allowed(scenario, tmp_path):
    path = scenario()
    result = invoke("run", path, "--set", "integrator.dt=1e-3", "--out", tmp_path / "a")
    message = f"error: {path}: integrator.dt = 0.001 s is"
    assert_one_line_error(result, message, "times the critical time step")
    assert not (tmp_path / "a").exists()
    checked = invoke("validate", path, "--set", "integrator.dt=1e-3")
    assert_one_line_error(checked, message, "times the critical time step")
    passed = invoke("validate", path, "--set", "integrator.dt=1e-3", "--allow-unstable-dt")
    assert passed.exit_code == 0 and passed.output.startswith(f"{path}: valid"), passed.output
    swept = invoke("sweep", path, "--set", "integrator.dt=1e-3", "--out", tmp_path / "s", "-q")
    variant = message.replace("error: ", "error: variant integrator.dt=1e-3: ")  # which one
    assert_one_line_error(swept, variant, "--allow-unstable-dt to run anyway")
    plan = tmp_path / "plan.toml"
    plan.write_text(f'kind = "sweep"\nscenario = "{path}"\nset = ["integrator.dt=1e-3,1e-7"]\n')
    assert_one_line_error(invoke("validate", plan), variant)
    passed = invoke("validate", plan, "--allow-unstable-dt")
    assert passed.exit_code == 0 and "valid sweep: 2 variants" in passed.output, passed.output
    allowed = invoke(
        "run",
        path,
        "--set",
        "integrator.dt=1e-3",
        "--set",
        "stages.0.steps=10",
        "--out",
        tmp_path / "b",
        "--allow-unstable-dt",
        "--no-reverse",
        "-q",
    )
    assert allowed.exit_code == 0, allowed.output


def test_a_yaml_scenario_runs_and_reverses(tmp_path):
    result = invoke("run", CONFIGS / "smoke" / "collision.yaml", "--out", tmp_path, "-q")
    assert result.exit_code == 0, result.output
    verdict = json.loads((tmp_path / "collision_smoke.compare.json").read_text())
    assert verdict["reversible"] and verdict["max_position_error_rel"] <= 1e-10


@pytest.mark.parametrize(
    "path",
    sorted(p for p in CONFIGS.rglob("*") if p.suffix in (".toml", ".yaml")),
    ids=lambda p: str(p.relative_to(CONFIGS)),
)
def test_every_shipped_file_validates(path):
    result = invoke("validate", path)
    assert result.exit_code == 0, result.output
    assert result.output.startswith(f"{path}: valid")


def test_info_system_names_the_threading_layer_loaded_and_the_threads():
    from revdem_cli.kernels import LAYERS

    result = CliRunner().invoke(app, ["info", "--system", "--json"])
    assert result.exit_code == 0, result.output
    system = json.loads(result.stdout)
    assert system["threading_layer"] in LAYERS
    assert 1 <= system["threads"] <= system["thread_pool"]
    assert system["pool_helpers"] == system["thread_pool"] - 1  # the regions' threads
    assert system["cores_available"] >= 1
    assert_one_line_error(CliRunner().invoke(app, ["info"]), "or --system")


def test_more_threads_than_the_pool_is_refused_naming_the_option(tmp_path):
    result = CliRunner().invoke(
        app,
        [
            "run",
            str(CONFIGS / "smoke" / "collision.yaml"),
            "--out",
            str(tmp_path),
            "--threads",
            "999",
        ],
    )
    assert_one_line_error(result, "--threads 999", "NUMBA_NUM_THREADS")
    assert not list(tmp_path.iterdir())


def test_a_single_valued_option_given_twice_is_refused_and_set_may_repeat(scenario, tmp_path):
    """Every command takes an option that holds one value once (a second --out was taken,
    the first dropped); --set, meant to repeat, still does."""
    path = scenario()
    result = invoke("run", path, "--out", tmp_path / "a", "--out", tmp_path / "b", "-q")
    assert_one_line_error(result, "run: --out is given 2 times; give it once")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    result = invoke("validate", path, "--set", "stages.0.steps=20", "--set", "integrator.dt=1e-8")
    assert result.exit_code == 0 and "at most 20 steps" in result.output, result.output


def test_a_field_path_as_an_error_names_it_is_taken_by_set(tmp_path):
    """Errors name a field `stages[0].steps`, --set took only `stages.0.steps`: the path
    copied from an error into --set was "not a table or a list". Both are taken, as one."""
    path = CONFIGS / "collision.toml"
    assert invoke("validate", path, "--set", "stages[0].steps=100").exit_code == 0
    twice = invoke("validate", path, "--set", "stages[0].steps=100", "--set", "stages.0.steps=2")
    assert_one_line_error(twice, "stages.0.steps is given twice (also --set stages[0].steps=100)")
    sweep = invoke("sweep", path, "--set", "stages[0].steps=10,20", "--set", "stages.0.steps=3",
                   "--out", tmp_path)  # fmt: skip
    assert_one_line_error(sweep, "stages.0.steps is given twice")
