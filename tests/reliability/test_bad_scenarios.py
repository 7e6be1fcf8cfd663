"""Broken scenario files, generated: `revdem run` refuses every one with exit status 2 and one
line naming the file and the field, without a traceback, before it writes anything.

Each test starts from a valid small scenario (configs/collision.toml, configs/smoke/
collision.yaml and configs/drop_A.toml, shortened, and two built here: two spheres in a
cylinder on a floor, and packings on a floor), breaks it in one way, writes it as TOML or
YAML and runs the real command line. Hypothesis draws the examples deterministically
(derandomize); how many were tried is printed after the test run ("reliability: N generated
bad inputs tried").
"""

import copy
import datetime
import json
import math
import os
import re
import string
import tempfile
from pathlib import Path
from unittest import mock

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from revdem_cli import config
from revdem_cli.cli import app
from revdem_cli.config import host, schema
from tests.conftest import CONFIGS, assert_one_line_error

EXAMPLES = 30
"""Generated examples per test."""

SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)

runner = CliRunner()


def _short(data: dict, name: str) -> dict:
    """A scenario cut to 200 steps a stage, so that a broken file let through runs briefly."""
    data = copy.deepcopy(data)
    data["name"] = name
    for stage in data["stages"]:
        stage.update(steps=200, output_every=50)
        if "observables_every" in stage:
            stage["observables_every"] = 10
    return data


WALL = {"density": 1000.0, "shear_modulus": 1.0e9, "poisson_ratio": 0.2}
FLOOR = {
    "name": "floor",
    "type": "plane",
    "material": "wall",
    "point": [0.0, 0.0, -0.006],
    "normal": [0.0, 0.0, 1.0],
}
SIDE = {
    "name": "side",
    "type": "cylinder",
    "material": "wall",
    "point": [0.0, 0.0, 0.0],
    "normal": [0.0, 0.0, 1.0],
    "radius": 0.03,
}


def _read(name: str) -> dict:
    path = CONFIGS / name
    return config.parse_text(path.read_text(), path.suffix, name)


COLLISION = _short(_read("collision.toml"), "collision")
SMOKE = _short(_read("smoke/collision.yaml"), "smoke")
DROP = _short(_read("drop_A.toml"), "drop")
CONTAINED = {
    **copy.deepcopy(SMOKE),
    "name": "contained",
    "materials": {**SMOKE["materials"], "wall": WALL},
    "walls": [FLOOR, SIDE],
}
PACKED = {key: value for key, value in copy.deepcopy(COLLISION).items() if key != "particles"} | {
    "name": "packed",
    "materials": {**COLLISION["materials"], "wall": WALL},
    "gravity": [0.0, 0.0, -9.81],
    "packings": [
        {
            "count": 5,
            "material": "sphere",
            "radius_min": 0.001,
            "radius_max": 0.0015,
            "seed": 2,
            "region": {"shape": "box", "origin": [-0.01, -0.01, -0.006], "size": [0.02] * 3},
        },
        {
            "count": 3,
            "material": "sphere",
            "radius_min": 0.001,
            "radius_max": 0.001,
            "region": {"shape": "cylinder", "origin": [0.05, 0.0, -0.006], "radius": 0.01}
            | {"height": 0.01},
        },
    ],
    "walls": [FLOOR],
}
BASES = {
    "collision.toml": (COLLISION, ".toml"),
    "smoke.yaml": (SMOKE, ".yaml"),
    "drop.toml": (DROP, ".toml"),
    "contained.yaml": (CONTAINED, ".yaml"),
    "packed.toml": (PACKED, ".toml"),
}
WITH_PARTICLES = ["collision.toml", "smoke.yaml", "drop.toml", "contained.yaml"]
WITH_WALLS = ["drop.toml", "contained.yaml", "packed.toml"]


# Writing scenarios --------------------------------------------------------------------


