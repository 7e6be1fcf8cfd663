"""Periodic cells: contacts through the faces, the stress of Hanley 2020 Eq 22-23 against
lattices where it follows from one contact force, and a deforming cell carrying its spheres."""

import math

import h5py
import numpy as np
import pytest

from revdem_cli.config import Scenario
from revdem_cli.engine import run_scenario
from revdem_cli.kernels.stress import particle_stress
from revdem_cli.stage import Model
from revdem_cli.state import initial_state
from tests.conftest import CONFIGS

KN = 1.0e5  # N/m


def lattice_scenario(positions, radius, box, stages=None, **changes) -> Scenario:
    data = {
        "name": "lattice",
        "materials": {"m": {"density": 1000.0, "shear_modulus": 1e6, "poisson_ratio": 0.2}},
        "contact": {"model": "linear", "kn": KN},
        "particles": [
            {"material": "m", "radius": radius, "position": tuple(map(float, p))} for p in positions
        ],
        "cell": {"size": list(box)},
        "integrator": {"dt": 1e-4},
        "stages": stages or [{"name": "hold", "steps": 10}],
    }
    return Scenario.model_validate(data | changes)


def stress_row(scenario):
    model = Model.of(scenario)
    state = initial_state(scenario)
    row = model.observe(state, model.dynamics)
    at = model.layout.column("stress")
    return row[at : at + 9].reshape(3, 3), row[model.layout.column("coordination_number")], state


def test_a_compressed_simple_cubic_lattice_carries_kn_overlap_over_its_face():
    # each sphere touches six neighbours through the faces of its cubic cell of edge a
    r, overlap, n = 0.5, 1e-3, 4
    a = 2 * r - overlap
    grid = np.indices((n, n, n)).reshape(3, -1).T * a + a / 2
    sigma, coordination, state = stress_row(lattice_scenario(grid, r, [n * a] * 3))
    np.testing.assert_allclose(np.diag(sigma), KN * overlap / a**2, rtol=1e-12)
    assert np.abs(sigma - np.diag(np.diag(sigma))).max() < 1e-9 * sigma[0, 0]
    assert coordination == 6.0
    assert np.abs(state.particles.f).max() < 1e-9 * KN * overlap  # every sphere balanced


def test_a_compressed_fcc_lattice_has_the_isotropic_stress_of_its_twelve_contacts():
    # 12 contacts of force F along face diagonals of length d: sigma = 2 sqrt(2) F / d^2
    r, overlap = 0.5, 2e-3
    d = 2 * r - overlap
    spacing = d * math.sqrt(2)
    cells = np.indices((3, 3, 3)).reshape(3, -1).T
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    x = ((cells[:, None, :] + basis[None]) * spacing).reshape(-1, 3)
    sigma, coordination, state = stress_row(lattice_scenario(x, r, [3 * spacing] * 3))
    expected = 2 * math.sqrt(2) * KN * overlap / d**2
    np.testing.assert_allclose(sigma, expected * np.eye(3), rtol=1e-12, atol=1e-12 * expected)
    assert coordination == 12.0
    # Eq 22 sphere by sphere, and Eq 23: their volume-weighted mean is the cell's stress
    per_sphere = np.zeros((len(x), 3, 3))
    particle_stress(state.particles, state.pairs, state.walls, state.cell, per_sphere)
    volume = 4 / 3 * math.pi * r**3
    mean = per_sphere.sum(axis=0) * volume / (3 * spacing) ** 3
    np.testing.assert_allclose(mean, sigma, rtol=1e-12, atol=1e-12 * expected)
    np.testing.assert_allclose(per_sphere[5], per_sphere[0], rtol=1e-12, atol=1e-12 * expected)


