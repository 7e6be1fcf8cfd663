"""Shared fixtures: scenarios built in code, the collision run once per session, and the counts
of what the reliability tests tried, summed over the test workers and shown after the run."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import pytest

from revdem_cli.config import Scenario, load_scenario
from revdem_cli.engine import run_scenario
from revdem_cli.io.tape import no_tape
from revdem_cli.kernels import parallel_from

TRIED = pytest.StashKey[dict]()
"""{kind: {what: how many}} of what the reliability tests tried (`tests/reliability`)."""

TRIED_TITLES = {
    "generated bad inputs": "generated bad inputs tried",
    "runs stopped": "runs stopped (SIGKILL at random moments, SIGINT, SIGTERM) and resumed, "
    "each to the uninterrupted run's files",
}


def _tally(config, kind: str) -> dict:
    """{what: how many} of one kind of TRIED_TITLES, in this process's stash."""
    return config.stash.setdefault(TRIED, {}).setdefault(kind, {})


@pytest.fixture(scope="session")
def tried(request) -> dict:
    """{what: how many} generated bad inputs a reliability test tried; summed up after the
    run."""
    return _tally(request.config, "generated bad inputs")


@pytest.fixture(scope="session")
def kills(request) -> dict:
    """{case: how many} runs stopped and resumed to the uninterrupted files."""
    return _tally(request.config, "runs stopped")


def pytest_sessionfinish(session):
    """A test worker (pytest-xdist) hands its counts to the process that reports."""
    output = getattr(session.config, "workeroutput", None)
    if output is not None:
        output["tried"] = session.config.stash.get(TRIED, {})


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """A worker's counts added to the run's (pytest-xdist)."""
    for kind, tried in getattr(node, "workeroutput", {}).get("tried", {}).items():
        mine = _tally(node.config, kind)
        for what, n in tried.items():
            mine[what] = mine.get(what, 0) + n


def pytest_terminal_summary(terminalreporter, config):
    for kind, title in TRIED_TITLES.items():
        counts = config.stash.get(TRIED, {}).get(kind, {})
        if counts:
            detail = ", ".join(f"{name} {n}" for name, n in sorted(counts.items()))
            terminalreporter.write_sep(
                "-", f"reliability: {sum(counts.values())} {title} ({detail})"
            )


ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"

SPHERE = {"density": 1000.0, "shear_modulus": 2e6, "poisson_ratio": 0.2}
PLANE = {"density": 1000.0, "shear_modulus": 1e9, "poisson_ratio": 0.2}
"""The materials of Hanley 2020's sphere dropped on a plane (§5.2)."""

FLOOR = {
    "name": "plane",
    "type": "plane",
    "material": "plane",
    "point": (0, 0, 0),
    "normal": (0, 0, 1),
}
"""The plane z = 0 facing up, of material 'plane'."""


def periodic_fcc(cells: int, spacing: float, random_velocity: float, seed: int) -> dict:
    """Scenario fields of a periodic fcc lattice of `cells`^3 unit cells of 5 mm spheres of
    SPHERE with frictional Mindlin contacts (mu = 0.5), shaken with random velocities."""
    return {
        "materials": {"m": SPHERE},
        "contact": {"model": "hertz", "tangential": "mindlin", "friction": 0.5},
        "lattices": [
            {
                "material": "m",
                "radius": 0.005,
                "cells": [cells] * 3,
                "spacing": spacing,
                "random_velocity": random_velocity,
                "seed": seed,
            }
        ],
        "cell": {"size": [cells * spacing] * 3},
    }


def on_threads(threads: int) -> str:
    """Python that makes the stepper of the process it runs in step on `threads` at every
    step, every loop in parallel whatever its size: by itself it times one thread against
    them and steps on the faster, which at a few hundred spheres is one, and a run meant for
    two would then test one; and a loop runs in parallel only from its crossover on
    (`kernels.CROSSOVERS`: hundreds of particles for light loops)."""
    return (
        "from revdem_cli.threads import Stepper; from revdem_cli import kernels;"
        f"Stepper._counts = staticmethod(lambda particles: ({threads},));"
        "kernels.parallel_from[:] = [1, 1];"
    )