def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, datetime.date):
        return value.isoformat()
    if isinstance(value, list | tuple):
        return "[" + ", ".join(map(_toml, value)) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_key(k)} = {_toml(v)}" for k, v in value.items()) + "}"
    raise TypeError(value)


def text_of(data: dict, suffix: str) -> str:
    """A scenario as TOML (every table inline) or YAML."""
    if suffix == ".yaml":
        return yaml.safe_dump(data, sort_keys=False)
    return "".join(f"{_key(key)} = {_toml(value)}\n" for key, value in data.items())


def field(path: tuple) -> str:
    """A path into the scenario as revdem names it: particles[1].position[2]."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text


def refused(tried: dict, what: str, data: dict, suffix: str, *fragments: str) -> str:
    """`revdem run` on the scenario: exit 2, one line naming the file and the fragments,
    and nothing written into the output directory; the line, after the file's name."""
    tried[what] = tried.get(what, 0) + 1
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"broken{suffix}"
        path.write_text(text_of(data, suffix))
        out = Path(folder) / "out"
        result = runner.invoke(app, ["run", str(path), "--out", str(out), "-q"])
        assert_one_line_error(result, f"error: {path}: ", *fragments)
        assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())
        return result.output.strip().removeprefix(f"error: {path}: ")


# Finding places to break --------------------------------------------------------------


def _walk(node, path=()):
    """(path, value) of every node below the root, depth first."""
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for key, value in items:
        yield path + (key,), value
        if isinstance(value, dict | list):
            yield from _walk(value, path + (key,))


def _get(data, path):
    for part in path:
        data = data[part]
    return data


def _set(data, path, value) -> None:
    _get(data, path[:-1])[path[-1]] = value


MODELS = {
    (): config.Scenario,
    ("contact",): config.Contact,
    ("integrator",): config.Integrator,
    ("reversal",): config.Reversal,
    ("output",): config.Output,
    ("damping",): config.Damping,
    ("materials", "*"): config.Material,
    ("particles", "#"): config.Particle,
    ("stages", "#"): config.Stage,
    ("walls", "#"): config.Wall,
    ("packings", "#"): config.Packing,
    ("packings", "#", "region"): config.Region,
}
"""Tables of a scenario and their models: '*' any name, '#' any index."""


def _pattern(path: tuple) -> tuple:
    return tuple("#" if isinstance(p, int) else p for p in path)


def model_of(path: tuple, data: dict):
    pattern = _pattern(path)
    if len(path) == 2 and path[0] == "materials":
        pattern = ("materials", "*")
    return MODELS.get(pattern)


@st.composite
def base(draw, names=tuple(BASES)):
    name = draw(st.sampled_from(sorted(names)))
    data, suffix = BASES[name]
    return copy.deepcopy(data), suffix


LETTERS = st.text(alphabet=string.ascii_letters, min_size=1, max_size=10)
NUMBERS = st.one_of(
    st.integers(-(10**6), 10**6), st.floats(allow_nan=False, allow_infinity=False, width=32)
)
LISTS = st.lists(st.integers(-3, 3), min_size=0, max_size=3)
DICTS = st.dictionaries(st.sampled_from(["a", "b", "value"]), st.integers(), min_size=1)
DATES = st.dates(datetime.date(1900, 1, 1), datetime.date(2100, 1, 1))


def wrong_for(value):
    """Values of another type than `value` (as a scenario field would have it)."""
    if isinstance(value, bool):
        return st.one_of(LETTERS, NUMBERS, LISTS, DICTS)
    if isinstance(value, int | float):
        return st.one_of(LETTERS, st.booleans(), LISTS, DICTS, DATES)
    if isinstance(value, str):
        return st.one_of(NUMBERS, st.booleans(), LISTS, DICTS, DATES)
    if isinstance(value, list):
        return st.one_of(LETTERS, NUMBERS, st.booleans(), DICTS)
    return st.one_of(LETTERS, NUMBERS, st.booleans(), LISTS)


