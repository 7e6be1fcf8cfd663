import pytest

from revdem_cli.config import load_scenario, scenario_from_text
from revdem_cli.config.schema import Scenario
from revdem_cli.errors import InputError
from tests.conftest import CONFIGS

YAML = """
name: yaml-pair
materials:
  sphere: {density: 1000.0, shear_modulus: 2.0e6, poisson_ratio: 0.2}
contact: {model: linear, kn: 1.0e4}
particles:
  - {material: sphere, radius: 0.005, position: [0, 0, 0]}
  - {material: sphere, radius: 0.005, position: [0.0101, 0, 0], velocity: [-1, 0, 0]}
integrator: {dt: 1.0e-6}
stages:
  - {name: go, steps: 10}
"""


def test_collision_file_is_the_papers_case():
    scenario, _ = load_scenario(CONFIGS / "collision.toml")
    a, b = scenario.particles
    assert (a.radius, b.radius) == (0.005, 0.005)
    assert a.velocity == (0.9, 0.1, 0.0) and b.velocity == (0.0, 0.0, 0.1)
    assert b.position == (0.0101, 0.0, 0.0)
    assert scenario.integrator.dt == 1e-7
    assert scenario.reversed_stage.steps == 15000


def test_yaml_scenario_is_read_like_toml():
    scenario = scenario_from_text(YAML, ".yaml", "pair.yaml")
    assert scenario.contact.model == "linear" and scenario.contact.kn == 1e4
    assert scenario.particles[1].velocity == (-1.0, 0.0, 0.0)


def test_overrides_reach_nested_fields_and_list_items():
    scenario = scenario_from_text(
        YAML, ".yaml", "pair.yaml", ["integrator.dt=2e-6", "particles.1.radius=0.004"]
    )
    assert scenario.integrator.dt == 2e-6
    assert scenario.particles[1].radius == 0.004


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("integrator.dt=-1.0", "integrator.dt: Input should be greater than 0"),
        ("particles.0.radius=0", "particles[0].radius: Input should be greater than 0"),
        ("particles.0.material='steel'", "particles[0].material: unknown material 'steel'"),
        ("contact.kn=nan", "contact.kn"),
        ("integrator.dt='fast'", "integrator.dt: Input should be a valid number"),
        ("stages.0.colour='red'", "stages[0].colour: unknown field"),
        (
            "contact.normal_dampin=0.1",
            "contact.normal_dampin: unknown field (did you mean normal_damping?)",
        ),
        ("stages.0.stop_whn=1", "stages[0].stop_whn: unknown field (did you mean stop_when?)"),
        (
            "materials.sphere.densty=1",
            "materials.sphere.densty: unknown field (did you mean density?)",
        ),
        (  # was run to its end, the condition never checked
            "stages.0.stop_when={kinetic_energy_below=1e-7, after_steps=10}",
            "stages[0].stop_when.after_steps: 10 must be below the stage's steps, 10",
        ),
        ("output.figures=['speed','speed']", "output: figure 'speed' is listed twice"),
        # was silently ignored, where the same in a stage's [contact] is refused
        ("contact.friction=0.5", "contact.friction: needs a tangential law"),
        # tangential damping without a tangential law was accepted and did nothing
        ("contact.tangential_damping=0.3", "contact.tangential_damping: needs a tangential law"),
        (
            "stages.0.contact={tangential_damping=0.3}",
            "stages[0].contact.tangential_damping: needs a tangential law",
        ),
        (
            "particles.1.position=[0.005, 0, 0]",
            "particles[1].position: sphere 1 of particles overlaps sphere 0 of",
        ),
    ],
)
def test_bad_fields_are_named_by_path(change, message):
    with pytest.raises(InputError) as error:
        scenario_from_text(YAML, ".yaml", "pair.yaml", [change])
    assert str(error.value).startswith("pair.yaml: ")
    assert message in str(error.value)
    assert "\n" not in str(error.value)


