import numpy as np

from revdem_cli.engine import run_scenario
from revdem_cli.io.restart import CELL_ARRAYS, PAIR_FIELDS, WALL_FIELDS, read_restart, write_restart
from tests.conftest import FLOOR, PLANE, SPHERE, two_spheres

BALL = {"material": "sphere", "radius": 0.005}


def frictional_scene():
    """Two spheres pressed together obliquely and a third rolling on a floor, with shear and
    rolling histories, under gravity, in fixed point: every array a restart keeps in use."""
    return two_spheres(
        materials={"sphere": SPHERE, "plane": PLANE},
        contact={
            "model": "hertz",
            "tangential": "mindlin",
            "friction": 0.5,
            "rolling": "epsd",
            "rolling_stiffness": 1e-3,
            "rolling_friction": 0.1,
        },
        particles=[
            {
                **BALL,
                "position": [0, 0, 0.02],
                "velocity": [0.5, 0.1, 0],
                "angular_velocity": [0, 0, 3.0],
            },
            {**BALL, "position": [0.0097, 0.002, 0.02], "velocity": [-0.5, 0, 0]},
            {
                **BALL,
                "position": [0.03, 0, 0.00499],
                "velocity": [0.2, 0, 0],
                "angular_velocity": [1.0, 0, 0],
            },
        ],
        walls=[FLOOR],
        gravity=[0, 0, -9.81],
        integrator={"dt": 1e-7, "arithmetic": "fixed"},
        stages=[{"name": "collide", "steps": 500, "output_every": 100}],
    )


def listed(pairs, name):
    """The meaningful part of a pair-list array: the listed pairs, or all of a per-particle one."""
    n = int(pairs.count[0])
    whole = {"first": pairs.first, "start": pairs.start, "x_built": pairs.x_built}
    return {**whole, "slots": pairs.slots[:n]}.get(name, getattr(pairs, name)[:n])


def test_restart_round_trip_keeps_every_array_bit_for_bit(tmp_path):
    outputs = run_scenario(frictional_scene(), "text", ".toml", tmp_path, reverse=False)
    first = read_restart(outputs.restart)
    write_restart(tmp_path / "again.h5", first)
    second = read_restart(tmp_path / "again.h5")
    one, two = first.state, second.state
    assert two.step == one.step == 500
    assert one.pairs.count[0] == 1
    for history in (one.pairs.history, one.pairs.rolling, one.walls.history, one.walls.rolling):
        assert np.abs(history).max() > 0  # the contacts' histories are live
    assert np.abs(one.fixed.x).max() > 0
    bundles = (
        ("particles", one.particles._fields),
        ("walls", WALL_FIELDS),
        ("cell", CELL_ARRAYS),
        ("fixed", one.fixed._fields),
    )
    for bundle, names in bundles:
        for name in names:
            a, b = getattr(getattr(one, bundle), name), getattr(getattr(two, bundle), name)
            np.testing.assert_array_equal(a, b, err_msg=f"{bundle}.{name}")
    np.testing.assert_array_equal(one.ids, two.ids, err_msg="ids")
    for name in (*PAIR_FIELDS, "first", "start", "slots", "x_built"):
        np.testing.assert_array_equal(
            listed(one.pairs, name), listed(two.pairs, name), err_msg=f"pairs.{name}"
        )
    assert second.scenario_json == first.scenario_json and second.scenario_text == "text"
