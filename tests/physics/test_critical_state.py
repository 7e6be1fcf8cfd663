"""The critical-state observables (void ratio, p, q, the fabric of the contact normals, the
mechanical coordination number, the sliding fraction) on packings whose values are known,
and a stage's own friction and viscous damping (`stages[].contact`)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from revdem_cli import api as revdem
from revdem_cli.config import Scenario
from revdem_cli.config.loader import scenario_from_text
from revdem_cli.errors import InputError
from revdem_cli.stage import Model
from revdem_cli.state import initial_state
from tests.conftest import periodic_fcc, two_spheres

RADIUS = 0.005


def observed(scenario: Scenario) -> tuple[Model, dict]:
    """The model of `scenario` and its observables row at the start, by name."""
    model = Model.of(scenario)
    row = model.observe(initial_state(scenario), model.dynamics)
    named = {}
    for name, shape in model.layout.series():
        at = model.layout.column(name)
        named[name] = row[at : at + math.prod(shape)].reshape(shape) if shape else row[at]
    return model, named


def test_a_chain_of_three_spheres_and_a_rattler():
    """Spheres 0-1-2 touching along x, sphere 3 alone: the fabric is n n = diag(1, 0, 0),
    its deviatoric invariant sqrt(3/2 (4/9 + 1/9 + 1/9)) = 1; two contacts give 2 x 2 / 4 =
    1 contact a sphere, but with the rattler (no contact) and the two ends (one contact)
    left out, Z_m = (2 x 2 - 2) / (4 - 1 - 2) = 2 (Thornton 2000)."""
    sphere = {"material": "sphere", "radius": RADIUS}
    places = [[0, 0, 0], [0.0099, 0, 0], [0.0198, 0, 0], [0, 0.05, 0]]
    _, row = observed(two_spheres(particles=[{**sphere, "position": x} for x in places]))
    assert row["fabric"] == pytest.approx(np.diag([1.0, 0.0, 0.0]), abs=1e-15)
    assert row["fabric_deviator"] == pytest.approx(1.0, rel=1e-12)
    assert row["coordination_number"] == 1.0
    assert row["mechanical_coordination_number"] == 2.0
    assert row["sliding_fraction"] == 0.0


def test_no_contact_gives_zero_fabric_and_coordination():
    """Two spheres apart: nothing to average, so the fabric, Z_m and the sliding fraction
    are 0, not a division by zero."""
    _, row = observed(two_spheres())
    assert not row["fabric"].any()
    assert row["mechanical_coordination_number"] == 0.0
    assert row["fabric_deviator"] == 0.0
    assert row["sliding_fraction"] == 0.0


def test_a_compressed_fcc_lattice_is_isotropic():
    """A periodic fcc lattice of 108 spheres pressed 0.1 % into each other: 12 contacts a
    sphere and no rattler (Z_m = 12), the twelve normals <110> average to I / 3 (deviatoric
    invariant 0); void ratio (3 s)^3 / (108 x 4/3 pi r^3) - 1 from the cell; p the mean of
    the stress's diagonal, q = 0 by symmetry."""
    spacing = 0.999 * 2 * RADIUS * 2**0.5
    fields = periodic_fcc(3, spacing, random_velocity=0.0, seed=0)
    scenario = Scenario.model_validate(
        {
            "name": "lattice",
            **fields,
            "integrator": {"dt": 1e-6},
            "stages": [{"name": "run", "steps": 1}],
        }
    )
    _, row = observed(scenario)
    assert row["mechanical_coordination_number"] == 12.0
    assert row["fabric"] == pytest.approx(np.eye(3) / 3.0, abs=1e-15)
    assert row["fabric_deviator"] < 1e-14
    solids = 108 * 4.0 / 3.0 * math.pi * RADIUS**3
    assert row["void_ratio"] == pytest.approx((3 * spacing) ** 3 / solids - 1.0, rel=1e-12)
    sigma = row["stress"]
    assert sigma[0, 0] > 0.0  # compression positive
    assert row["mean_stress"] == pytest.approx(np.trace(sigma) / 3.0, rel=1e-12)
    assert row["deviator_stress"] < 1e-9 * row["mean_stress"]


