"""The time-reversible velocity predictor (integrator.scheme = 'trvp', Kolafa & Lisal 2011):
its coefficients, its identity with velocity Verlet where nothing reads it, and a damped
contact that it reverses to round-off where velocity Verlet does not (Hanley 2020 §5.2)."""

import json
import math

import h5py
import numpy as np
import pytest

from revdem_cli import api as revdem
from revdem_cli.errors import InputError
from revdem_cli.io.restart import read_restart
from revdem_cli.kernels.predictor import coefficients
from tests.conftest import FLOOR, PLANE, SPHERE, crashed_after


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_predictor_is_consistent_and_time_symmetric_to_its_order(k):
    b = coefficients(k)
    middles = np.arange(k + 1) + 0.5  # the half steps it reads, j + 1/2 steps back
    assert b.sum() == pytest.approx(1.0, abs=1e-15)  # v_P of a constant velocity is it
    for m in range(1, 2 * k, 2):  # odd moments: forward and reversed predictions agree
        assert (b * middles**m).sum() == pytest.approx(0.0, abs=1e-12)
    assert abs((b * middles ** (2 * k + 1)).sum()) > 0.1  # and no further
    if k <= 2:  # the values of Kolafa & Lisal 2011 for k = 1, 2
        assert b == pytest.approx([[1.5, -0.5], [5 / 3, -5 / 6, 1 / 6]][k - 1], rel=1e-15)


def _collision(scheme: dict) -> revdem.Experiment:
    """Two spheres in a Hertz-Mindlin collision (no sliding) without any damping."""
    return revdem.load("configs/collision.toml").changed(
        {
            "contact.tangential": "mindlin",
            "contact.friction": math.inf,
            "particles.1.velocity": [-0.2, 0.3, 0.1],  # an oblique impact: shear and spin
            "stages.0.steps": 3000,
            **scheme,
        }
    )


def _arrays(path):
    with h5py.File(path) as f:
        return {
            name: f[f"particles/all/{name}/value"][:]
            for name in ("position", "velocity", "angular_velocity", "force")
        }


def test_trvp_without_damping_is_velocity_verlet_bit_for_bit(tmp_path):
    verlet = revdem.run(_collision({}), tmp_path / "verlet")
    trvp = _collision({"integrator.scheme": "trvp", "integrator.trvp_order": 3})
    predicted = revdem.run(trvp, tmp_path / "trvp")
    for run in ("forward", "reverse"):
        a, b = _arrays(getattr(verlet.outputs, run)), _arrays(getattr(predicted.outputs, run))
        assert np.abs(a["angular_velocity"]).max() > 1.0  # the shear springs turned them
        for name in a:
            assert np.array_equal(a[name], b[name]), (run, name)
    history = read_restart(predicted.outputs.restart).state.particles.v_past
    assert history.shape == (3, 2, 3) and np.abs(history).max() > 0.1  # it was carried


def _resting(scheme: dict) -> revdem.Experiment:
    """A sphere pressed 8 um into a plane by a linear spring of 1000 N/m with viscous
    damping of 0.3 of critical, in contact throughout: it settles towards the 5.1 um of its
    weight. The reversed stage starts after 10 steps, so that it reverses to a state the
    predictor reached with its own history."""
    return revdem.from_dict(
        {
            "name": "resting",
            "materials": {"sphere": SPHERE, "plane": PLANE},
            "contact": {"model": "linear", "kn": 1e3, "normal_damping": 0.3},
            "particles": [
                {"material": "sphere", "radius": 0.005, "position": [0, 0, 0.005 - 8e-6]}
            ],
            "walls": [FLOOR],
            "gravity": [0, 0, -9.81],
            "integrator": {"dt": 1e-6, **scheme},
            "stages": [
                {"name": "start", "steps": 10},
                {"name": "settle", "steps": 3000, "output_every": 100, "reverse": True},
            ],
            "reversal": {"position_tolerance_rel": 1e-13, "velocity_tolerance": 1e-12},
        }
    )