def _matches(path: tuple, patterns) -> bool:
    return any(
        len(p) == len(path) and all(a in ("*", "#") or a == b for a, b in zip(p, path, strict=True))
        for p in patterns
    )


# The tests ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(BASES))
def test_every_starting_scenario_is_valid_and_written_faithfully(name, tmp_path):
    data, suffix = BASES[name]
    path = tmp_path / f"{name}{suffix}"
    path.write_text(text_of(data, suffix))
    assert config.parse_text(path.read_text(), suffix, name) == data
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output


@SETTINGS
@given(st.data())
def test_a_value_of_the_wrong_type_is_named(tried, data):
    scenario, suffix = data.draw(base())
    path, value = data.draw(st.sampled_from(list(_walk(scenario))))
    _set(scenario, path, data.draw(wrong_for(value)))
    refused(tried, "wrong type", scenario, suffix, field(path))


REQUIRED = [
    ("name",),
    ("materials",),
    ("contact",),
    ("integrator",),
    ("stages",),
    ("contact", "model"),
    ("integrator", "dt"),
    ("materials", "*", "density"),
    ("materials", "*", "shear_modulus"),
    ("materials", "*", "poisson_ratio"),
    ("particles", "#", "material"),
    ("particles", "#", "radius"),
    ("particles", "#", "position"),
    ("stages", "#", "name"),
    ("stages", "#", "steps"),
    ("walls", "#", "name"),
    ("walls", "#", "type"),
    ("walls", "#", "material"),
    ("walls", "#", "point"),
    ("walls", "#", "normal"),
    ("walls", "#", "radius"),
    ("packings", "#", "count"),
    ("packings", "#", "material"),
    ("packings", "#", "radius_min"),
    ("packings", "#", "radius_max"),
    ("packings", "#", "region"),
    ("packings", "#", "region", "shape"),
    ("packings", "#", "region", "origin"),
    ("packings", "#", "region", "radius"),
    ("packings", "#", "region", "height"),
    ("packings", "#", "region", "size"),
]


@SETTINGS
@given(st.data())
def test_a_missing_required_field_is_named(tried, data):
    scenario, suffix = data.draw(base())
    paths = [path for path, _ in _walk(scenario) if _matches(path, REQUIRED)]
    if "packings" not in scenario:
        paths.append(("particles",))
    path = data.draw(st.sampled_from(paths))
    del _get(scenario, path[:-1])[path[-1]]
    if path == ("particles",):
        expected = ["particles: no spheres"]
    elif path[-1] in ("radius", "height", "size") and path[0] in ("walls", "packings"):
        expected = [f"{field(path[:-1])}: a "]  # the cylinder or box that lost a dimension
    else:
        expected = [f"{field(path)}: missing required field"]
    refused(tried, "missing field", scenario, suffix, *expected)


@SETTINGS
@given(st.data())
def test_a_misspelt_required_field_is_named_with_the_field_meant(tried, data):
    """A required field under a name one letter off: the line names the misspelling and the
    field meant, whose absence is the same problem, not counted again (it was the missing
    field, the misspelling hidden behind "(and 1 more problem)")."""
    scenario, suffix = data.draw(base())
    path = data.draw(st.sampled_from([p for p, _ in _walk(scenario) if _matches(p, REQUIRED)]))
    name = path[-1]
    typo = data.draw(st.sampled_from([name[:-1], name + "s", name[0] + name[2:]]))
    table = _get(scenario, path[:-1])
    table[typo] = table.pop(name)
    line = refused(tried, "misspelt field", scenario, suffix)
    assert line == f"{field(path[:-1] + (typo,))}: unknown field (did you mean {name}?)"