YAML = """
name: pair
materials: {sphere: {density: 1000.0, shear_modulus: 2.0e6, poisson_ratio: 0.2}}
contact: {model: hertz, tangential: mindlin, friction: 0.5, normal_damping: 0.1}
particles:
  - {material: sphere, radius: 0.005, position: [0, 0, 0]}
  - {material: sphere, radius: 0.005, position: [0.00996, 0, 0]}
integrator: {dt: 1.0e-7}
stages:
  - {name: prepare, steps: 10, contact: {friction: 0.0}}
  - {name: damp, steps: 10, contact: {normal_damping: 0.3, tangential_damping: 0.2}}
  - {name: shear, steps: 10}
"""


def test_a_stage_sets_its_own_friction_and_damping():
    """A stage's contact record takes the coefficients it gives and keeps the others (and
    the laws) of [contact]; a stage without them runs with [contact]'s record itself."""
    model = Model.of(scenario_from_text(YAML, ".yaml", "pair.yaml"))
    prepare, damp, shear = (model.stage_law(s) for s in model.scenario.stages)
    assert (prepare.mu, prepare.beta_n, prepare.beta_t) == (0.0, 0.1, 0.0)
    assert (damp.mu, damp.beta_n, damp.beta_t) == (0.5, 0.3, 0.2)
    assert shear is model.law
    assert prepare._replace(mu=0.5) == model.law  # the laws and their parameters kept


@pytest.mark.parametrize(
    ("text", "change", "message"),
    [
        (
            YAML.replace("tangential: mindlin, friction: 0.5, ", ""),
            None,
            "stages[0].contact.friction: needs a tangential law",
        ),
        (YAML, "stages.2.contact.friction=-1", "stages[2].contact.friction"),
        (YAML, "stages.2.contact.normal_damping=nan", "stages[2].contact.normal_damping"),
        (YAML, "stages.2.contact.kn=1", "stages[2].contact.kn: unknown field"),
    ],
)
def test_bad_stage_contacts_are_named_by_path(text, change, message):
    with pytest.raises(InputError) as error:
        scenario_from_text(text, ".yaml", "pair.yaml", [change] if change else [])
    assert message in str(error.value)
    assert "\n" not in str(error.value)


SMOKE = Path(__file__).resolve().parents[2] / "configs" / "smoke" / "critical_state.toml"
LOOSE = {"stages.0.contact.friction": 1.0, "stages.1.contact.friction": 1.0}
"""The smoke sample's preparation with mu = 1: loose."""


def _shearing(result) -> dict[str, np.ndarray]:
    """Void ratio, q / p and sliding fraction of the shear stage (the last 5 000 steps)."""
    series = result.observables()
    time = result.observable("void_ratio")[0]
    keep = time >= time[-1] - 5000 * 2.0e-5 * (1 + 1e-9)  # 5 000 steps of 20 us
    return {
        "e": series["void_ratio"][1][keep],
        "q/p": series["deviator_stress"][1][keep] / series["mean_stress"][1][keep],
        "sliding": series["sliding_fraction"][1][keep],
    }


def test_smoke_dense_dilates_and_loose_contracts(tmp_path):
    """The smoke samples (300 spheres at 10 kPa) sheared 5 % with mu = 0.5: prepared without
    friction the sample is denser than with mu = 1; sheared, the dense one dilates and the
    loose one contracts, towards each other (Hanley 2020 Figure 7), with some contacts
    sliding and most not; the dense one mobilises q / p above 0.5 at its peak and after, the
    loose one, still hardening, some of it but less (its q / p after 5 % depends on the
    realisation of its packing: 0.56 and 0.29 in two that differ only by the rounding of
    the moments)."""
    dense = _shearing(revdem.run(revdem.load(SMOKE), tmp_path / "dense", reverse=False))
    loose = _shearing(revdem.run(revdem.load(SMOKE, LOOSE), tmp_path / "loose", reverse=False))
    assert loose["e"][0] > dense["e"][0] + 0.03, (loose["e"][0], dense["e"][0])
    assert dense["e"][-1] > dense["e"][0] + 0.02
    assert loose["e"][-1] < loose["e"][0]
    assert abs(loose["e"][-1] - dense["e"][-1]) < abs(loose["e"][0] - dense["e"][0])
    assert dense["q/p"][-1] > 0.5
    assert 0.2 < loose["q/p"][-1] < dense["q/p"][-1]
    for sample in (dense, loose):
        assert 0.0 < sample["sliding"][-1] < 0.6


