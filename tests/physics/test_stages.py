"""Staged protocols: each stage with its own time step, damping and wall velocities."""

import math

import h5py
import numpy as np
import pytest

from revdem_cli.config import Scenario
from revdem_cli.engine import run_scenario
from revdem_cli.errors import InputError
from tests.physics.test_friction import on_plane


def settle_then_push(lift=0.01):
    data = on_plane(friction=math.inf).model_dump()
    data["particles"][0]["position"] = (0.0, 0.0, 0.0052)  # dropped from 0.2 mm
    data["stages"] = [
        {
            "name": "settle",
            "steps": 4000,
            "dt": 1e-5,
            "output_every": 500,
            "damping": {"local": 0.7},
        },
        {
            "name": "push",
            "steps": 6000,
            "dt": 5e-6,
            "output_every": 500,
            "reverse": True,
            "wall_velocities": {"plane": (0.0, 0.0, lift)},
        },
    ]
    return Scenario.model_validate(data)


def test_each_stage_runs_with_its_own_time_step_damping_and_wall_motion(tmp_path):
    lift = 0.01
    outputs = run_scenario(settle_then_push(lift), "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        time = f["particles/all/position/time"][:]
        steps = f["particles/all/position/step"][:]
        z = f["particles/all/position/value"][:, 0, 2]
        kinetic = f["observables/kinetic_energy/value"][:]
        kinetic_steps = f["observables/kinetic_energy/step"][:]
    assert time[-1] == pytest.approx(4000 * 1e-5 + 6000 * 5e-6, rel=1e-12)
    settled = np.nonzero(steps == 4000)[0][0]
    assert kinetic[kinetic_steps == 4000][0] < 1e-12  # at rest after the damped stage
    # undamped, the plane lifts the resting sphere by lift x duration
    assert z[-1] - z[settled] == pytest.approx(lift * 6000 * 5e-6, rel=0.02)
    verdict = outputs.verdict
    assert verdict["reversible"] and verdict["max_position_error_rel"] < 1e-10
    assert verdict["frames_compared"] == 13  # the push stage only: steps 4000 to 10000


def test_a_stage_naming_a_wall_that_does_not_exist_is_refused():
    data = settle_then_push().model_dump()
    data["stages"][1]["wall_velocities"] = {"lid": (0.0, 0.0, 1.0)}
    with pytest.raises(ValueError, match=r"stages\[1\]\.wall_velocities\.lid: no wall is named"):
        Scenario.model_validate(data)


def test_the_time_step_guard_checks_every_stage(tmp_path):
    data = settle_then_push().model_dump()
    data["stages"][0]["dt"] = 1e-2
    with pytest.raises(InputError, match=r"stages\[0\]\.dt = 0\.01 s is .* times the critical"):
        run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)


def test_a_frictionless_sphere_bounces_elastically_off_the_inside_of_a_cylinder(tmp_path):
    data = on_plane(tangential="none").model_dump()
    data["gravity"] = (0.0, 0.0, 0.0)
    data["particles"][0].update(position=(0.09, 0.0, 0.5), velocity=(0.3, 0.4, 0.0))
    data["walls"] = [
        {
            "name": "tube",
            "type": "cylinder",
            "material": "plane",
            "point": (0.0, 0.0, 0.0),
            "normal": (0.0, 0.0, 1.0),
            "radius": 0.1,
        }
    ]
    data["stages"] = [
        {
            "name": "bounce",
            "steps": 30000,
            "dt": 1e-6,
            "output_every": 1000,
            "observables_every": 100,
            "reverse": True,
        }
    ]
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        x = f["particles/all/position/value"][:, 0]
        total = f["observables/total_energy/value"][:]
        elastic = f["observables/elastic_energy/value"][:]
    assert elastic.max() > 0.1 * total[0]  # it hit the wall
    assert np.hypot(x[:, 0], x[:, 1]).max() < 0.1  # and stayed inside
    assert np.ptp(total) < 1e-6 * total[0]
    assert outputs.verdict["reversible"] and outputs.verdict["max_position_error_rel"] < 1e-10


def test_a_stage_ends_at_the_first_frame_where_its_stop_condition_holds(tmp_path):
    data = settle_then_push().model_dump()
    data["stages"][0].update(steps=40000, stop_when={"kinetic_energy_below": 1e-12})
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        steps = f["particles/all/position/step"][:]
        time = f["particles/all/position/time"][:]
        kinetic = f["observables/kinetic_energy/value"][:]
        kinetic_steps = f["observables/kinetic_energy/step"][:]
    push_start = int(steps[-1]) - 6000
    assert push_start < 40000 and push_start % 500 == 0  # ended early, at a frame
    assert kinetic[kinetic_steps == push_start][0] < 1e-12
    assert kinetic[kinetic_steps == push_start - 500][0] >= 1e-12  # not a frame earlier
    stage = Scenario.model_validate(data).stages[0]  # the run says where its condition ended it
    assert outputs.stopped == {stage.name: (push_start, 40000, stage.observable_interval)}
    assert time[-1] == pytest.approx(push_start * 1e-5 + 6000 * 5e-6, rel=1e-12)
    verdict = outputs.verdict
    assert verdict["reversible"] and verdict["frames_compared"] == 13
    assert min(verdict["frames"]["step"]) == push_start