@SETTINGS
@given(st.data())
def test_an_unknown_field_is_named(tried, data):
    scenario, suffix = data.draw(base())
    tables = [()] + [path for path, _ in _walk(scenario) if model_of(path, scenario)]
    path = data.draw(st.sampled_from(tables))
    known = set(model_of(path, scenario).model_fields)
    if path == ():  # a kind says the file is no scenario (tests/cli/test_sweep.py)
        known.add("kind")
    key = data.draw(
        st.from_regex(r"[a-z][a-z_]{0,11}", fullmatch=True).filter(lambda k: k not in known)
    )
    _get(scenario, path)[key] = data.draw(st.one_of(NUMBERS, LETTERS, st.booleans()))
    refused(tried, "unknown field", scenario, suffix, f"{field(path + (key,))}: unknown field")


SIZES = [
    ("particles", "#", "radius"),
    ("materials", "*", "density"),
    ("materials", "*", "shear_modulus"),
    ("integrator", "dt"),
    ("stages", "#", "steps"),
    ("stages", "#", "output_every"),
    ("stages", "#", "observables_every"),
    ("walls", "#", "radius"),
    ("packings", "#", "count"),
    ("packings", "#", "radius_min"),
    ("packings", "#", "radius_max"),
    ("packings", "#", "region", "radius"),
    ("packings", "#", "region", "height"),
    ("packings", "#", "region", "size", "#"),
    ("reversal", "position_tolerance_rel"),
    ("reversal", "velocity_tolerance"),
]


@SETTINGS
@given(st.data())
def test_a_negative_or_zero_size_is_named(tried, data):
    scenario, suffix = data.draw(base())
    path = data.draw(st.sampled_from([p for p, _ in _walk(scenario) if _matches(p, SIZES)]))
    if isinstance(_get(scenario, path), int):
        value = data.draw(st.integers(-(10**9), 0))
    else:
        value = data.draw(
            st.one_of(st.just(-0.0), st.floats(max_value=0.0, allow_infinity=False)).filter(
                lambda v: not math.isnan(v)
            )
        )
    _set(scenario, path, value)
    expected = field(path[:-2]) if path[-2] == "size" else field(path)  # the box as a whole
    refused(tried, "non-positive size", scenario, suffix, expected)


@SETTINGS
@given(st.data())
def test_nan_and_inf_are_refused_where_a_finite_number_is_needed(tried, data):
    scenario, suffix = data.draw(base())
    numbers = [
        path
        for path, value in _walk(scenario)
        if isinstance(value, int | float) and not isinstance(value, bool)
    ]
    path = data.draw(st.sampled_from(numbers))
    _set(scenario, path, data.draw(st.sampled_from([math.nan, math.inf, -math.inf])))
    refused(tried, "nan or inf", scenario, suffix, field(path))


def _unit(draw) -> list[float]:
    vector = draw(
        st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: math.hypot(*v) > 0.1)
    )
    return [c / math.hypot(*vector) for c in vector]


@SETTINGS
@given(st.data())
def test_overlapping_particles_are_named(tried, data):
    scenario, suffix = data.draw(base(WITH_PARTICLES))
    particles = scenario["particles"]
    i = data.draw(st.integers(0, len(particles) - 1))
    near = particles[i]
    radius = near["radius"] * data.draw(st.floats(0.5, 2.0))
    distance = (near["radius"] + radius) * (1.0 - data.draw(st.floats(0.05, 1.0)))
    u = _unit(data.draw)
    position = [x + distance * c for x, c in zip(near["position"], u, strict=True)]
    particles.append({"material": near["material"], "radius": radius, "position": position})
    refused(
        tried, "overlap", scenario, suffix, f"particles[{len(particles) - 1}].position", "overlaps"
    )