def test_smoke_frictionless_undamped_shearing_reverses_bit_for_bit(tmp_path):
    """The dense smoke sample sheared with the stage's mu = 0 and no damping (energy-
    conserving, fixed-point arithmetic): every contact slides (its shear force is capped at
    0), and the reversed shearing lands on the very integers it started from, so on the
    sample's own initial void ratio."""
    experiment = revdem.load(SMOKE, {"stages.2.contact.friction": 0.0})
    result = revdem.run(experiment, tmp_path)
    assert result.comparison["bitwise_identical"], result.comparison
    forward = _shearing(result)
    assert (forward["sliding"][1:] > 0.99).all()
    back = result.observable("void_ratio", run="reverse")[1]
    assert back[-1] == forward["e"][0]
    assert abs(forward["e"][-1] - forward["e"][0]) > 1e-4  # it did move


def test_a_run_stopped_inside_a_stage_of_its_own_friction_resumes_to_the_same_bits(tmp_path):
    """The shear collision (Mindlin, mu = inf in [contact]) with mu = 0.3 for its one stage,
    stopped by SIGINT while the spheres slide (after frame 4 of 30, step 2 000), resumed from its
    checkpoint: the files, reversal included, are those of the run left alone, and in both
    the shear force was capped at 0.3 |f_n| (Hanley 2020 §4-5.1), not left free."""
    import os
    import signal

    from revdem_cli.checkpoint import Interrupted
    from revdem_cli.engine import run_scenario
    from tests.conftest import CONFIGS
    from tests.reliability.test_checkpoints import assert_same_files

    changes = {"stages.0.contact": {"friction": 0.3}, "stages.0.output_every": 500}
    changes |= {"output.figures": []}
    experiment = revdem.load(CONFIGS / "collision_shear.toml", changes)
    experiment = experiment.changed({"output.checkpoint_interval": 0.0})  # at every frame
    whole = revdem.run(experiment, tmp_path / "whole")
    frames = []

    def interrupt_at_frame_4(label, done, total, particles):
        frames.append(done)
        if len(frames) == 4:
            os.kill(os.getpid(), signal.SIGINT)  # a checkpoint at the next frame, then a stop

    with pytest.raises(Interrupted):
        run_scenario(experiment.scenario, experiment.text, experiment.suffix, tmp_path / "cut",
                     True, interrupt_at_frame_4)  # fmt: skip
    revdem.resume(tmp_path / "cut")
    assert_same_files(tmp_path / "whole", tmp_path / "cut")
    shear = whole.observable("max_shear_force")[1]
    normal = whole.observable("max_normal_force")[1]
    touching = normal > 0.0
    ratio = shear[touching] / normal[touching]
    assert ratio.max() == pytest.approx(0.3, rel=1e-9)
    assert not whole.comparison["reversible"]  # the cap destroyed information


SHORT = {
    "stages.1.steps": 1000,
    "stages.2.steps": 300,
    "stages.2.output_every": 100,
    "reversal.tape": True,
    "output.figures": [],
}
"""The smoke sample's stages cut short (1 000 steps of isotropic compression, its stop
condition unmet; 300 of shearing), reversed with an information tape: bit for bit."""

CAPPED = re.compile(
    r"capped +stage shear began at step (\d+) under friction 0\.5: (\d+) contacts slid to "
    r"the new limit, (\S+) J of elastic energy gone"
)
"""The summary's line on what the shear stage's law cut at its start."""