def test_a_wall_pushing_down_stops_when_its_force_exceeds_the_target(tmp_path):
    data = settle_then_push().model_dump()
    data["walls"].append(
        {
            "name": "lid",
            "type": "plane",
            "material": "plane",
            "point": (0.0, 0.0, 0.0105),
            "normal": (0.0, 0.0, -1.0),
        }
    )
    data["stages"][1] = {
        "name": "press",
        "steps": 20000,
        "dt": 5e-6,
        "output_every": 100,
        "wall_velocities": {"lid": (0.0, 0.0, -0.01)},
        "stop_when": {"wall_force_above": {"wall": "lid", "force": 0.02}},
    }
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        lid = np.linalg.norm(f["observables/wall_force/lid/value"][:], axis=1)
        steps = f["observables/wall_force/lid/step"][:]
    assert steps[-1] < 4000 + 20000  # stopped early
    assert lid[-1] > 0.02 and (lid[steps <= steps[-1] - 100] <= 0.02).all()
    assert outputs.unmet == {}
    data["stages"][1]["steps"] = 1000  # the lid does not reach the packing: not met, and said
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path / "short")
    assert "press" not in outputs.stopped
    assert outputs.unmet == {"press": {"wall_force_above": {"wall": "lid", "force": 0.02}}}


def test_a_stage_short_of_rest_says_how_much_of_its_energy_is_spin(tmp_path):
    """A sphere resting on a plane and spinning about the vertical, its contact's normal:
    no law resists twisting and local damping leaves a spin no moment drives, so a stage
    asking for rest runs all its steps. The summary says its kinetic energy at the end,
    1/2 I w^2 within the settling's, and that all of it is rotation (a user waited on a
    stage that could never end)."""
    from rich.console import Console

    from revdem_cli.report import summary

    data = settle_then_push().model_dump()
    data["particles"][0]["angular_velocity"] = (0.0, 0.0, 17.0)
    data["stages"] = data["stages"][:1]
    data["stages"][0]["stop_when"] = {"kinetic_energy_below": 1e-9, "after_steps": 2000}
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    left = outputs.unmet["settle"]
    radius, density = data["particles"][0]["radius"], data["materials"]["sphere"]["density"]
    inertia = 0.4 * (4 / 3 * math.pi * radius**3 * density) * radius**2
    assert left["kinetic_energy_at_end"] == pytest.approx(0.5 * inertia * 17.0**2, rel=1e-3)
    assert left["rotation_share"] > 0.999
    console = Console(record=True, width=200)
    summary.print_summary(outputs, console)
    said = " ".join(console.export_text().split())
    assert "without kinetic_energy_below 1e-09 (from step 2000 of the stage): " in said
    assert "J at its end, 100% of it the spheres' rotation" in said


def test_the_summary_says_where_a_stop_condition_ended_a_stage_and_when_at_once():
    """A pour from rest meets kinetic_energy_below at its first check: said, not silent."""
    from rich.console import Console

    from revdem_cli.engine import Outputs
    from revdem_cli.report import summary

    console = Console(record=True, width=200)
    outputs = Outputs(
        stopped={"settle": (28000, 60000, 500), "pour": (500, 200000, 500)},
        unmet={
            "rest": {"kinetic_energy_below": 1e-8},
            "fill": {"after_steps": 2000, "solid_fraction_above": 0.6},
        },
    )
    summary.print_summary(outputs, console)
    lines = console.export_text().splitlines()
    assert lines[0].split() == "stopped stage settle after 28000 of 60000 steps".split()
    assert lines[1].endswith("pour after 500 of 200000 steps, at its first check: its "
                             "condition held from its start")  # fmt: skip
    assert lines[2].split() == (  # a stage that ran all its steps: its condition not met
        "not met stage rest ran all its steps without kinetic_energy_below 1e-08".split()
    )
    assert (
        lines[3].split()
        == (
            "not met stage fill ran all its steps without solid_fraction_above 0.6 (from step 2000 "
            "of the stage)"
        ).split()
    )


def test_a_drop_from_rest_is_checked_for_rest_only_after_the_steps_it_asks(tmp_path):
    """The sphere dropped from rest 0.2 mm above the plane has 2.5e-8 J after its first
    100 steps, below a threshold of 1e-7 J: kinetic_energy_below ends the stage at its
    first check, in mid-air. With after_steps the first check waits past the fall (6.4 ms,
    640 steps), and the stage ends at rest on the plane."""
    data = settle_then_push().model_dump()
    data["stages"] = data["stages"][:1]
    data["stages"][0] |= {"steps": 40000, "observables_every": 100}
    data["stages"][0]["stop_when"] = {"kinetic_energy_below": 1e-7}
    at_once = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path / "at_once")
    assert at_once.stopped == {"settle": (100, 40000, 100)}
    with h5py.File(at_once.forward) as f:
        assert f["particles/all/position/value"][-1, 0, 2] > 0.005  # in the air
    data["stages"][0]["stop_when"]["after_steps"] = 2000
    settled = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path / "settled")
    ran = settled.stopped["settle"][0]
    assert 2000 <= ran < 40000
    with h5py.File(settled.forward) as f:
        z = f["particles/all/position/value"][-1, 0, 2]
        kinetic = f["observables/kinetic_energy/value"][-1]
    assert kinetic < 1e-7 and z < 0.005  # on the plane, pressed into it by its weight
