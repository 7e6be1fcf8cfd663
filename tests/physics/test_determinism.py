"""Results do not depend on the thread count: each particle sums its forces in a fixed order."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from revdem_cli.config import Scenario
from tests.conftest import on_threads, periodic_fcc


def pile(n_side: int = 7, rolling: bool = False) -> Scenario:
    """n_side^3 frictional spheres on a jittered lattice, falling into a box of planes; with
    `rolling`, rolling resistance too."""
    rng = np.random.default_rng(7)
    r, spacing = 0.005, 0.0102
    cells = np.array(
        [(i, j, k) for i in range(n_side) for j in range(n_side) for k in range(n_side)],
        dtype=float,
    )
    x = (cells + 0.5) * spacing + rng.uniform(-1e-4, 1e-4, cells.shape)
    walls = [
        {
            "name": f"w{a}{s}",
            "type": "plane",
            "material": "m",
            "point": [0.0 if s == "lo" else n_side * spacing if a != 2 else 1.0] * 3,
            "normal": [(1.0 if s == "lo" else -1.0) if b == a else 0.0 for b in range(3)],
        }
        for a in range(3)
        for s in ("lo", "hi")
    ]
    return Scenario.model_validate(
        {
            "name": "pile",
            "materials": {"m": {"density": 2500, "shear_modulus": 1e7, "poisson_ratio": 0.3}},
            "contact": {
                "model": "hertz",
                "tangential": "mindlin",
                "friction": 0.5,
                "normal_damping": 0.1,
            }
            | (
                {"rolling": "epsd", "rolling_stiffness": 1e-3, "rolling_friction": 0.1}
                if rolling
                else {}
            ),
            "particles": [
                {
                    "material": "m",
                    "radius": r,
                    "position": tuple(p),
                    "velocity": tuple(rng.uniform(-0.05, 0.05, 3)),
                }
                for p in x
            ],
            "walls": walls,
            "gravity": [0, 0, -9.81],
            "integrator": {"dt": 2e-6},
            "stages": [{"name": "fall", "steps": 5000, "output_every": 1000}],
        }
    )


def lattice(arithmetic: str = "float") -> Scenario:
    """4 x 4 x 4 cells of a periodic fcc lattice pressed 1e-5 m into each other, shaken with
    random velocities, frictional Mindlin contacts, local damping; the lateral edges held
    at 5 kPa by the inertial servo while z is compressed."""
    spacing = 0.999 * 0.01 * 2**0.5
    fcc = periodic_fcc(4, spacing, random_velocity=0.01, seed=3)
    return Scenario.model_validate(
        {
            "name": "lattice",
            **fcc,
            "cell": fcc["cell"] | {"servo_mass": 0.01},
            "integrator": {"dt": 1e-6, "arithmetic": arithmetic},
            "damping": {"local": 0.1},
            "stages": [
                {
                    "name": "squeeze",
                    "steps": 3000,
                    "output_every": 500,
                    "cell": {
                        "x": {"stress": 5e3},
                        "y": {"stress": 5e3},
                        "z": {"strain_rate": -1.0},
                    },
                }
            ],
        }
    )


def run_with_threads(threads: int, out, builder: str = "pile()") -> dict[str, np.ndarray]:
    """The trajectory's positions, velocities and spins, and every observable (some found
    from the pair arrays at their steps), of the scenario `builder` run on `threads`, by
    their paths in the forward file."""
    script = on_threads(threads) + (
        "import sys; from pathlib import Path; from tests.physics.test_determinism import *;"
        "from revdem_cli.engine import run_scenario;"
        f"run_scenario({builder}, '', '.toml', Path(sys.argv[1]), reverse=False)"
    )
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    subprocess.run([sys.executable, "-c", script, str(out)], check=True, env=env, cwd=os.getcwd())
    name = builder.split("(")[0]
    with h5py.File(out / f"{name}.forward.h5") as f:
        kept = [
            f"particles/all/{quantity}/value"
            for quantity in ("position", "velocity", "angular_velocity")
        ]
        f["observables"].visit(
            lambda path: kept.append(f"observables/{path}") if path.endswith("value") else None
        )
        return {path: f[path][:] for path in kept}


def assert_bitwise_identical_and_moving(one: dict, two: dict) -> None:
    """Every array of the two runs the same bit for bit, over a trajectory in which the
    spheres moved and turned, so that their forces and moments were compared."""
    assert one.keys() == two.keys()
    for path in one:
        assert np.array_equal(one[path], two[path]), path
    position = one["particles/all/position/value"]
    assert np.abs(position[-1] - position[0]).max() > 0
    assert np.abs(one["particles/all/angular_velocity/value"][-1]).max() > 0


@pytest.mark.parametrize("builder", ["pile()", "pile(rolling=True)"])
def test_one_and_two_threads_give_bitwise_identical_trajectories(tmp_path, builder):
    """One thread: the serial pair loop sums each sphere's forces and moments itself, and
    fills the pair arrays only where something reads them (`pairs.sum_in_order`); two: one
    chunk of the list a thread, each summing its own spheres, those with a partner in an
    earlier chunk summed after from the pair arrays (`pairs.sum_foreign`)."""
    one = run_with_threads(1, tmp_path / "one", builder)
    two = run_with_threads(2, tmp_path / "two", builder)
    assert_bitwise_identical_and_moving(one, two)


@pytest.mark.parametrize("arithmetic", ["float", "fixed"])
def test_a_deforming_periodic_cell_is_bitwise_the_same_with_one_and_two_threads(
    tmp_path, arithmetic
):
    builder = f"lattice({arithmetic!r})"
    one = run_with_threads(1, tmp_path / "one", builder)
    two = run_with_threads(2, tmp_path / "two", builder)
    assert_bitwise_identical_and_moving(one, two)
