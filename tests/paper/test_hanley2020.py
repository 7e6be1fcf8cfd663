"""Hanley 2020's verification cases that run in minutes against the numbers the paper
reports (scenarios/hanley2020/paper_numbers.toml): the collisions, the drops A and C and the
fcc triaxial test. The full oedometer (up to 2.1e6 steps) and drop B (8e6) are set beside the
paper by `make paper` (`revdem report`, scenarios/report/hanley2020.md); the oedometer's
physics is tested small in tests/physics/test_oedometer.py."""

import json
import tomllib

import h5py
import numpy as np
import pytest

from revdem_cli.config import load_scenario
from revdem_cli.engine import run_scenario
from tests.conftest import ROOT

PAPER = tomllib.loads((ROOT / "scenarios/hanley2020/paper_numbers.toml").read_text())


def run(case: str, tmp_path, *overrides: str, reverse: bool = True):
    scenario, text = load_scenario(ROOT / PAPER[case]["config"], list(overrides))
    return run_scenario(scenario, text, ".toml", tmp_path, reverse=reverse)


def test_figure_1_collision_reverses_to_round_off(collision_run):
    paper = PAPER["collision"]
    verdict = json.loads(collision_run.comparison.read_text())
    assert verdict["max_position_error_rel"] <= paper["max_position_error_rel"]
    assert verdict["max_velocity_error"] <= paper["max_velocity_error"]


def test_figure_5_shear_forces_and_the_irreversibility_they_bring(tmp_path):
    paper = PAPER["collision_shear"]
    outputs = run("collision_shear", tmp_path)
    with h5py.File(outputs.forward) as f:
        shear = f["observables/max_shear_force/value"][:]
        normal = f["observables/max_normal_force/value"][:]
    at_separation = shear[np.nonzero(normal)[0][-1]]
    tolerance = paper["relative_tolerance"]
    assert shear.max() == pytest.approx(paper["max_shear_force"], rel=tolerance)
    assert at_separation == pytest.approx(paper["shear_force_at_separation"], rel=tolerance)
    verdict = outputs.verdict
    assert verdict["reversible"] is paper["reversible"]
    cause = verdict["divergence_causes"][0]
    assert cause["mechanism"] == "contact_lost_with_shear_force"
    assert (cause["particle"], cause["partner"]) == (0, 1)
    assert (cause["particle_id"], cause["partner_id"]) == (1, 2)  # numbered from 1
    assert cause["message"].startswith("the contact of particle 0 (id 1) and particle 1 (id 2)")
    assert cause["amount"] == pytest.approx(at_separation, rel=1e-6)
    assert 0 <= cause["step"] - verdict["first_divergence_step"] <= 50  # within a frame


def test_figure_6a_drop_with_drag_reverses_while_it_bounces(tmp_path):
    # the first 10 ms of case A: impact at about 2 ms and the bounces after it
    outputs = run("drop_A", tmp_path, "stages.0.steps=1000000")
    assert outputs.verdict["reversible"] is PAPER["drop_A"]["reversible"]
    assert outputs.verdict["max_position_error_rel"] <= 1e-6


def test_figure_6c_falling_sphere_reaches_the_terminal_velocity(tmp_path):
    paper = PAPER["drop_C"]
    # 10 ms of free fall: ten time constants dt/(1 - gamma_d) = 1 ms, no contact yet
    outputs = run("drop_C", tmp_path, "stages.0.steps=1000000", reverse=False)
    with h5py.File(outputs.forward) as f:
        vz = f["particles/all/velocity/value"][-1, 0, 2]
        elastic = f["observables/elastic_energy/value"][:]
    assert elastic.max() == 0.0
    assert vz == pytest.approx(
        paper["terminal_velocity"], rel=paper["terminal_velocity_relative_tolerance"]
    )


@pytest.fixture(scope="module")
def fcc_run(tmp_path_factory):
    """configs/fcc_triaxial.toml (inertial servo), forward and reversed."""
    directory = tmp_path_factory.mktemp("fcc")
    return directory, run("fcc_triaxial", directory)


def test_figure_4_stress_ratio_rises_to_2_as_coordination_falls_from_12_to_8(fcc_run):
    from revdem_cli.report.paper import _Run, case_rows

    directory, _ = fcc_run
    rows = case_rows(_Run(directory, "fcc_triaxial", PAPER["fcc_triaxial"]))
    assert len(rows) == 7
    assert all(agrees == "yes" for *_, agrees in rows), rows


def test_figure_4_the_inertial_servo_reverses_far_closer_than_the_proportional(fcc_run, tmp_path):
    _, inertial = fcc_run
    proportional = run("fcc_triaxial", tmp_path, "cell.servo=proportional").verdict
    assert inertial.verdict["max_position_error_rel"] <= 1e-9
    assert proportional["max_position_error_rel"] > 1e3 * inertial.verdict["max_position_error_rel"]
    # the cause named first is the servo, not the motions lost to round-off that the
    # inertial run has as much of and still reverses (Hanley 2020 §3.2.3)
    named = [cause["mechanism"] for cause in proportional["divergence_causes"]]
    assert named[0] == "proportional_servo"
    assert "proportional_servo" not in [
        cause["mechanism"] for cause in inertial.verdict["divergence_causes"]
    ]
    with h5py.File(tmp_path / "fcc_triaxial.reverse.h5") as f:
        principal = f["observables/principal_stress/value"][-1]
    assert principal[0] / principal[2] == pytest.approx(1.0, abs=1e-3)  # isotropic again


@pytest.mark.parametrize("mu", [0.1, 0.25, 0.5])
def test_eq_24_peak_stress_ratio_with_friction(tmp_path, mu):
    # Thornton 1979: the contacts in the xz and yz planes slide at sigma_1/sigma_3 =
    # 2 (1 + mu) / (1 - mu)
    sweep = tomllib.loads((ROOT / "configs/sweeps/fcc_friction.toml").read_text())
    overrides = [item for item in sweep["set"] if not item.startswith("contact.friction")]
    outputs = run("fcc_triaxial", tmp_path, *overrides, f"contact.friction={mu}", reverse=False)
    with h5py.File(outputs.forward) as f:
        principal = f["observables/principal_stress/value"][1:]
    peak = (principal[:, 0] / principal[:, 2]).max()
    assert peak == pytest.approx(2 * (1 + mu) / (1 - mu), rel=0.05)