def _run_smoke(out: Path, changes: dict) -> str:
    """`revdem run` of the smoke sample cut short (SHORT) with `changes`, as the command line
    takes them, into `out`: its output."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app

    settings = [f"{key}={json.dumps(value)}" for key, value in (SHORT | changes).items()]
    args = ["run", str(SMOKE), "--out", str(out), "--threads", "1"]
    result = CliRunner().invoke(app, args + [item for s in settings for item in ("--set", s)])
    assert result.exit_code == 0, result.output
    return result.output


def _rows(path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The steps and values of an observable's rows in a trajectory."""
    from revdem_cli.io.h5md import observable_steps, open_trajectory, read_observable

    with open_trajectory(path) as f:
        return observable_steps(f, name), read_observable(f, name)[1]


@pytest.mark.parametrize("all_stages", [False, True])
def test_a_loose_sample_reversed_returns_to_the_start_its_shear_stage_cut(tmp_path, all_stages):
    """The loose smoke sample (mu = 1 in its preparation) sheared with mu = 0.5: the shear
    stage's law cuts every shear force above 0.5 |f_n| at its start (Hanley 2020 §5.1), and
    the run writes the row of that start beside the preparation's end, at the same step.
    The reversal returns to it bit for bit: the total energy back is the forward run's
    there, and every reversed row of energy and stress is the forward row of its state, to
    the last digit (with every stage reversed, through the preparation's end too, written
    back in the other order). The summary says what the cut took: the contacts and the
    elastic energy between the two rows, which `read` gives back from the restart."""
    out = tmp_path / "loose"
    said = _run_smoke(out, LOOSE | {"reversal.all_stages": all_stages})
    step, slid, gone = CAPPED.search(said).groups()
    result = revdem.read(out)
    verdict = result.comparison
    assert verdict["bitwise_identical"], verdict
    back = verdict["total_energy_back"]
    assert back["forward"] == back["reversed"]
    assert back["step"] == (0 if all_stages else int(step))
    steps, elastic = _rows(result.trajectory(), "elastic_energy")
    before, start = elastic[steps == int(step)]  # the preparation's end, the stage's start
    assert int(slid) > 0 and float(gone) > 0.0
    assert float(gone) == pytest.approx(before - start, rel=1e-2)  # as printed, 3 digits
    assert result.outputs.capped["shear"]["slid"] == int(slid)
    from revdem_cli.compare import paired_rows

    for name in ("elastic_energy", "total_energy", "stress", "bits_destroyed"):
        (steps, forward), (back_steps, reverse) = (
            _rows(result.trajectory(run), name) for run in ("forward", "reverse")
        )
        pairs = paired_rows(steps, back_steps)
        assert len(pairs) == len(back_steps)
        for row, reversed_row in pairs:
            assert np.array_equal(forward[row], reverse[reversed_row], equal_nan=True), name
    assert (back_steps == int(step)).sum() == (2 if all_stages else 1)
    from revdem_cli.report.paper import MEASURES, _Run

    run = _Run(out, "critical_state_smoke", {})  # `revdem report`'s measures of the stage
    measured = {key: MEASURES[f"stress_ratio_{key}"][1](run) for key in ("start", "reversed")}
    assert measured["start"] == measured["reversed"]


def test_a_loose_sample_stopped_while_shearing_resumes_to_the_same_files(tmp_path):
    """Stopped after the shear stage's second frame, the loose sample resumes from the
    checkpoint of its first, which keeps what the stage's law cut at its start: the files
    are those of the run left alone, and the reversal returns to the stage's own start."""
    from tests.conftest import crashed_after
    from tests.reliability.test_checkpoints import assert_same_files

    experiment = revdem.load(SMOKE, LOOSE | SHORT | {"output.checkpoint_interval": 0.0})
    whole = revdem.run(experiment, tmp_path / "whole", threads=1)
    assert crashed_after(experiment, tmp_path / "cut", 7)[-1] == "shear (forward)"
    resumed = revdem.resume(tmp_path / "cut", threads=1)
    assert_same_files(tmp_path / "whole", tmp_path / "cut")
    assert resumed.outputs.capped == whole.outputs.capped != {}
    back = resumed.comparison["total_energy_back"]
    assert back["forward"] == back["reversed"]


