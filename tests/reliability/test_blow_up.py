"""Blow-ups: a run whose state stops being physical (non-finite values, overlaps deeper than
`integrator.overlap_limit`) stops there with one line naming the step, the particles and
the likely cause, and keeps a readable trajectory of the good states before it."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.config import Scenario
from revdem_cli.kernels.health import HEALTHY, NOT_FINITE, TOO_DEEP, examine
from revdem_cli.state import initial_state
from tests.conftest import CONFIGS, two_spheres


def _failed(result) -> str:
    """The one line of a run that failed (exit 1) without a traceback."""
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    return lines[0]


def _steps_written(path) -> tuple[np.ndarray, np.ndarray]:
    """Frame steps and observables steps of a trajectory, whose positions must be finite."""
    with h5py.File(path) as f:
        assert np.isfinite(f["particles/all/position/value"][:]).all()
        return f["particles/all/position/step"][:], f["observables/kinetic_energy/step"][:]


def test_an_overlap_deeper_than_the_limit_stops_the_run_where_it_happens(tmp_path):
    # the collision's deepest overlap is 0.06 of the radius (Hertz, 0.9 m/s): a limit of
    # 0.01 is passed part-way into the contact, with a time step far below the critical one
    scenario = CONFIGS / "smoke" / "collision.yaml"
    args = ["run", str(scenario), "--out", str(tmp_path), "-q"]
    result = CliRunner().invoke(app, [*args, "--set", "integrator.overlap_limit=0.01"])
    line = _failed(result)
    assert "blown up at step" in line
    assert "particle 0 (id 1) and particle 1 (id 2) overlap by 0.01" in line
    assert "integrator.overlap_limit = 0.01" in line
    assert "the time step is an unlikely cause" in line
    step = int(line.split("blown up at step ")[1].split(":")[0])
    frames, rows = _steps_written(tmp_path / "collision_smoke.forward.h5")
    assert frames[-1] < step and rows[-1] < step  # nothing from the blown-up state
    assert not (tmp_path / "collision_smoke.restart.h5").exists()


def test_a_time_step_above_the_critical_one_is_named_as_the_likely_cause(tmp_path):
    # the smoke oedometer poured at 100 times its time step: spheres hit the walls and one
    # another ever harder until one is pushed deep into the cylinder
    scenario = CONFIGS / "smoke" / "oedometer.toml"
    args = ["run", str(scenario), "--out", str(tmp_path), "-q", "--allow-unstable-dt"]
    sets = ["--set", "stages.0.dt=1e-3", "--set", "stages.0.output_every=5"]
    line = _failed(CliRunner().invoke(app, [*args, *sets]))
    assert "blown up at step" in line and "overlap by" in line
    assert "likely cause: dt = 0.001 s is" in line and "times the critical time step" in line
    step = int(line.split("blown up at step ")[1].split(":")[0])
    frames, _ = _steps_written(tmp_path / "oedometer_smoke.forward.h5")
    assert frames[-1] < step
    assert f"holds the frames up to step {frames[-1]}" in line


def test_a_time_step_below_one_contacts_limit_but_not_a_lattices_is_a_possible_cause(tmp_path):
    """The fcc lattice at dt = 0.03 s, 0.71 of one contact's limit (0.0421 s) and 1.42 of the
    lattice's (0.0211 s, `revdem dt --restart`: twelve contacts a sphere), blows up in 21
    steps. The line called the time step an unlikely cause; it is a possible one below one
    contact's limit and above 1/√12 of it, where a sphere in many contacts may be unstable."""
    from revdem_cli.timestep.guard import CROWDED

    args = ["run", str(CONFIGS / "fcc_triaxial.toml"), "--out", str(tmp_path), "-q"]
    sets = ["integrator.dt=0.03", "stages.0.steps=3000", "stages.1.steps=100"]
    line = _failed(CliRunner().invoke(app, [*args, "--no-reverse", *(f"--set={s}" for s in sets)]))
    assert "blown up at step" in line and "unlikely cause" not in line
    limit = float(line.split("of the critical time step ")[1].split(" s")[0])
    assert 0.03 / limit == pytest.approx(0.71, abs=0.01)
    assert f"so the time step may be the cause: try dt below {limit / CROWDED**0.5:.3g} s" in line