def test_spheres_collide_through_a_face_and_the_collision_reverses(tmp_path):
    # two spheres 0.23 m apart across the face x = 0 = L, moving towards each other through
    # it: the first crosses the face before they touch
    box = [1.0, 1.0, 1.0]
    sphere = {"material": "m", "radius": 0.09}
    scenario = lattice_scenario(
        [(0.01, 0.5, 0.5), (0.78, 0.5, 0.5)],
        0.09,
        box,
        stages=[
            {"name": "collide", "steps": 4000, "output_every": 100, "observables_every": 10}
            | {"reverse": True}
        ],
        particles=[
            sphere | {"position": (0.01, 0.5, 0.5), "velocity": (-0.1, 0, 0)},
            sphere | {"position": (0.78, 0.5, 0.5), "velocity": (0.1, 0, 0)},
        ],
    )
    outputs = run_scenario(scenario, "text", ".toml", tmp_path)
    with h5py.File(outputs.forward) as f:
        v = f["particles/all/velocity/value"][:]
        x = f["particles/all/position/value"][:]
        energy = f["observables/total_energy/value"][:]
        contacts = f["observables/coordination_number/value"][:]
        boundary = f["particles/all/box"].attrs["boundary"]
        edges = f["particles/all/box/edges/value"][:]
    assert contacts.max() == 1.0  # they touched, through the face
    # equal masses swap velocities (to O(dt^2): velocity Verlet keeps a shadow energy)
    np.testing.assert_allclose(v[-1, :, 0], [0.1, -0.1], rtol=1e-4)
    assert x[:, 0, 0].min() < 0.0 < x[0, 0, 0]  # positions are unwrapped
    np.testing.assert_allclose(v.sum(axis=1)[:, 0], 0.0, atol=1e-15)
    omega = math.sqrt(KN / (0.5 * 1000.0 * 4 / 3 * math.pi * 0.09**3))  # the contact's
    assert np.ptp(energy) < (omega * 1e-4) ** 2 * energy[0]  # velocity Verlet: O((w dt)^2)
    assert list(boundary) == [b"periodic"] * 3 and (edges == box).all()
    assert outputs.verdict["reversible"]
    assert outputs.verdict["max_position_error_rel"] < 1e-12


@pytest.mark.parametrize("servo", ["inertial", "proportional"])
def test_a_deforming_cell_carries_its_lattice_and_the_stress_follows_the_contacts(tmp_path, servo):
    # a simple cubic lattice compressed along z at a strain rate while x and y hold 1 kPa:
    # the spheres stay on the lattice of the cell, and the z stress is that of its contacts
    r, n = 0.5, 3
    a = 2 * r - 1e-3
    grid = np.indices((n, n, n)).reshape(3, -1).T * a + a / 2
    steps = 20000
    scenario = lattice_scenario(
        grid,
        r,
        [n * a] * 3,
        stages=[
            {
                "name": "squeeze",
                "steps": steps,
                "output_every": 1000,
                "cell": {"x": {"stress": 1e3}, "y": {"stress": 1e3}, "z": {"strain_rate": -0.1}},
            }
        ],
        cell={"size": [n * a] * 3, "servo": servo, "servo_mass": 1e3, "servo_gain": 20.0},
        damping={"local": 0.7},
    )
    outputs = run_scenario(scenario, "text", ".toml", tmp_path, reverse=False)
    with h5py.File(outputs.forward) as f:
        x = f["particles/all/position/value"][-1]
        length = f["observables/cell_length/value"][-1]
        sigma = f["observables/stress/value"][-1]
    np.testing.assert_allclose(length[2], n * a * (1 - 0.1 * steps * 1e-4), rtol=1e-12)
    spacing = length / n
    np.testing.assert_allclose(x, (grid / a) * spacing, rtol=1e-9)
    np.testing.assert_allclose(sigma[2, 2], KN * (2 * r - spacing[2]) / (spacing[0] * spacing[1]))
    np.testing.assert_allclose([sigma[0, 0], sigma[1, 1]], 1e3, rtol=1e-2)


def test_spheres_must_start_inside_the_cell_and_the_cell_must_be_wide_enough():
    from revdem_cli.config.checks import FieldError
    from revdem_cli.config.geometry import check_spheres

    with pytest.raises(FieldError, match="outside the cell"):
        check_spheres(lattice_scenario([(1.5, 0.5, 0.5)], 0.1, [1.0, 1.0, 1.0]))
    with pytest.raises(FieldError, match="twice the contact reach"):
        check_spheres(lattice_scenario([(0.5, 0.5, 0.5)], 0.3, [1.0, 1.0, 1.0]))


