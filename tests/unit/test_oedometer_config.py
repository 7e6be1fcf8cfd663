"""The oedometer scenario files, the solid fraction container and the stop conditions."""

import numpy as np
import pytest

from revdem_cli.config import load_scenario, scenario_from_text
from revdem_cli.errors import InputError
from revdem_cli.stage import Model
from revdem_cli.state import initial_state
from tests.conftest import CONFIGS

SMOKE = CONFIGS / "smoke" / "oedometer.toml"


def test_the_full_oedometer_is_the_papers_case():
    scenario, _ = load_scenario(CONFIGS / "oedometer.toml")
    radii = scenario.spheres.radius
    assert len(radii) == 900 and 0.0045 <= radii.min() and radii.max() <= 0.0055
    assert {m.shear_modulus for m in scenario.materials.values()} == {2e6, 1e9}
    compress = scenario.reversed_stage
    assert compress.steps == 1_500_000 and scenario.integrator.dt == 5e-8 and compress.dt is None
    assert compress.wall_velocities == {"top": (0.0, 0.0, -0.01)}
    assert compress.damping.local == 0.0
    cylinder = next(w for w in scenario.walls if w.type == "cylinder")
    assert cylinder.radius == 0.1


def test_solid_fraction_is_the_spheres_volume_over_the_volume_between_the_planes():
    scenario, _ = load_scenario(SMOKE)
    model = Model.of(scenario)
    state = initial_state(scenario)
    row = model.observe(state, model.dynamics)
    volume = float((4 / 3 * np.pi * scenario.spheres.radius**3).sum())
    expected = volume / (np.pi * 0.055**2 * 0.065)
    assert row[model.layout.column("solid_fraction")] == pytest.approx(expected, rel=1e-12)
    top = model.layout.column("wall_position/top")
    assert tuple(row[top : top + 3]) == (0.0, 0.0, 0.065)


@pytest.mark.parametrize(
    "override, where",
    [
        ("solid_fraction.cylinder=bottom", "solid_fraction.cylinder: no cylinder wall is named"),
        ("solid_fraction.planes.1=nowhere", "solid_fraction.planes[1]: no plane wall is named"),
        ("walls.1.normal=[1,0,0]", "solid_fraction.planes[1]: plane 'top' is not perpendicular"),
        ("stages.1.stop_when.solid_fraction_above=1.5", "stages[1].stop_when.solid_fraction_above"),
        ("walls.2.material=sphere", "walls[2].material: with contact.wall_moduli = 'wall' a wall"),
    ],
)
def test_a_bad_container_or_stop_condition_is_named(override, where):
    with pytest.raises(InputError, match=where.replace("[", r"\[").replace("]", r"\]")):
        load_scenario(SMOKE, [override])


def test_a_solid_fraction_stop_needs_a_container():
    text = SMOKE.read_text()
    start = text.index("[solid_fraction]")
    end = text.index("[integrator]")
    with pytest.raises(
        InputError, match="needs a periodic \\[cell\\] .* or a \\[solid_fraction\\] table"
    ):
        scenario_from_text(text[:start] + text[end:], ".toml", "no_container.toml")


def test_a_stop_condition_names_one_thing():
    with pytest.raises(InputError, match="give exactly one of"):
        load_scenario(SMOKE, ["stages.1.stop_when.kinetic_energy_below=1.0"])
