"""Generated hostile overrides (hypothesis, derandomized): whatever `--set` path and value it
draws, on whichever shipped scenario, `revdem validate` and a short `revdem run` end with
exit status 0, 1 or 2 and at most one line on stderr: never a traceback, never a crash (a
crash of the compiled kernels would take the test process down with it)."""

import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS

runner = CliRunner()
SCENARIOS = ("collision", "collision_shear", "drop_A", "fcc_triaxial", "rolling_resistance")


def leaf_paths(node, prefix="") -> list[str]:
    """Every field path of a scenario file, lists by index, as `--set` takes them."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = ((str(k), v) for k, v in enumerate(node))
    else:
        return [prefix]
    found = []
    for key, value in items:
        found += leaf_paths(value, f"{prefix}.{key}" if prefix else key)
    return found


FILES = {name: tomllib.loads((CONFIGS / f"{name}.toml").read_text()) for name in SCENARIOS}
PATHS = {name: leaf_paths(data) for name, data in FILES.items()}
EXTRA = ["integrator.dt.x", "stages.9.steps", "cell.size", "walls.0.radius", "contact.rolling",
         "particles.0", "stages", "neighbours.skin", "output.figures", "unknown.field"]  # fmt: skip

NUMBERS = st.sampled_from(
    ["0", "-1", "1e-300", "1e300", "-1e300", "1e17", "nan", "inf", "-inf", "9223372036854775808",
     "0.5", "2", "1e-9", "-0.0", "4.9e-324"]
)  # fmt: skip
TEXT = st.sampled_from(['"auto"', '"hertz"', '"none"', "true", '""', '"x" ', "'}'", "[", "{"])
LISTS = st.sampled_from(
    ["[]", "[1e300,0,0]", "[0,0]", "[0,0,0,0]", "[nan,0,0]", "[1e17,0,0]", '["a",0,0]',
     "[[0]]", "{a = 1}", "[-1,-1,-1]"]
)  # fmt: skip
VALUES = st.one_of(NUMBERS, TEXT, LISTS)

SETTINGS = settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def settings_of(data, count: int) -> tuple[str, list[str]]:
    name = data.draw(st.sampled_from(SCENARIOS))
    paths = st.sampled_from(PATHS[name] + EXTRA)
    overrides = [f"{data.draw(paths)}={data.draw(VALUES)}" for _ in range(count)]
    return name, overrides


def ends_cleanly(result) -> None:
    assert result.exit_code in (0, 1, 2), (result.exit_code, result.output, result.exception)
    assert len(result.stderr.strip().splitlines()) <= 1, result.stderr
    assert "Traceback" not in result.output


@settings(SETTINGS, max_examples=300)
@given(data=st.data())
def test_validate_takes_any_override(tried, data):
    name, overrides = settings_of(data, data.draw(st.integers(1, 3)))
    sets = [part for item in overrides for part in ("--set", item)]
    tried["fuzzed overrides, validate"] = tried.get("fuzzed overrides, validate", 0) + 1
    ends_cleanly(runner.invoke(app, ["validate", str(CONFIGS / f"{name}.toml"), *sets]))


@settings(SETTINGS, max_examples=40)
@given(data=st.data())
def test_a_short_run_takes_any_override(tried, data, tmp_path_factory):
    name, overrides = settings_of(data, 1)
    out = tmp_path_factory.mktemp("fuzz")
    stages = range(len(FILES[name]["stages"]))
    short = [f"stages.{k}.{field}" for k in stages for field in ("steps=30", "output_every=10")]
    sets = [part for item in overrides + short for part in ("--set", item)]
    tried["fuzzed overrides, run"] = tried.get("fuzzed overrides, run", 0) + 1
    args = ["run", str(CONFIGS / f"{name}.toml"), "--out", str(out), "-q", *sets]
    ends_cleanly(runner.invoke(app, args))


@pytest.fixture(scope="module", autouse=True)
def _numba_warm(tmp_path_factory):
    """Compile the kernels once, outside the examples' timing."""
    out = tmp_path_factory.mktemp("warm")
    args = ["run", str(CONFIGS / "collision.toml"), "--out", str(out), "-q", "--set",
            "stages.0.steps=10"]  # fmt: skip
    assert runner.invoke(app, args).exit_code == 0