def test_the_trajectory_keeps_each_spheres_stress_and_their_mean_is_the_cells(tmp_path):
    r, overlap = 0.5, 2e-3
    spacing = (2 * r - overlap) * math.sqrt(2)
    cells = np.indices((3, 3, 3)).reshape(3, -1).T
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    x = ((cells[:, None, :] + basis[None]) * spacing).reshape(-1, 3)
    scenario = lattice_scenario(
        x,
        r,
        [3 * spacing] * 3,
        stages=[{"name": "hold", "steps": 20, "output_every": 10}],
        output={"particle_stress": True},
    )
    outputs = run_scenario(scenario, "text", ".toml", tmp_path, reverse=False)
    with h5py.File(outputs.forward) as f:
        per_sphere = f["particles/all/stress/value"][:]
        frames = f["particles/all/stress/step"][:]
        steps = f["observables/stress/step"][:]
        sigma = f["observables/stress/value"][:]
    assert per_sphere.shape == (3, len(x), 3, 3) and list(frames) == [0, 10, 20]
    mean = per_sphere.sum(axis=1) * (4 / 3 * math.pi * r**3) / (3 * spacing) ** 3
    expected = sigma[np.searchsorted(steps, frames)]
    np.testing.assert_allclose(mean, expected, rtol=1e-10, atol=1e-12 * expected.max())


def test_a_periodic_cell_stops_a_stage_at_a_solid_fraction(tmp_path):
    """solid_fraction_above asked for a [solid_fraction] container, which walls make and a
    periodic cell refuses: a cell had no stop at a density. Its solid fraction is the
    spheres' volume over the cell's, 1 / (1 + void ratio): the fcc lattice pressed from
    touching (0.74048) by the servo passes 0.74053 at its first check, 50 steps in, and
    never reaches 0.7406."""
    from revdem_cli import api as revdem

    experiment = revdem.load(CONFIGS / "fcc_triaxial.toml").changed(
        {"stages.1.steps": 100, "output.figures": []}
    )
    for above, stopped in ((0.74053, {"isotropic": (50, 20000, 50)}), (0.7406, {})):
        changed = experiment.changed({"stages.0.stop_when": {"solid_fraction_above": above}})
        outputs = revdem.run(changed, tmp_path / str(above), reverse=False, threads=1).outputs
        assert outputs.stopped == stopped
        assert ("isotropic" in outputs.unmet) == (not stopped)
    _, void_ratio = revdem.read(tmp_path / "0.74053").observable("void_ratio")
    assert 1.0 / (1.0 + void_ratio[1]) > 0.74053 >= 1.0 / (1.0 + void_ratio[0])


def test_a_strain_rate_that_inverts_the_cell_is_refused_before_it_runs():
    """The edge moves as L0 (1 + rate t) from the stage's start: -0.012 1/s over the shear
    stage's 44 000 steps of 2 ms takes it to -0.056 L0, which `validate` let through and
    the run met as a cell too small, 41 s in. -0.011 1/s leaves 0.032 L0: left to the
    run's own check of the cell against the contact reach, which needs the spheres."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import assert_one_line_error

    args = ["validate", str(CONFIGS / "fcc_triaxial.toml"), "--set"]
    assert_one_line_error(
        CliRunner().invoke(app, [*args, "stages.1.cell.z.strain_rate=-0.012"]),
        "stages[1].cell.z.strain_rate: -0.012 1/s for 44000 steps of 0.002 s takes the edge "
        "to -0.056 times its length at the stage's start: below zero",
    )
    result = CliRunner().invoke(app, [*args, "stages.1.cell.z.strain_rate=-0.011"])
    assert result.exit_code == 0, result.output


def test_gravity_in_a_periodic_cell_is_refused():
    """A cell takes no walls, so nothing holds spheres under gravity: the whole sample fell
    together (smoke critical state: mean v_z -1.55 m/s), and no kinetic-energy stop was met."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import assert_one_line_error

    config = str(CONFIGS / "smoke" / "critical_state.toml")
    assert_one_line_error(
        CliRunner().invoke(app, ["validate", config, "--set", "gravity=[0, 0, -9.81]"]),
        "gravity: [0.0, 0.0, -9.81] m/s^2 with a periodic [cell]: every sphere falls together, "
        "for no wall or floor holds them",
    )
    # a scenario a run stored before is not held to it: its outputs stay readable
    from revdem_cli.config import Scenario, load_scenario

    scenario, _ = load_scenario(config)
    stored = scenario.model_dump_json().replace('"gravity":[0.0,0.0,0.0]', '"gravity":[0,0,-9.81]')
    assert Scenario.model_validate_json(stored).gravity == (0.0, 0.0, -9.81)