def test_a_damped_stage_blown_up_backwards_names_its_damping(tmp_path):
    """The oedometer's settle stage under local damping 0.7, reversed by velocity Verlet
    without a tape, gains energy until two spheres overlap by half a radius. The line said
    the time step was an unlikely cause and to look at the walls or the cell; it names the
    damping run backwards (Hanley 2020 §5.2)."""
    scenario = CONFIGS / "trvp" / "oedometer_settle.toml"
    line = _failed(CliRunner().invoke(app, ["run", str(scenario), "--out", str(tmp_path), "-q"]))
    assert "blown up at step" in line and "overlap by" in line
    assert "likely cause: the stage's local damping 0.7, reversed, puts energy in" in line
    assert "reversal.tape with integrator.arithmetic = 'fixed', reverses it exactly" in line
    assert "unlikely cause" not in line
    # the reversal's frames go down from its restart: "up to step 134525" said the opposite
    steps, _ = _steps_written(tmp_path / "oedometer_settle.reverse.h5")
    assert line.endswith(f"holds the reversed frames from step {steps[0]} down to {steps[-1]}")


@pytest.mark.parametrize("arithmetic", ["float", "fixed"])
@pytest.mark.parametrize("scheme", ["verlet", "trvp"])
def test_the_tape_a_damped_blow_up_points_to_is_one_the_run_can_take(arithmetic, scheme):
    """The line of a damped stage blown up backwards pointed to reversal.tape alone, and a
    run that took it was refused, for fixed-point arithmetic, then again for velocity Verlet.
    It names what of those the run lacks, nothing where it has both; with them and the tape
    the scenario is valid."""
    from revdem_cli.stage import _likely_cause

    integrator = {"dt": 1e-7, "arithmetic": arithmetic, "scheme": scheme}
    cause = _likely_cause(two_spheres(integrator=integrator), 1e-7, "local damping 0.7")
    named = cause.split("an information tape, reversal.tape")[1].split(", reverses it")[0]
    lacking = [(arithmetic, "fixed"), (scheme, "verlet")]
    assert bool(named) == any(have != needed for have, needed in lacking)
    for need in named.removeprefix(" with ").split(" and ") if named else []:
        field, value = need.removeprefix("integrator.").split(" = ")
        integrator[field] = value.strip("'")
    assert two_spheres(integrator=integrator, reversal={"tape": True}).reversal.tape


def _examined(scenario: Scenario, change, limit: float = 0.5) -> tuple[int, np.ndarray]:
    state = initial_state(scenario)
    change(state)

    p, pairs, walls, cell = state.particles, state.pairs, state.walls, state.cell
    finding = examine(p, pairs, walls, cell, limit)
    return finding.what, list(finding)


def test_examine_names_the_first_non_finite_value():
    scenario = two_spheres()
    assert _examined(scenario, lambda s: None)[0] == HEALTHY
    for quantity, field in enumerate(("x", "v", "omega")):
        for value in (np.nan, np.inf, -np.inf):

            def spoil(state, field=field, value=value):
                getattr(state.particles, field)[1, 2] = value

            what, alarm = _examined(scenario, spoil)
            assert what == NOT_FINITE
            assert alarm == [NOT_FINITE, 1, -1, quantity]


def test_examine_names_the_deepest_overlap_with_a_sphere_or_a_wall():
    scenario = two_spheres()  # 0.0101 m apart: 0.1 mm from touching

    def press(state):
        state.particles.x[1, 0] = 0.0099  # overlap 0.1 mm, 0.02 of the radius 5 mm

    assert _examined(scenario, press, limit=0.03)[0] == HEALTHY
    what, alarm = _examined(scenario, press, limit=0.01)
    assert what == TOO_DEEP and alarm[:3] == [TOO_DEEP, 0, 1]
    assert np.isclose(alarm[3], 0.02)

    on_floor = two_spheres(
        walls=[
            {"name": "floor", "type": "plane", "material": "sphere", "point": [0, 0, -0.005],
             "normal": [0, 0, 1]},
        ]
    )  # fmt: skip

    def sink(state):
        state.walls.overlap[1, 0] = 0.003  # 0.6 of the radius, as the wall loop measured it

    what, alarm = _examined(on_floor, sink)
    assert what == TOO_DEEP and alarm[:3] == [TOO_DEEP, 1, -1]
    assert np.isclose(alarm[3], 0.6)
    assert on_floor.integrator.overlap_limit == 0.5  # the default


