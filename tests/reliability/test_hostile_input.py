"""Hostile input that once crashed revdem (a segmentation fault, a traceback) or slipped past
it: each gets one line and exit status 2 now, and the compiled kernels never see it."""

import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.kernels.neighbours import build_pairs
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()
COLLISION = str(CONFIGS / "collision.toml")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_the_pair_search_takes_any_position_without_leaving_its_grid():
    """A cell coordinate beyond the int64 range (1e17 m in cells of 1 cm) once converted to
    a negative index and wrote outside the grid; far, infinite and NaN positions now land in
    the grid's edge cells, and the pairs found are the true ones."""
    x = np.array([[0.0, 0.0, 0.0], [0.009, 0.0, 0.0], [1e17, 0, 0], [1e300, 0, 0], [-1e300, 0, 0]])
    radius = np.full(len(x), 0.005)
    pair_i, pair_j = np.zeros(16, dtype=np.int32), np.zeros(16, dtype=np.int32)
    periodic, length = np.zeros(3, dtype=np.int64), np.ones(3)
    count = build_pairs(x, radius, 5e-4, periodic, length, pair_i, pair_j)
    assert (count, pair_i[0], pair_j[0]) == (1, 0, 1)
    x[2] = [np.nan, np.inf, -np.inf]
    assert build_pairs(x, radius, 5e-4, periodic, length, pair_i, pair_j) == 1


def test_a_position_float64_cannot_resolve_is_refused():
    result = invoke("validate", COLLISION, "--set", "particles.0.position=[1e17,0,0]")
    assert_one_line_error(
        result,
        "particles[0].position: sphere 0 starts 1e+17 m from the origin, where float64 "
        "resolves a position only to 16 m",
    )
    assert_one_line_error(
        invoke("validate", COLLISION, "--set", "particles.1.position=[0,0,-1e300]"),
        "particles[1].position: sphere 1 starts 1e+300 m from the origin",
    )


@pytest.mark.parametrize(
    ("velocity", "fragment"),
    [
        ("[1e5,0,0]", "is 40 times the kinematic limit 2.5e-09 s (the fastest sphere or wall, "
                      "at 1e+05 m/s, would move more than half the neighbour skin"),
        ("[1e10,0,0]", "times the kinematic limit"),
        ("[1e200,0,0]", "is 4e+196 times the kinematic limit 2.5e-204 s"),
        ("[1e300,1e300,0]", "at 1.41e+300 m/s"),
    ],
)  # fmt: skip
def test_a_step_that_jumps_past_contacts_is_refused(velocity, fragment, tmp_path):
    """At 1e10 m/s two spheres once passed through each other in one step and the run said
    "reversible"; at 1e200 m/s the guard's v² overflowed and the run crashed."""
    result = invoke(
        "run", COLLISION, "--out", tmp_path, "-q", "--set", f"particles.0.velocity={velocity}"
    )
    assert_one_line_error(result, "integrator.dt = 1e-07 s", fragment)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["validate", "run", "sweep"])
def test_setting_a_field_inside_a_value_is_one_line(command, tmp_path):
    args = ["--out", tmp_path] if command != "validate" else []
    value = "1,2" if command == "sweep" else "1"
    result = invoke(command, COLLISION, *args, "--set", f"integrator.dt.x={value}")
    assert_one_line_error(result, "--set integrator.dt.x: 'dt' holds a value, not a table")


def test_a_yaml_key_given_twice_is_refused(tmp_path):
    text = (CONFIGS / "smoke" / "collision.yaml").read_text()
    path = tmp_path / "twice.yaml"
    path.write_text(text + "name: another\n")
    assert_one_line_error(invoke("validate", path), "the key 'name' is given twice")


@pytest.mark.parametrize("suffix", [".toml", ".yaml"])
def test_a_file_nested_without_end_is_refused(suffix, tmp_path):
    path = tmp_path / f"deep{suffix}"
    separator = " = " if suffix == ".toml" else ": "
    path.write_text("name" + separator + "[" * 50000 + "]" * 50000 + "\n")
    assert_one_line_error(invoke("validate", path), f"{path}: nested more than 64 levels deep")