@SETTINGS
@given(st.data())
def test_a_sphere_outside_the_walls_is_named(tried, data):
    name = data.draw(st.sampled_from(["drop.toml", "contained.yaml", "packed.toml"]))
    scenario, suffix = copy.deepcopy(BASES[name][0]), BASES[name][1]
    floor = scenario["walls"][0]
    how = data.draw(st.sampled_from(["below the floor", "outside the cylinder"]))
    if name == "packed.toml":  # a packing's region below the floor
        k = data.draw(st.integers(0, 1))
        region = scenario["packings"][k]["region"]
        region["origin"][2] = floor["point"][2] - data.draw(st.floats(0.03, 1.0))
        refused(tried, "outside walls", scenario, suffix, f"packings[{k}]: ", "plane wall")
        return
    i = data.draw(st.integers(0, len(scenario["particles"]) - 1))
    sphere = scenario["particles"][i]
    r = sphere["radius"]
    depth = r * (0.99 - data.draw(st.floats(0.02, 50.0)))  # centre height or distance inside
    if how == "below the floor" or name == "drop.toml":
        sphere["position"][2] = floor["point"][2] + depth
        wall = f"plane wall '{floor['name']}'"
    else:
        angle = data.draw(st.floats(0.0, 2.0 * math.pi))
        rho = SIDE["radius"] - depth
        sphere["position"][:2] = [rho * math.cos(angle), rho * math.sin(angle)]
        others = [p["position"] for j, p in enumerate(scenario["particles"]) if j != i]
        if any(math.dist(sphere["position"], x) < 2.05 * r for x in others):
            sphere["position"][:2] = [-rho * math.cos(angle), -rho * math.sin(angle)]
        wall = "cylinder wall 'side'"
    refused(tried, "outside walls", scenario, suffix, f"particles[{i}].position: ", wall)


@SETTINGS
@given(st.data())
def test_a_packing_outside_a_cylinder_is_named(tried, data):
    scenario = copy.deepcopy(CONTAINED)
    x = data.draw(st.floats(SIDE["radius"] + 0.001, 1.0))
    count = data.draw(st.integers(1, 20))
    scenario["packings"] = [
        {
            "count": count,
            "material": "sphere",
            "radius_min": 0.001,
            "radius_max": 0.002,
            "region": {"shape": "box", "origin": [x, -0.01, 0.0], "size": [0.02, 0.02, 0.02]},
        }
    ]
    refused(tried, "outside walls", scenario, ".yaml", "packings[0]: ", "cylinder wall 'side'")


@SETTINGS
@given(st.data())
def test_a_time_step_not_above_zero_is_named(tried, data):
    scenario, suffix = data.draw(base())
    path = data.draw(st.sampled_from([("integrator", "dt"), ("stages", 0, "dt")]))
    value = data.draw(
        st.one_of(st.sampled_from([0.0, -0.0]), st.floats(max_value=-1e-300, allow_infinity=False))
    )
    _set(scenario, path, value)
    refused(tried, "dt <= 0", scenario, suffix, f"{field(path)}: Input should be greater than 0")


@SETTINGS
@given(st.data())
def test_no_stages_is_refused(tried, data):
    scenario, suffix = data.draw(base())
    empty = data.draw(st.sampled_from([[], {}, [{}]]))
    scenario["stages"] = empty
    expected = "stages[0].name: missing required field" if empty == [{}] else "stages: "
    refused(tried, "no stages", scenario, suffix, expected)


