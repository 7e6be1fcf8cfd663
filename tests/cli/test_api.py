"""The Python API: the README's example run as it is written there, and bad input raised
as the one line the command line prints."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from revdem_cli import api as revdem
from revdem_cli.errors import InputError
from tests.conftest import CONFIGS

README = Path(__file__).parents[2] / "README.md"


def _example() -> str:
    section = README.read_text().split("## Python\n", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_example_runs_as_written(tmp_path, capsys):
    """The example reverses the frictionless collision and not the sliding one, and its
    arrays are the trajectory's."""
    code = _example().replace('"configs/', f'"{CONFIGS}/')
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        scope: dict = {}
        exec(compile(code, "README.md", "exec"), scope)
    finally:
        os.chdir(here)
    assert capsys.readouterr().out.startswith("False [")
    verdict = scope["verdict"]
    assert verdict["reversible"] is False and verdict["divergence_causes"]
    time, energy = scope["time"], scope["energy"]
    assert len(time) == len(energy) > 10 and np.all(np.diff(time) > 0)
    mass = 1000.0 * 4.0 / 3.0 * np.pi * 0.005**3  # configs/collision.toml's spheres
    assert energy[0] == pytest.approx(0.5 * mass * (0.9**2 + 0.1**2 + 0.1**2), rel=1e-12)
    assert scope["position"].shape == (len(scope["steps"]), 2, 3)
    assert (tmp_path / "out" / "api" / "collision.compare.json").is_file()


def test_a_changed_field_is_checked_as_a_file_is():
    collision = revdem.load(CONFIGS / "collision.toml")
    with pytest.raises(InputError, match=r"collision.toml: integrator.dt: .*greater than 0"):
        collision.changed({"integrator.dt": -1.0})
    with pytest.raises(InputError, match=r"^<dict>: particles\[0\].radius"):
        revdem.from_dict(collision.fields, changes={"particles.0.radius": "big"})
    with pytest.raises(InputError, match="stages.5.steps: '5' is not an index of a list of 1"):
        collision.changed({"stages.5.steps": 10})


def test_results_name_what_they_do_not_have(tmp_path):
    result = revdem.run(revdem.load(CONFIGS / "collision.toml"), tmp_path, reverse=False)
    assert result.comparison is None
    with pytest.raises(InputError, match="no reverse trajectory"):
        result.observable("kinetic_energy", run="reverse")
    with pytest.raises(InputError, match="no observable 'entropy'.*kinetic_energy"):
        result.observable("entropy")
    assert set(result.observables()) >= {"kinetic_energy", "total_energy"}
