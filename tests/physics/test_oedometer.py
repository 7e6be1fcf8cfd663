"""The oedometer of Hanley 2020 §3.2.2, small (configs/smoke/oedometer.toml): pour, close,
settle, compress with a moving platen, and the reversal of the compression."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from revdem_cli.config import load_scenario
from revdem_cli.kernels import CROSSOVERS, HEAVY
from tests.conftest import CONFIGS, on_threads

SMOKE = CONFIGS / "smoke" / "oedometer.toml"
G = 9.81


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """The smoke oedometer run once, forward and reversed, by the command line."""
    out = tmp_path_factory.mktemp("oedometer")
    subprocess.run(
        [sys.executable, "-m", "revdem_cli.cli", "run", str(SMOKE), "--out", str(out), "-q"],
        check=True,
    )
    return out


def observables(path, *names):
    with h5py.File(path) as f:
        steps = f["observables/kinetic_energy/step"][:]
        return steps, {name: f[f"observables/{name}/value"][:] for name in names}


def test_the_smoke_case_has_enough_spheres_to_step_in_parallel():
    assert len(load_scenario(SMOKE)[0].spheres) >= CROSSOVERS[HEAVY]


def test_the_platens_carry_the_load_and_the_weight_at_rest(smoke):
    """Frictionless spheres: the cylinder takes no vertical load, so at rest the force on the
    bottom platen is the top platen's plus the weight of the spheres (Hanley 2020: -323 N
    against 318 N, 5 N of weight)."""
    scenario = load_scenario(SMOKE)[0]
    weight = float((4 / 3 * np.pi * scenario.spheres.radius**3 * 1000.0 * G).sum())
    with h5py.File(smoke / "oedometer_smoke.reverse.h5") as f:
        start = int(f["observables/kinetic_energy/step"][:].min())
    steps, obs = observables(
        smoke / "oedometer_smoke.forward.h5",
        "wall_force/bottom",
        "wall_force/top",
        "kinetic_energy",
        "solid_fraction",
    )
    at_rest = np.nonzero(steps == start)[0][0]
    assert obs["kinetic_energy"][at_rest] < 1e-8
    bottom, top = obs["wall_force/bottom"][at_rest, 2], obs["wall_force/top"][at_rest, 2]
    assert top > 10 * weight  # the platen is loaded
    assert -bottom - top == pytest.approx(weight, rel=0.01)
    # the close stage stopped past its solid fraction, which the settling keeps
    assert obs["solid_fraction"][at_rest] > scenario.stages[1].stop_when.solid_fraction_above


def test_the_close_stage_stops_at_the_first_row_past_the_solid_fraction(smoke):
    with h5py.File(smoke / "oedometer_smoke.forward.h5") as f:
        frames = f["particles/all/position/step"][:]
        steps = f["observables/solid_fraction/step"][:]
        fraction = f["observables/solid_fraction/value"][:]
        top = f["observables/wall_position/top/value"][:, 2]
    close = load_scenario(SMOKE)[0].stages[1]
    speed = -np.diff(top) / np.diff(steps) / close.dt
    closing = np.nonzero(np.isclose(speed, 0.5, rtol=1e-6))[0]  # rows k -> k + 1 at 0.5 m/s
    first, last = closing[0], closing[-1] + 1
    # the platen moves at its stage velocity, from z = 0.065 m
    elapsed = (steps[last] - steps[first]) * close.dt
    assert top[last] == pytest.approx(0.065 - 0.5 * elapsed, abs=1e-12)
    # it stopped at the first observables row (every 5 steps) where the fraction passed
    # its threshold, and a frame was written there
    assert (np.diff(steps[first : last + 1]) == close.observables_every).all()
    passed = fraction[first : last + 1] > close.stop_when.solid_fraction_above
    assert passed[-1] and not passed[:-1].any()
    assert steps[last] in frames


def test_the_compression_reverses_with_its_platen(smoke):
    import json

    verdict = json.loads((smoke / "oedometer_smoke.compare.json").read_text())
    assert verdict["reversible"]
    assert verdict["max_position_error_rel"] < 1e-9
    steps, forward = observables(smoke / "oedometer_smoke.forward.h5", "wall_position/top")
    back_steps, back = observables(smoke / "oedometer_smoke.reverse.h5", "wall_position/top")
    common, i, j = np.intersect1d(steps, back_steps, return_indices=True)
    assert len(common) == 201
    np.testing.assert_array_equal(forward["wall_position/top"][i], back["wall_position/top"][j])
    assert (smoke / "oedometer_smoke.wall_forces.png").stat().st_size > 10_000


SHORTER = ["stages.0.steps=8000", "stages.2.steps=2000", "stages.3.steps=2000"]
"""Every stage of the smoke case, shortened (the close stage still ends on its condition)."""


def forward_state_with(threads: int, out) -> np.ndarray:
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    overrides = [arg for item in SHORTER for arg in ("--set", item)]
    subprocess.run(
        [sys.executable, "-c", on_threads(threads) + "from revdem_cli.cli import main; main()"]
        + ["run", str(SMOKE), "--out", str(out), "-q"]
        + ["--no-reverse", *overrides],
        check=True,
        env=env,
    )
    with h5py.File(out / "oedometer_smoke.forward.h5") as f:
        return np.concatenate(
            [f[f"particles/all/{name}/value"][:].ravel() for name in ("position", "velocity")]
            + [f["observables/wall_force/top/value"][:].ravel()]
        )


def test_one_and_two_threads_give_bitwise_identical_oedometers(tmp_path):
    one = forward_state_with(1, tmp_path / "one")
    two = forward_state_with(2, tmp_path / "two")
    assert one.shape == two.shape
    assert np.array_equal(one, two)