STOP = ("stages", 0, "stop_when")
TRAVEL = {"wall_travel_above": {"wall": "floor", "distance": 1e-6}}
"""A stop condition of `contained.yaml` (walls floor and side): the floor has travelled, half
what it travels at 0.1 m/s in the stage's 200 steps of 1e-7 s."""
VELOCITIES = ("stages", 0, "wall_velocities")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (  # the stage ran to its end, "not met ... (from step 500 of the stage)"
            {STOP: {"kinetic_energy_below": 1e-7, "after_steps": 500}},
            "stages[0].stop_when.after_steps: 500 must be below the stage's steps, 200",
        ),
        (
            {STOP: {"kinetic_energy_below": 1e-7, "after_steps": 200}},
            "stages[0].stop_when.after_steps: 200 must be below the stage's steps, 200",
        ),
        (  # its only row from step 199 on is the stage's last: it never ended the stage early
            {STOP: {"kinetic_energy_below": 1e-7, "after_steps": 199}},
            "stages[0].observables_every: 50 (default: output_every, 50) leaves "
            "stages[0].stop_when no observables row to be checked at from its after_steps, 199, "
            "before the stage's last step, 200",
        ),
        (  # no row in the stage but its start and its end: the stage ran all its steps
            {STOP: {"kinetic_energy_below": 1e-7}, ("stages", 0, "observables_every"): 200},
            "stages[0].observables_every: 200 leaves stages[0].stop_when no observables row to "
            "be checked at before the stage's last step, 200: it could never end the stage "
            "early; give observables_every at most 199",
        ),
        (
            {STOP: TRAVEL},
            "stages[0].stop_when.wall_travel_above.wall: wall 'floor' does not move in this "
            "stage: its velocity here is zero (stages[0].wall_velocities.floor, else "
            "walls[0].velocity)",
        ),
        (  # another wall's motion does not move it
            {STOP: TRAVEL, VELOCITIES: {"side": [0.0, 0.0, 0.1]}},
            "wall 'floor' does not move in this stage",
        ),
        (  # the stage stops the wall that [[walls]] moves
            {
                STOP: TRAVEL,
                ("walls", 0, "velocity"): [0.0, 0.0, 0.1],
                VELOCITIES: {"floor": [0] * 3},
            },
            "wall 'floor' does not move in this stage",
        ),
        (  # it moves 2e-6 m in the stage
            {
                STOP: {"wall_travel_above": {"wall": "floor", "distance": 2e-6}},
                VELOCITIES: {"floor": [0.0, 0.06, 0.08]},
            },
            "stages[0].stop_when.wall_travel_above.distance: 2e-06 m is never reached: wall "
            "'floor' moves 2e-06 m in this stage (0.1 m/s for 200 steps of 1e-07 s)",
        ),
    ],
)
def test_a_stop_condition_that_cannot_be_met_is_refused(changes, message):
    """Each was accepted, and its stage ran all its steps."""
    scenario = copy.deepcopy(CONTAINED)
    for path, value in changes.items():
        _set(scenario, path, value)
    refused({}, "written by hand", scenario, ".yaml", message)


@pytest.mark.parametrize(
    "changes",
    [
        {STOP: {"kinetic_energy_below": 1e-7, "after_steps": 150}},  # a row at 150, of 200
        {STOP: TRAVEL, VELOCITIES: {"floor": [0.0, 0.0, 0.1]}},
        {STOP: TRAVEL, ("walls", 0, "velocity"): [0.1, 0.0, 0.0]},  # along its plane: it travels
        {STOP: {"wall_force_above": {"wall": "floor", "force": 1.0}}},  # a still wall is loaded
    ],
)
def test_a_stop_condition_that_can_be_met_is_accepted(tmp_path, changes):
    scenario = copy.deepcopy(CONTAINED)
    for path, value in changes.items():
        _set(scenario, path, value)
    path = tmp_path / "stops.yaml"
    path.write_text(text_of(scenario, ".yaml"))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output


@SETTINGS
@given(st.data())
def test_an_unknown_material_is_named(tried, data):
    scenario, suffix = data.draw(base())
    users = [path for path, _ in _walk(scenario) if _matches(path, [("*", "#", "material")])]
    path = data.draw(st.sampled_from(users))
    name = data.draw(
        st.from_regex(r"[a-z][a-z0-9_]{0,9}", fullmatch=True).filter(
            lambda m: m not in scenario["materials"]
        )
    )
    _set(scenario, path, name)
    refused(tried, "unknown material", scenario, suffix, f"{field(path)}: unknown material")


MEMORY = 64 * 2**20
"""The memory the huge-count tests pretend this machine has, bytes."""