def test_an_empty_override_unsets_an_optional_field():
    """`--set stages.0.stop_when=null` was refused as the text 'null', and nothing on the
    command line unset a field a file gives: an empty value does, as the API's None does;
    a field that must have a value is refused as before."""
    smoke = CONFIGS / "smoke" / "oedometer.toml"
    assert load_scenario(smoke)[0].stages[0].stop_when is not None
    assert load_scenario(smoke, ["stages.0.stop_when="])[0].stages[0].stop_when is None
    fcc = CONFIGS / "fcc_triaxial.toml"
    unset = load_scenario(fcc, ["cell.servo=proportional", "cell.servo_mass="])[0]
    assert unset.cell.servo_mass is None
    # a field whose default is not None takes it (it was refused as "not a valid tuple")
    walled = load_scenario(CONFIGS / "drop_A.toml", ["gravity=", "walls=", "output="])[0]
    default = Scenario.model_fields
    assert walled.gravity == default["gravity"].default == (0.0, 0.0, 0.0)
    assert walled.walls == [] and walled.output == default["output"].get_default(
        call_default_factory=True
    )
    with pytest.raises(InputError, match="integrator.dt: Input should be a valid number"):
        load_scenario(CONFIGS / "collision.toml", ["integrator.dt="])


def test_linear_law_requires_kn():
    with pytest.raises(InputError, match="contact: .*needs kn"):
        scenario_from_text(YAML.replace("kn: 1.0e4", ""), ".yaml", "pair.yaml")


def test_only_the_last_stage_can_be_reversed():
    text = YAML.replace(
        "- {name: go, steps: 10}",
        "- {name: go, steps: 10, reverse: true}\n  - {name: settle, steps: 5}",
    )
    with pytest.raises(InputError, match=r"stages\[0\]\.reverse: the reversed stage must be"):
        scenario_from_text(text, ".yaml", "pair.yaml")
    both = text.replace("{name: settle, steps: 5}", "{name: settle, steps: 5, reverse: true}")
    with pytest.raises(InputError) as error:  # the message named the later stage alone
        scenario_from_text(both, ".yaml", "pair.yaml")
    assert (
        "stages[0].reverse: only one stage can be reversed, the last; stages[0] and "
        "stages[1] are marked" in str(error.value)
    )


def test_the_platens_are_the_planes_across_z():
    """The oedometer's bottom and top, not its cylinder: the walls whose z force is a load
    (`wall_forces`); a plane whose normal lies nearest x or y is a side wall."""
    scenario, _ = load_scenario(CONFIGS / "oedometer.toml")
    assert [wall.name for wall in scenario.walls if wall.across_z] == ["bottom", "top"]
    side = scenario.walls[1].model_copy(update={"normal": (1.0, 0.0, 0.5)})
    tilted = scenario.walls[1].model_copy(update={"normal": (0.3, -0.4, 0.6)})
    assert (side.across_z, tilted.across_z) == (False, True)


def test_scenarios_apart_in_one_fields_value_name_that_field_alone():
    """A stage's contact given in one run and not the other was listed as three garbled
    fields: 'stages.2.contact = None and -; stages.2.contact.friction = - and 0.0;
    stages.2.contact.normal_damping = - and None and 1 more'."""
    from revdem_cli.config import fields_apart

    smoke = CONFIGS / "smoke" / "critical_state.toml"
    given = load_scenario(smoke, ["stages.2.contact.friction=0"])[0]
    assert fields_apart(load_scenario(smoke)[0], given) == [
        ("stages.2.contact.friction", "(unset)", 0.0)
    ]
    unset = load_scenario(smoke, ["stages.1.stop_when="])[0]  # a table set against none
    assert fields_apart(unset, load_scenario(smoke)[0]) == [
        ("stages.1.stop_when.kinetic_energy_below", "(unset)", 1.5e-7)
    ]


def test_a_time_step_just_above_its_limit_is_not_said_to_be_at_it():
    """dt = 4e-5 s against 3.98e-5 s was refused as "1 times the critical time step"."""
    from revdem_cli.timestep.guard import time_step_excess, times_above

    scenario = load_scenario(CONFIGS / "smoke" / "oedometer.toml", ["integrator.dt=4e-5"])[0]
    said = str(time_step_excess(scenario))
    assert "4e-05 s is 1.005 times the critical time step 3.98e-05 s" in said
    assert [times_above(r) for r in (1.0049, 1.0000001, 2.5, 11.94)] == [
        "1.005",
        "1.0000001",
        "2.5",
        "11.9",
    ]