def test_a_blow_up_under_a_servo_names_it(tmp_path):
    """The fcc lattice held at 150 kPa by an inertial servo whose edges weigh 100 kg where
    8e8 keep it steady: the edges jump at the first step and crush the lattice. The line
    said to look at "the cell"; it names the servo that moved it and how it overshoots. A
    cell crushed below twice the contact reach says so too."""
    from revdem_cli.state import CellTooSmall

    args = ["run", str(CONFIGS / "fcc_triaxial.toml"), "--out", str(tmp_path), "-q"]
    line = _failed(CliRunner().invoke(app, [*args, "--set", "cell.servo_mass=1e2", "--no-reverse"]))
    assert "blown up at step 1:" in line
    assert (
        "the cell (the inertial servo of stage isotropic holds a stress on x, y, z and "
        "overshoots with a servo_mass too small for the packing's stiffness)" in line
    )
    assert "servo_gain" not in line
    said = str(CellTooSmall(7, np.array([1.0, 1.0, -0.5]), "the inertial servo of stage "
                            "press holds a stress on z"))  # fmt: skip
    assert said.endswith(
        "start bigger; or the inertial servo of stage press holds a stress on z, swinging an "
        "edge further at each step"
    )


def test_a_cell_crushed_at_a_time_step_above_the_critical_one_names_the_time_step(tmp_path):
    """Let go on at 12 times its critical time step (`--allow-unstable-dt`), the fcc cell
    collapses in 8 steps; its line named only the servo, whose mass holds it at dt = 2 ms,
    where a blow-up's line names the time step first."""
    args = ["run", str(CONFIGS / "fcc_triaxial.toml"), "--out", str(tmp_path), "-q", "--threads",
            "1", "--no-reverse", "--allow-unstable-dt", "--set", "integrator.dt=0.5"]  # fmt: skip
    line = _failed(CliRunner().invoke(app, args))
    assert "is no longer more than twice the contact reach" in line
    before, _ = line.split("; or the inertial servo of stage isotropic", 1)
    assert "likely cause: dt = 0.5 s is 11.9 times the critical time step 0.0421 s" in before


@pytest.mark.parametrize(
    ("servo", "named", "not_named"),
    [
        ([], "the inertial servo of stage isotropic", "servo_gain"),
        (
            ["cell.servo=proportional", "cell.servo_gain=50", "cell.servo_mass="],
            "the proportional servo of stage isotropic",
            "servo_mass",
        ),
    ],
)
def test_a_cell_crushed_by_its_servo_names_the_servo_and_its_parameter(
    tmp_path, servo, named, not_named
):
    """The smoke critical-state sample held at 5 kPa on x and y and 10 kPa on z: the cell
    grows on x and y and is crushed on z. The line said "the stage's inertial servo ...: a
    servo_mass too small or a servo_gain too large", naming neither the stage nor which of
    the two parameters belongs to the servo the run has."""
    args = ["run", str(CONFIGS / "smoke" / "critical_state.toml"), "--out", str(tmp_path)]
    changes = ["stages.1.cell.x.stress=5e3", "stages.1.cell.y.stress=5e3", *servo]
    sets = [a for change in changes for a in ("--set", change)]
    result = CliRunner().invoke(app, [*args, "-q", "--no-reverse", "--threads", "1", *sets])
    line = _failed(result)
    assert "is no longer more than twice the contact reach" in line
    assert f"; or {named} holds a stress on x, y, z and overshoots with " in line
    assert not_named not in line


def test_a_blow_ups_line_quotes_the_one_critical_estimate_that_judged_its_time_step(monkeypatch):
    """The estimate was found twice on a blow-up, once to judge whether the time step was
    above it and once more for the sentence: the line could quote a limit other than the one
    that judged it. Here the second estimate differs from the first, as no real one does,
    so that a line built from it shows."""
    from revdem_cli import stage
    from revdem_cli.timestep import guard

    estimates = iter([(1.0, "first estimate"), (1e-9, "second estimate")])

    def found(scenario):
        return next(estimates)

    monkeypatch.setattr(guard, "critical_time_step", found)
    monkeypatch.setattr(stage, "critical_time_step", found, raising=False)
    line = stage._likely_cause(two_spheres(), 0.5)
    assert line.startswith("dt = 0.5 s is 0.5 of the critical time step 1 s (first estimate)")
    assert "so the time step may be the cause: try dt below 0.289 s" in line