def _no_generation(*args, **kwargs):
    raise AssertionError("spheres were generated for a scenario that cannot fit")


@SETTINGS
@given(st.data())
def test_huge_counts_are_refused_before_anything_is_generated(tried, data):
    scenario, suffix = data.draw(base())
    what = data.draw(st.sampled_from(["spheres", "steps", "frames", "observables"]))
    if what == "spheres":
        fits = MEMORY // host.BYTES_PER_SPHERE  # with no walls at all
        count = data.draw(st.integers(fits + 1, 10**15))
        packings = scenario.setdefault("packings", [])
        packings.append(copy.deepcopy(PACKED["packings"][0]) | {"count": count})
        k = len(packings) - 1
        expected = [f"packings[{k}].count: "]
        limit = schema.MAX_GENERATED
        expected.append(f"less than or equal to {limit}" if count > limit else "memory")
    elif what == "steps":
        scenario["stages"][0]["steps"] = data.draw(st.integers(2**62 + 1, 2**63 - 1))
        expected = ["stages[0].steps: ", "2^62"]
    elif what == "frames":
        stage = scenario["stages"][0]
        stage.update(steps=data.draw(st.integers(10**9, 2**53)), output_every=1)
        stage.pop("observables_every", None)
        expected = ["stages[0].output_every: ", "frames", "memory"]
    else:
        stage = scenario["stages"][0]
        stage.update(observables_every=1, output_every=data.draw(st.integers(10**7, 2**62)))
        expected = ["stages[0].observables_every: ", "memory"]
    with (
        mock.patch.object(host, "memory_bytes", return_value=MEMORY),
        mock.patch("revdem_cli.assembly.packing.place_spheres", _no_generation),
    ):
        refused(tried, "huge count", scenario, suffix, *expected)


PHYSICAL = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.parametrize(
    ("limit", "expected"),
    [
        (None, PHYSICAL),  # no control group file
        ("max\n", PHYSICAL),  # no limit
        ("1048576\n", 1048576),
        (f"{PHYSICAL + 4096}\n", PHYSICAL),  # a limit above the machine's memory
    ],
)
def test_memory_is_this_machines_or_its_control_groups_if_lower(tmp_path, limit, expected):
    path = tmp_path / "memory.max"
    if limit is not None:
        path.write_text(limit)
    with mock.patch.object(host, "CGROUP_LIMIT", path):
        assert host.memory_bytes() == expected


def test_yaml_numbers_are_read_as_yaml_1_2_reads_them():
    text = (CONFIGS / "smoke" / "collision.yaml").read_text().replace("1.0e-7", "1e-7")
    text = text.replace(
        "contact: {model: hertz}", "contact: {model: hertz, tangential: mindlin, friction: inf}"
    )
    scenario = config.scenario_from_text(text, ".yaml", "smoke.yaml")
    assert scenario.integrator.dt == 1e-7 and scenario.contact.friction == math.inf


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (
            ("particles", 0, "radius"),
            True,
            "particles[0].radius: Input should be a valid number, not true",
        ),
        (
            ("particles", 0, "radius"),
            "0.005",
            "particles[0].radius: Input should be a valid number, not the text '0.005'",
        ),
        (
            ("stages", 0, "steps"),
            "200",
            "stages[0].steps: Input should be a valid number, not the text",
        ),
        (("stages", 0, "reverse"), 1, "stages[0].reverse: Input should be a valid boolean"),
        (("stages", 0, "reverse"), "yes", "stages[0].reverse: Input should be a valid boolean"),
    ],
)
def test_what_pydantic_would_read_leniently_is_refused(path, value, message):
    """pydantic alone reads true as 1, "0.005" as 0.005 and 1 or "yes" as true."""
    scenario = copy.deepcopy(COLLISION)
    _set(scenario, path, value)
    refused({}, "written by hand", scenario, ".toml", message)  # not counted as generated