def test_trvp_reverses_a_damped_contact_that_verlet_does_not(tmp_path):
    verlet = revdem.run(_resting({}), tmp_path / "verlet").comparison
    trvp = revdem.run(_resting({"scheme": "trvp", "trvp_order": 2}), tmp_path / "trvp")
    with h5py.File(trvp.outputs.forward) as f:
        energy = f["observables/total_energy/value"][:]
    assert energy[-1] < energy[0] - 0.5 * 5e-10  # the dashpot took most of the 8.5e-10 J
    assert not verlet["reversible"] and verlet["max_velocity_error"] > 1e-6
    verdict = trvp.comparison
    assert verdict["reversible"], verdict["first_divergence_step"]
    assert verdict["max_velocity_error"] < 1e-15  # m/s, against a largest speed of 4e-3
    assert verdict["max_position_error_rel"] < 1e-15
    assert json.loads(trvp.outputs.comparison.read_text())["frames_compared"] == 31


def test_trvp_settings_that_do_not_fit_are_refused():
    with pytest.raises(InputError, match="integrator.trvp_order: needs integrator.scheme"):
        _resting({"trvp_order": 2})
    with pytest.raises(InputError, match=r"damping.drag: drag .* needs integrator.scheme"):
        revdem.load("configs/drop_A.toml").changed({"integrator.scheme": "trvp"})


def test_the_time_step_guard_takes_the_predictors_limit(tmp_path):
    """With damping read from the predictor the two-body limit is the root of its
    characteristic polynomial: 0.646 of velocity Verlet's for the collision's beta = 0.3."""
    from revdem_cli.timestep.guard import critical_time_step

    collision = revdem.load("configs/trvp/collision_damped.toml")
    verlet, _ = critical_time_step(collision.scenario)
    trvp = collision.changed({"integrator.scheme": "trvp", "integrator.trvp_order": 2})
    limit, reason = critical_time_step(trvp.scenario)
    assert limit == pytest.approx(0.646 * verlet, rel=1e-3)
    assert "velocity predictor of order 2" in reason
    with pytest.raises(InputError, match="times the critical time step"):
        revdem.run(trvp.changed({"integrator.dt": 0.8 * verlet}), tmp_path)


@pytest.mark.parametrize("frames", [6, 16], ids=["forward", "reversed"])
def test_a_trvp_run_resumed_from_a_checkpoint_is_the_uninterrupted_run(tmp_path, frames):
    """The predictor's history travels in the checkpoint: a run stopped part-way through its
    forward or its reversed phase resumes to the uninterrupted run's frames, bit for bit."""
    from revdem_cli.engine import output_paths

    experiment = _resting({"scheme": "trvp", "trvp_order": 3}).changed(
        {"output.checkpoint_interval": 0.0, "stages.1.steps": 1000}
    )
    whole = revdem.run(experiment, tmp_path / "whole")
    shown = crashed_after(experiment, tmp_path / "cut", frames)
    assert ("reversed" in shown[-1]) == (frames == 16)
    resumed = revdem.resume(tmp_path / "cut")
    cut = output_paths(tmp_path / "cut", "resting")
    for run in ("forward", "reverse"):
        a, b = _arrays(getattr(whole.outputs, run)), _arrays(cut[run])
        for name in a:
            assert np.array_equal(a[name], b[name]), (run, name)
    assert resumed.comparison["reversible"]


def test_a_damped_reversal_under_the_predictor_is_explained_by_it(tmp_path):
    """The damped collision parts under trvp too (at the contact's end, the predictor's
    O(dt^5) asymmetry grown): the cause says the force read the predictor, not the
    half-step velocity of velocity Verlet, and `revdem info` names the scheme."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import CONFIGS

    experiment = revdem.load(CONFIGS / "trvp" / "collision_damped.toml").changed(
        {"integrator.scheme": "trvp", "output.figures": []}
    )
    result = revdem.run(experiment, tmp_path)
    assert not result.comparison["reversible"]
    (cause,) = result.comparison["divergence_causes"]
    assert cause["mechanism"] == "viscous_damping"
    assert "velocity predictor of order 2" in cause["message"]
    assert "O(dt^5)" in cause["message"] and "half step" not in cause["message"]
    assert "a linear dashpot's jump as a contact opens or closes" in cause["message"]
    shown = CliRunner().invoke(app, ["info", str(result.outputs.forward)])
    named = "trvp (velocity-dependent forces read the time-reversible velocity predictor of order 2"
    assert f"scheme:     {named}" in shown.output, shown.output