def test_a_stage_that_ends_with_its_servo_off_its_target_says_so(tmp_path):
    """The fcc lattice's inertial servo, given 20 steps of the 20 000 it takes to press the
    lattice to 150 kPa, ends near 64 kPa; a run said nothing of it (nor of a proportional
    servo whose gain overshoots). The summary now names each axis off its target by more
    than 5 %; 200 steps get there, and nothing is said."""
    from rich.console import Console

    from revdem_cli import api as revdem
    from revdem_cli.engine import HELD, carried_summary, summary_so_far
    from revdem_cli.report.summary import print_summary

    experiment = revdem.load(CONFIGS / "fcc_triaxial.toml").changed(
        {"stages.1.steps": 100, "output.figures": []}
    )
    short = revdem.run(experiment.changed({"stages.0.steps": 20}), tmp_path / "short",
                       reverse=False, threads=1).outputs  # fmt: skip
    assert list(short.unheld) == ["isotropic", "shear"]
    assert list(short.unheld["shear"]) == ["x", "y"]  # z is strained, not held
    for stress, target in short.unheld["isotropic"].values():
        assert target == 1.5e5 and abs(stress - target) > HELD * target
    console = Console(record=True, width=400)
    print_summary(short, console)
    said = console.export_text()
    assert (
        "not held             stage isotropic ended with its servo off its target stress: "
        "σ_xx " in said
    )
    assert "off: a servo_mass too small overshoots" in said  # an inertial servo's
    assert "servo_gain" not in said
    kept = summary_so_far({}, {}, {}, short.unheld, [], "inertial", {})  # a checkpoint's, read back
    assert carried_summary(tmp_path, kept)[3::2] == (short.unheld, "inertial")
    enough = revdem.run(experiment.changed({"stages.0.steps": 200}), tmp_path / "enough",
                        reverse=False, threads=1).outputs  # fmt: skip
    assert "isotropic" not in enough.unheld


def test_what_a_run_said_of_its_stages_is_read_back_from_its_restart(tmp_path):
    """Where a stage stopped on its condition, which did not hold its stress: the run's
    summary said it once, and `revdem info` and `read` had lost it (`read` gave stopped {}).
    The restart that ends the run keeps it. The stage stopped after 50 steps is off its
    target, and said to be, as one that ran all its steps is (it was not judged)."""
    from typer.testing import CliRunner

    from revdem_cli import api as revdem
    from revdem_cli.cli import app

    experiment = revdem.load(CONFIGS / "fcc_triaxial.toml").changed(
        {
            "stages.0.stop_when": {"solid_fraction_above": 0.74053},
            "stages.1.steps": 20,
            "output.figures": [],
        }
    )
    ran = revdem.run(experiment, tmp_path, reverse=False, threads=1).outputs
    assert ran.stopped == {"isotropic": (50, 20000, 50)}
    assert list(ran.unheld) == ["isotropic", "shear"]
    read = revdem.read(tmp_path).outputs
    assert (read.stopped, read.unheld, read.unmet) == (ran.stopped, ran.unheld, ran.unmet)
    for name in ("restart", "forward"):
        shown = CliRunner().invoke(app, ["info", str(tmp_path / f"fcc_triaxial.{name}.h5")])
        assert shown.exit_code == 0, shown.output
        lines = shown.output.splitlines()
        # in the words of the run's summary (`info.stage_lines`), which info's were not
        assert (
            "stopped:    stage isotropic after 50 of 20000 steps, at its first check: its "
            "condition held from its start" in lines
        )
        held = "not held:   stage shear ended with its servo off its target stress: σ_xx "
        (line,) = [line for line in lines if line.startswith(held)]
        assert "off: a servo_mass too small overshoots" in line and "servo_gain" not in line


def test_the_not_held_line_names_the_parameter_of_the_runs_servo():
    """It named servo_mass and servo_gain together whatever the servo; a restart written
    before runs kept the servo's kind names both, each with its kind."""
    from revdem_cli.report.info import stage_lines

    unheld = {"unheld": {"shear": {"x": (6.386e4, 1.5e5)}}}
    for servo, words in [
        ("inertial", "a servo_mass too small overshoots"),
        ("proportional", "a servo_gain too large overshoots"),
        (None, "a servo_mass too small (inertial) or a servo_gain too large (proportional)"),
    ]:
        said = unheld | ({"servo": servo} if servo else {})
        ((label, text),) = stage_lines(said)
        assert label == "not held" and f"(more than 5% off: {words}" in text