@contextmanager
def crossovers(light: int, heavy: int):
    """Loops of each weight in parallel from these particle counts (`kernels.parallel_from`),
    restored after."""
    loaded = parallel_from[:]
    parallel_from[:] = [light, heavy]
    try:
        yield
    finally:
        parallel_from[:] = loaded


@pytest.fixture
def every_loop_parallel():
    """Every loop in parallel whatever its size, as `on_threads` makes it."""
    with crossovers(1, 1):
        yield


def assert_one_line_error(result, *fragments):
    """A command that failed on bad input: exit 2, one line "error: ..." holding the
    fragments, no traceback."""
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error: ") and "Traceback" not in result.output
    for fragment in fragments:
        assert fragment in lines[0]


def two_spheres(**changes) -> Scenario:
    """A small two-sphere scenario (the paper's collision materials); fields can be replaced."""
    data = {
        "name": "pair",
        "materials": {"sphere": {"density": 1000.0, "shear_modulus": 2e6, "poisson_ratio": 0.2}},
        "contact": {"model": "hertz"},
        "particles": [
            {"material": "sphere", "radius": 0.005, "position": [0, 0, 0], "velocity": [0.5, 0, 0]},
            {
                "material": "sphere",
                "radius": 0.005,
                "position": [0.0101, 0, 0],
                "velocity": [-0.5, 0, 0],
            },
        ],
        "integrator": {"dt": 1e-7},
        "stages": [
            {
                "name": "collide",
                "steps": 6000,
                "output_every": 100,
                "observables_every": 1,
                "reverse": True,
            }
        ],
    }
    data.update(changes)
    return Scenario.model_validate(data)


@pytest.fixture(scope="session")
def collision_run(tmp_path_factory):
    """configs/collision.toml run forward and reversed, as `revdem run` does."""
    scenario, text = load_scenario(CONFIGS / "collision.toml")
    return run_scenario(scenario, text, ".toml", tmp_path_factory.mktemp("collision"))


def stepped(scenario: Scenario, steps: int, every: int):
    """The state of a scenario's first stage after every `every` of `steps` steps, as the
    compiled stage loop leaves it (forward, the stage's dt, damping and contact)."""

    from revdem_cli.kernels.integrate import OK, PAIR_OVERFLOW, advance
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import empty_events, initial_state

    model, state = Model.of(scenario), initial_state(scenario)
    stage = scenario.stages[0]
    dyn = model.stage_dynamics(stage)
    state.walls.velocity[:] = model.stage_wall_velocities(stage)
    stepping = model.stepping(scenario.stage_dt(stage), 0, steps, steps)
    (obs, obs_steps), events = model.buffers(2), empty_events()
    while state.step < steps:
        target = min(state.step + every, steps)
        status, state.step, _, _ = advance(
            *stepping_bundles(state, model, dyn, model.stage_law(stage)), events, no_tape(),
            stepping, state.step, target, target, obs, obs_steps,
        )  # fmt: skip
        if status == PAIR_OVERFLOW:
            state.grow_pairs()
            continue
        assert status == OK, f"the stage loop stopped with status {status} at {state.step}"
        yield state


def crashed_after(experiment, folder, frames: int) -> list[str]:
    """Run `experiment` into `folder` as `revdem run` does, crashing it (RuntimeError) after
    `frames` frames, its checkpoint left behind; returns the progress labels shown, the
    last the phase it crashed in."""
    from revdem_cli.engine import run_scenario

    shown = []

    def stop(label, done, total, particles):
        if done == 0:  # a stage's start, not a frame
            return
        shown.append(label)
        if len(shown) == frames:
            raise RuntimeError("stopped")

    with pytest.raises(RuntimeError, match="stopped"):
        scenario, text, suffix = experiment.scenario, experiment.text, experiment.suffix
        run_scenario(scenario, text, suffix, folder, progress=stop)
    return shown
