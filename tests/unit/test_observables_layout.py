"""`Layout`: every column of an observables row that `observe` owns is one it writes, so that
an observable named in the layout but never computed cannot be stored as zeros."""

import math

import numpy as np
import pytest

from revdem_cli.config import load_scenario
from revdem_cli.kernels.observables import CELL_STATE, observe
from revdem_cli.stage import Model
from revdem_cli.state import initial_state
from tests.conftest import CONFIGS

DERIVED = {"solid_fraction", "principal_stress", "fabric_deviator", "bits_destroyed"}
DERIVED |= {name for name, _ in CELL_STATE}
"""The columns the engine fills from the others (`stage.Model.complete`, the tape's bits)."""


@pytest.mark.parametrize("config", ["smoke/oedometer.toml", "smoke/critical_state.toml"])
def test_observe_writes_every_column_it_owns(config):
    """The oedometer has walls and a [solid_fraction] container, the critical-state test a
    periodic cell: a row filled with NaN first keeps none where `observe` should write."""
    scenario, _ = load_scenario(CONFIGS / config)
    model = Model.of(scenario)
    state = initial_state(scenario)
    row = np.full(model.layout.width, np.nan)
    observe(state.particles, state.pairs, state.walls, state.cell, model.law, model.moduli,
            model.dynamics, row)  # fmt: skip
    owned, at = [], 0
    for name, shape in model.layout.series():
        size = math.prod(shape)
        if name not in DERIVED:
            owned.append(name)
            assert np.isfinite(row[at : at + size]).all(), name
        at += size
    assert at == model.layout.width
    assert {"kinetic_energy", "coordination_number", "fabric"} <= set(owned)
    assert any(name.startswith("wall_force/") for name in owned) or "stress" in owned


def test_every_figure_a_scenario_can_name_is_one_that_is_drawn():
    """A figure is named in two places, the scenario's choices (`config.schema.FIGURE_KINDS`,
    what validation takes) and the functions that draw them (`report.figures.FIGURES`): one
    added to the second alone was refused by validation, one in the first alone would fail
    after the run."""
    from revdem_cli.config.schema import FIGURE_KINDS
    from revdem_cli.report.figures import FIGURES

    assert sorted(FIGURE_KINDS) == sorted(FIGURES)
