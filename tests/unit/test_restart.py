import numpy as np

from revdem_cli.engine import run_scenario
from revdem_cli.io.restart import read_restart, write_restart
from tests.conftest import two_spheres


def listed(pairs, name):
    """The meaningful part of a pair-list array: the listed pairs, or all of a per-particle one."""
    n = int(pairs.count[0])
    whole = {"first": pairs.first, "start": pairs.start, "x_built": pairs.x_built}
    return {**whole, "slots": pairs.slots[:n]}.get(name, getattr(pairs, name)[:n])


def test_restart_round_trip_keeps_every_array_bit_for_bit(tmp_path):
    outputs = run_scenario(two_spheres(), "text", ".toml", tmp_path, reverse=False)
    first = read_restart(outputs.restart)
    write_restart(tmp_path / "again.h5", first)
    second = read_restart(tmp_path / "again.h5")
    assert second.state.step == first.state.step == 6000
    assert first.state.pairs.count[0] == 1
    for name, a in first.state.particles._asdict().items():
        np.testing.assert_array_equal(a, getattr(second.state.particles, name), err_msg=name)
    for name in ("i", "j", "history", "force", "first", "start", "slots", "x_built"):
        np.testing.assert_array_equal(
            listed(first.state.pairs, name), listed(second.state.pairs, name), err_msg=name
        )
    for name, a in first.state.cell._asdict().items():
        np.testing.assert_array_equal(a, getattr(second.state.cell, name), err_msg=name)
    assert second.scenario_json == first.scenario_json and second.scenario_text == "text"