@pytest.mark.parametrize(
    "changes",
    [{}, LOOSE | {"stages.2.contact.friction": 1.0}],
    ids=["dense, nothing to cut", "one friction throughout"],
)
def test_a_stage_start_that_cuts_nothing_adds_no_row(tmp_path, changes):
    """The dense smoke sample, prepared without friction (nothing for the shear stage's mu
    = 0.5 to cut), and the loose one sheared under its preparation's mu = 1: no stage
    writes a row of its own beside the end of the one before, and the summary names no cut;
    the rows are one a step, as the forward run's steps of observation give them."""
    said = _run_smoke(tmp_path, changes)
    assert "capped" not in said
    result = revdem.read(tmp_path)
    assert result.outputs.capped == {}
    assert result.comparison["bitwise_identical"]
    back = result.comparison["total_energy_back"]
    assert back["forward"] == back["reversed"]
    for run in ("forward", "reverse"):
        steps, _ = _rows(result.trajectory(run), "total_energy")
        assert len(np.unique(steps)) == len(steps), run


def _overlap(a: dict, b: dict) -> bool:
    """Whether two final values' ranges over the last 5 % of strain overlap."""
    return a["min"] <= b["max"] and b["min"] <= a["max"]


def test_the_committed_critical_state_runs_say_what_their_report_says():
    """scenarios/hanley2020/critical_state/results.json, from the full runs: with mu = 0.5
    the dense sample dilates and the loose one contracts (each by more than a third of the
    gap between them) to q/p, Z_m and fabric within each
    other's ranges over the last 5 % of strain; the void ratios of every pair that
    dissipates (mu = 0.5 from two packings and to 40 %, frictionless with viscous normal or
    tangential damping) end within a tenth of the gap they started with; frictionless and
    undamped they stay apart, and each reverses bit for bit to its own. With the
    information tape the mu = 0.5 pair reverses bit for bit too, and over the last 5 % the
    two destroy information at one rate, within a tenth."""
    folder = Path(__file__).resolve().parents[2] / "scenarios" / "hanley2020" / "critical_state"
    results = json.loads((folder / "results.json").read_text())
    dense, loose = results["friction"]["dense"], results["friction"]["loose"]
    gap = loose["start"]["void_ratio"] - dense["start"]["void_ratio"]
    assert gap > 0.2
    # each covers more than a third of the starting gap towards the other
    assert dense["final"]["void_ratio"]["mean"] > dense["start"]["void_ratio"] + gap / 3
    assert loose["final"]["void_ratio"]["mean"] < loose["start"]["void_ratio"] - gap / 3
    for key in ("stress_ratio", "mechanical_coordination_number", "fabric_deviator"):
        assert _overlap(dense["final"][key], loose["final"][key]), key

    def gaps(case):  # loose - dense: at the start of shearing, and over the last 5 %
        run = results[case]
        start = run["loose"]["start"]["void_ratio"] - run["dense"]["start"]["void_ratio"]
        end = run["loose"]["final"]["void_ratio"]["mean"]
        return start, end - run["dense"]["final"]["void_ratio"]["mean"]

    for case in ("friction", "seed23", "long", "viscous", "tangential"):
        start, end = gaps(case)
        assert abs(end) < 0.1 * start, case
    start, end = gaps("elastic")
    assert end > 0.4 * start
    for sample in ("dense", "loose"):
        run = results["elastic"][sample]
        assert run["reversal"]["bitwise_identical"]
        assert run["reversal"]["void_ratio_back"] == run["start"]["void_ratio"]
        assert results["tape"][sample]["reversal"]["bitwise_identical"]
    rates = [results["tape"][s]["bits_per_percent_strain_last"] for s in ("dense", "loose")]
    assert abs(rates[0] - rates[1]) < 0.1 * max(rates)
