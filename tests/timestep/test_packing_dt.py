"""The critical time step of a packing (`timestep.packing`): the largest eigenvalue of M⁻¹K
against lattice dynamics and two-body limits, checked on the stepping loop, and
`revdem dt --restart`, `integrator.dt = "auto"`."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.config import Scenario
from revdem_cli.engine import run_scenario
from revdem_cli.io.restart import read_restart
from revdem_cli.stage import Model
from revdem_cli.state import effective_modulus, effective_shear_modulus, initial_state
from revdem_cli.timestep import packing
from revdem_cli.timestep.guard import critical_time_step

DIAMETER = 0.01
SPACING = 0.999 * DIAMETER * 2**0.5  # the fcc benchmark's: an overlap of 10 µm at each contact
MATERIAL = {"density": 1000.0, "shear_modulus": 2.0e6, "poisson_ratio": 0.2}


def lattice(cells: int, contact: dict, steps: int = 10, **extra) -> dict:
    """The fcc Hertz benchmark's lattice (benchmarks/fcc_hertz.py), at rest."""
    return {
        "name": "fcc",
        "materials": {"m": MATERIAL},
        "contact": contact,
        "lattices": [
            {"material": "m", "radius": DIAMETER / 2, "cells": [cells] * 3, "spacing": SPACING}
        ],
        "cell": {"size": [cells * SPACING] * 3},
        "integrator": {"dt": 1.0e-5},
        "stages": [{"name": "run", "steps": steps, "output_every": steps}],
    } | extra


def limit_of(data: dict):
    scenario = Scenario.model_validate(data)
    state, model = initial_state(scenario), Model.of(scenario)
    return packing.packing_limit(state, model), state, model


def hertz_stiffnesses() -> tuple[float, float, float]:
    """(k_n = dF/dδ = 2 E* √(R* δ) (Hanley 2020 Eq 6), k_s = 8 G* √(R* δ) (Eq 10), the lever
    arm r - δ/2) at the benchmark's overlap."""
    from revdem_cli.config import Material

    m = Material(**MATERIAL)
    overlap = DIAMETER - SPACING / 2**0.5
    root = math.sqrt(DIAMETER / 4 * overlap)
    return (
        2.0 * effective_modulus(m, m) * root,
        8.0 * effective_shear_modulus(m, m) * root,
        DIAMETER / 2 - overlap / 2,
    )


def test_fcc_with_central_springs_has_the_analytic_top_frequency():
    """fcc, nearest-neighbour central springs k, mass m: the dynamical matrix is
    D(q) = k/m Σ_δ (1 - cos q·δ) n̂n̂ᵀ over the 12 neighbours δ = a/2 (±1, ±1, 0) and
    permutations. At the zone-boundary point X, q = 2π/a (1, 0, 0), the 8 neighbours with
    δ_x ≠ 0 have cos q·δ = -1 and Σ n̂n̂ᵀ over them = diag(4, 2, 2), so D = k/m diag(8, 4, 4);
    at L, q = π/a (1, 1, 1), D = 2k/m [[2,1,1],[1,2,1],[1,1,2]], also 8k/m at most: ω_max²
    = 8 k/m, Δt_crit = 2/ω_max = √(m/(2k)). A periodic lattice of any number of cells
    holds the X point."""
    limit, state, _ = limit_of(lattice(3, {"model": "hertz"}))
    kn, _, _ = hertz_stiffnesses()
    mass = state.particles.mass[0]
    assert len(limit.contacts) == 12 * 108 // 2
    assert limit.omega_max**2 == pytest.approx(8.0 * kn / mass, rel=1e-9)
    assert limit.dt == pytest.approx(math.sqrt(mass / (2.0 * kn)), rel=1e-9)
    assert limit.mode.rotation < 1e-12  # central springs do not turn the spheres
    assert limit.mode.participation == pytest.approx(108, rel=1e-6)  # a lattice wave


def test_fcc_with_shear_springs_spins_fastest_all_one_way():
    """With shear springs the fastest mode is every sphere spinning the same way (q = 0):
    then Δ = -2l θ × n at every contact, and with Σ (1 - (θ̂·n̂)²) = 12 - 4 = 8 over a
    sphere's 12 neighbours (Σ n̂n̂ᵀ = 4 I) the energy per sphere is 8 k_s l² θ² against a
    kinetic ½ I θ̇²: ω² = 16 k_s l² / I, 4.4 times the central 8 k_n/m here."""
    limit, state, _ = limit_of(
        lattice(3, {"model": "hertz", "tangential": "mindlin", "friction": 0.5})
    )
    kn, ks, arm = hertz_stiffnesses()
    inertia, mass = state.particles.inertia[0], state.particles.mass[0]
    assert 16.0 * ks * arm**2 / inertia > 8.0 * kn / mass
    assert limit.omega_max**2 == pytest.approx(16.0 * ks * arm**2 / inertia, rel=1e-9)
    assert limit.mode.rotation == pytest.approx(1.0, abs=1e-9)


def two_spheres(radii: tuple[float, float], overlap: float, contact: dict) -> dict:
    reach = radii[0] + radii[1] - overlap
    return {
        "name": "pair",
        "materials": {"m": MATERIAL},
        "contact": contact,
        "particles": [
            {"position": [0.0, 0.0, 0.0], "radius": radii[0], "material": "m"},
            {"position": [reach, 0.0, 0.0], "radius": radii[1], "material": "m"},
        ],
        "integrator": {"dt": 1.0e-6},
        "stages": [{"name": "run", "steps": 10}],
    }


def test_one_contact_is_its_two_body_limit():
    """One contact alone: normal ω² = k_n (1/m₁ + 1/m₂) (Peng 2020 Eq 49) and shear ω² =
    k_s (1/m₁ + l₁²/I₁ + 1/m₂ + l₂²/I₂) (Eq 26); the assembly's limit is the smaller
    direction's, and equals `single_contact_limits`."""
    contact = {"model": "linear", "kn": 1.0e5, "tangential": "linear", "ks": 4.0e4, "friction": 0.5}
    limit, state, model = limit_of(two_spheres((0.005, 0.003), 1e-5, contact))
    p = state.particles
    arms = np.array([0.005, 0.003]) - 0.5e-5
    normal = 1.0e5 * p.inv_mass.sum()
    shear = 4.0e4 * (p.inv_mass + arms**2 * p.inv_inertia).sum()
    assert limit.omega_max**2 == pytest.approx(max(normal, shear), rel=1e-9)
    single = packing.single_contact_limits(packing.contacts_of(state, model), state)
    assert single["normal"] == pytest.approx(2.0 / math.sqrt(normal), rel=1e-12)
    assert single["shear"] == pytest.approx(2.0 / math.sqrt(shear), rel=1e-12)
    assert limit.dt == pytest.approx(min(single.values()), rel=1e-9)


def test_a_sphere_on_a_wall_is_a_spring_on_a_fixed_body():
    """A wall does not move: a sphere pressed on a plane has ω² = k_n / m."""
    data = two_spheres((0.005, 0.005), 0.0, {"model": "linear", "kn": 1.0e5})
    data["particles"] = data["particles"][:1]
    data["particles"][0]["position"] = [0.0, 0.0, 0.005 - 2e-5]
    data["walls"] = [
        {"name": "floor", "type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 0, 1]}
    ]
    limit, state, _ = limit_of(data)
    assert (len(limit.contacts), limit.contacts.walls) == (1, 1)
    assert limit.omega_max**2 == pytest.approx(1.0e5 / state.particles.mass[0], rel=1e-12)


def test_the_stiffness_is_symmetric_and_free_under_rigid_translation():
    """K is a Hessian, so symmetric; a periodic packing moved as a whole stores nothing
    (each contact's two ends pull equally and oppositely: momentum is conserved)."""
    contact = {"model": "hertz", "tangential": "mindlin", "friction": 0.5}
    data = lattice(3, contact)
    data["lattices"][0] |= {"random_velocity": 0.0}
    scenario = Scenario.model_validate(data)
    state, model = initial_state(scenario), Model.of(scenario)
    state.particles.x[:] += np.random.default_rng(1).uniform(-2e-6, 2e-6, state.particles.x.shape)
    contacts = packing.contacts_of(state, model)
    k = packing.StiffnessOperator(contacts, 108, contacts.kn, contacts.ks, contacts.kr)
    x, y = np.random.default_rng(2).standard_normal((2, 108, 6))
    assert (x * k(y)).sum() == pytest.approx((y * k(x)).sum(), rel=1e-12)
    assert (x * k(x)).sum() > 0.0
    translation = np.zeros((108, 6))
    translation[:, :3] = [1.0, -2.0, 0.5]
    scale = np.abs(k(x)).max()
    assert np.abs(k(translation)).max() < 1e-12 * scale


@pytest.mark.parametrize(
    "contact", [{"model": "hertz"}, {"model": "hertz", "tangential": "mindlin", "friction": 0.5}]
)
def test_the_stepping_loop_goes_unstable_at_the_eigenvalue_limit(contact):
    """The engine's bracket (a mode perturbation grown 1000 times in 400 steps, or not)
    holds the assembly's limit to 0.1 % (the compressive prestress, left out of K, softens
    the lattice by f_n/(k_n d) ≈ 7e-4)."""
    limit, state, model = limit_of(lattice(3, contact))
    check = packing.engine_bracket(state, model, limit)
    assert check.stable < check.unstable < check.stable * (1.0 + 2e-4)
    assert check.dt / limit.dt == pytest.approx(1.0, abs=1e-3)


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def fcc_restart(tmp_path_factory):
    out = tmp_path_factory.mktemp("fcc")
    scenario = Scenario.model_validate(lattice(3, {"model": "hertz"}))
    run_scenario(scenario, "", ".toml", out, reverse=False)
    return out / "fcc.restart.h5"


def test_dt_restart_reports_the_assembly_beside_the_single_contact_estimates(fcc_restart):
    result = invoke("dt", "--restart", fcc_restart, "--verify", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    dt = report["assembly"]["dt"]
    estimates = report["estimates"]
    # a sphere of the lattice has 12 contacts: one alone has ω² = 2k/m, the lattice 8k/m
    assert estimates["single_contact_normal"]["ratio"] == pytest.approx(2.0, rel=1e-9)
    assert estimates["in_use"]["dt"] == 1.0e-5
    assert estimates["head_on"]["dt"] is None  # at rest: no impact, no Hertz stiffness
    assert estimates["guard"]["dt"] == estimates["rayleigh"]["dt"]
    engine = report["engine_integrated"]
    assert engine["stable"] < dt * 1.001 < engine["unstable"] * 1.001
    # at rest in a stable equilibrium, copies a kick apart part at most 1/√(1 - (ωΔt/4)²)
    # times at half the step, 1.14 at the first trial's 0.97 of the limit
    assert engine["measured"] and engine["divergence"] < 1.15
    assert engine["ratio"] == pytest.approx(1.0, abs=1e-2)
    # the mode's spheres by their ids, as every output names them, not by array index
    from revdem_cli.io.restart import read_restart

    ids = read_restart(fcc_restart).state.ids
    spheres = report["assembly"]["mode"]["spheres"]
    assert [s["id"] for s in spheres] == [int(ids[s["index"]]) for s in spheres]
    shown = " ".join(invoke("dt", "--restart", fcc_restart).output.split())
    assert f"largest shares: id {spheres[0]['id']} ({spheres[0]['share']:.2%}" in shown


def test_each_estimate_without_a_limit_says_why(fcc_restart):
    """An estimate with no limit (∞ in the table) had its dt and ratio null in the JSON, and
    nothing said why: the reader could not tell it from one that failed. Each such estimate
    now has `reason` beside its nulls, as the two-particle JSON has; an estimate with a
    limit has none, and the fields read before are as they were."""
    result = invoke("dt", "--restart", fcc_restart, "--json")
    assert result.exit_code == 0, result.output
    estimates = json.loads(result.stdout)["estimates"]
    for estimate in estimates.values():
        assert ("reason" in estimate) == (estimate["dt"] is None) == (estimate["ratio"] is None)
        assert set(estimate) - {"reason"} == {"label", "dt", "ratio"}
    alone = "no limit: no contact of this state has a {} stiffness ({} = 0 in each)"
    reasons = {key: estimate.get("reason") for key, estimate in estimates.items()}
    assert reasons == {  # a Hertz lattice at rest, frictionless, without rolling springs
        "single_contact_normal": None,
        "single_contact_shear": alone.format("shear", "k_s"),
        "single_contact_rolling": alone.format("rolling", "k_r"),
        "head_on": "no limit: no kind of contact the scenario forms has a stiffness at the "
        "overlap of a head-on impact at its approach speed (at most 0 m/s; a Hertz contact at "
        "zero overlap has none)",
        "rayleigh": None,
        "guard": None,
        "in_use": None,
    }


def test_the_table_says_why_an_estimate_has_no_limit(fcc_restart):
    """The table showed ∞ for an estimate without a limit and nothing more; a line under it
    now gives each such estimate's reason, as the JSON does, and none for one with a
    limit."""
    result = invoke("dt", "--restart", fcc_restart)
    assert result.exit_code == 0, result.output
    said = " ".join(result.stdout.split())
    alone = "no limit: no contact of this state has a {} stiffness ({} = 0 in each)"
    assert f"• single_contact_shear: {alone.format('shear', 'k_s')}" in said
    assert f"• single_contact_rolling: {alone.format('rolling', 'k_r')}" in said
    assert "• head_on: no limit: no kind of contact the scenario forms" in said
    assert "• single_contact_normal:" not in said


def test_dt_restart_tells_what_it_is_doing_as_it_goes(fcc_restart):
    """Minutes on a large packing: the Lanczos products so far, then each trial of the
    engine's bracket, in order."""
    said = []
    report = packing.assess_restart(fcc_restart, True, said.append)
    lanczos = [s for s in said if "(Lanczos)" in s]
    trials = [s for s in said if s.startswith("the engine's limit: trial")]
    motion = "the packing's own motion: 1600 steps of 108 spheres at Δt/2"
    assert lanczos and said == lanczos + [motion] + trials
    counts = [int(s.split(": ")[1].split()[0]) for s in lanczos]
    assert counts == list(range(10, 10 * len(counts) + 1, 10))
    assert [int(s.split()[4]) for s in trials] == list(range(1, len(trials) + 1))
    assert len(trials) == report["engine_integrated"]["trials"]
    assert all("800 steps of 108 spheres" in s for s in trials)


def test_dt_restart_prints_a_table(fcc_restart):
    result = invoke("dt", "--restart", fcc_restart)
    assert result.exit_code == 0, result.output
    assert "assembly" in result.output and "fastest mode" in result.output


def test_a_packing_that_still_moves_is_not_bracketed(tmp_path):
    """40 glass spheres poured into a steel box, the restart taken while some still fall:
    two copies of that state, a kick along the top mode apart, part millions of times in a
    few ms at any step (collisions), so growth of the kick says nothing of the integrator.
    Bisected as if at rest, it gave 0.607 of the assembly's limit (and 0.671 for 200 spheres
    pressed by a lid), the motion's parting, not the step's; it is reported not measured."""
    from revdem_cli.timestep.packing import PARTED

    steel = {"density": 7800.0, "shear_modulus": 7.9e10, "poisson_ratio": 0.3}
    sides = [([0, 0, 0], [0, 0, 1]), ([0.006, 0, 0], [-1, 0, 0]), ([0, 0, 0], [1, 0, 0])]
    sides += [([0, 0.006, 0], [0, -1, 0]), ([0, 0, 0], [0, 1, 0])]
    data = {
        "name": "box",
        "gravity": [0.0, 0.0, -9.81],
        "materials": {
            "glass": {"density": 2500.0, "shear_modulus": 2.6e10, "poisson_ratio": 0.22},
            "steel": steel,
        },
        "contact": {"model": "hertz", "tangential": "mindlin", "friction": 0.5},
        "packings": [
            {
                "count": 40,
                "material": "glass",
                "radius_min": 0.0009,
                "radius_max": 0.0011,
                "seed": 3,
                "region": {"shape": "box", "origin": [0, 0, 0], "size": [0.006, 0.006, 0.02]},
            }
        ],
        "walls": [
            {"name": f"w{k}", "type": "plane", "material": "steel", "point": p, "normal": n}
            for k, (p, n) in enumerate(sides)
        ],
        "integrator": {"dt": 5.0e-7},
        "stages": [{"name": "pour", "steps": 150000, "output_every": 150000}],
    }
    run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path, reverse=False)
    restart = tmp_path / "box.restart.h5"
    result = invoke("dt", "--restart", restart, "--verify", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    engine = report["engine_integrated"]
    assert report["assembly"]["contacts"] > 0
    assert not engine["measured"] and engine["divergence"] > 1e3 * PARTED
    assert "dt" not in engine and "ratio" not in engine and engine["trials"] == 0
    assert engine["reason"].startswith("the engine's limit was not measured: two copies")
    shown = " ".join(invoke("dt", "--restart", restart, "--verify").output.split())
    assert "the engine's limit was not measured: two copies of this state" in shown
    assert "Let the stage come to rest (stop_when.kinetic_energy_below)" in shown


def test_a_collision_caught_mid_contact_is_not_bracketed(tmp_path):
    """The two spheres of configs/collision.toml stopped in contact: set at rest they spring
    apart, so no step grows a kick along the top mode and the bracket finds no limit in its
    moves; that is reported not measured, with the steps tried, and the assembly's limit
    kept (it raised "no stability limit ... within 0.3 to 3 times", losing the table)."""
    from tests.conftest import CONFIGS

    run = ["run", CONFIGS / "collision.toml", "--set", "stages.0.steps=7000", "--no-reverse"]
    ran = invoke(*run, "--out", tmp_path, "-q")
    assert ran.exit_code == 0, ran.output
    restart = tmp_path / "collision.restart.h5"
    result = invoke("dt", "--restart", restart, "--verify", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    engine = report["engine_integrated"]
    assert report["assembly"]["contacts"] == 1 and report["assembly"]["dt"] > 0.0
    assert not engine["measured"] and engine["divergence"] <= packing.PARTED
    # two trials at the start, then one a move: the bracket's other end is one already tried
    # (each move tried both ends again, 2 * (MOVES + 1) trials)
    assert "dt" not in engine and engine["trials"] == packing.MOVES + 2
    # the trials start at 0.97 of the limit and move up 1.1 times a move
    reach = 1.03 * 1.1**packing.MOVES
    assert engine["reason"].startswith(
        f"the engine's limit was not measured: trial steps from "
        f"{0.97 * report['assembly']['damped_dt']:.3g} to "
    )
    assert f"(0.97 to {reach:.3g} times the assembly's limit)" in engine["reason"]
    shown = " ".join(invoke("dt", "--restart", restart, "--verify").output.split())
    assert "engine_integrated │ not measured (below)" in shown
    assert "the engine's limit was not measured: trial steps from" in shown


def test_a_mode_on_one_sphere_is_carried_by_1_sphere_in_the_table(tmp_path):
    """A sphere pressed into the floor: its one contact's mode lives on it alone ("carried by
    about 1 spheres", once)."""
    from tests.conftest import FLOOR, PLANE, SPHERE

    data = {
        "name": "rest",
        "materials": {"sphere": SPHERE, "plane": PLANE},
        "contact": {"model": "hertz"},
        "particles": [{"material": "sphere", "radius": 0.005, "position": [0, 0, 0.00499]}],
        "walls": [FLOOR],
        "integrator": {"dt": 1.0e-7},
        "stages": [{"name": "rest", "steps": 10, "output_every": 10}],
    }
    run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path, reverse=False)
    result = invoke("dt", "--restart", tmp_path / "rest.restart.h5")
    assert result.exit_code == 0, result.output
    assert "carried by about 1 sphere, " in " ".join(result.output.split())


def test_dt_restart_takes_no_particle_options(fcc_restart):
    result = invoke("dt", "--restart", fcc_restart, "--shape", "sphere")
    assert result.exit_code == 2
    assert "--restart takes the particles from the file; leave out --shape" in result.output


@pytest.mark.parametrize(
    "extra, named",
    [
        (["--damping", 0], "--damping"),  # its default, given: still refused
        (["--trvp-order", 2], "--trvp-order"),
        (["--omega-max", 10], "--omega-max"),
        (["--out", "x.csv", "--force"], "--out, --force"),
        (["--kn", 1e6, "--ks", 0, "--damping", 1], "--kn, --ks, --damping"),
    ],
)
def test_dt_restart_refuses_every_option_it_does_not_use(fcc_restart, extra, named):
    """Options that change nothing of a packing's assessment gave exit 0 and the same
    table, leaving their user believing they counted."""
    from tests.conftest import assert_one_line_error

    result = invoke("dt", "--restart", fcc_restart, "--verify", "--json", *extra)
    assert_one_line_error(
        result,
        f"--restart takes the particles from the file; leave out {named} (beside it only "
        "--verify and --json count)",
    )


def test_auto_dt_is_the_safety_fraction_of_the_packing_limit(tmp_path):
    """A linear lattice: the start-up estimate (one contact, √(2m/k)) is twice the
    lattice's √(m/(2k)), so 'auto' takes dt_safety of the lattice's."""
    kn = 1.0e4
    contact = {"model": "linear", "kn": kn}
    data = lattice(3, contact, integrator={"dt": "auto", "dt_safety": 0.3})
    scenario = Scenario.model_validate(data)
    run_scenario(scenario, "", ".toml", tmp_path, reverse=False)
    restart = read_restart(tmp_path / "fcc.restart.h5")
    mass = restart.state.particles.mass[0]
    assert critical_time_step(scenario)[0] == pytest.approx(math.sqrt(2.0 * mass / kn))
    assert restart.stage_dt == pytest.approx(0.3 * math.sqrt(mass / (2.0 * kn)), rel=1e-9)


def test_auto_dt_in_fixed_point_is_refused():
    data = lattice(3, {"model": "hertz"}, integrator={"dt": "auto", "arithmetic": "fixed"})
    with pytest.raises(ValueError, match=r"integrator.dt: 'auto' needs integrator.arithmetic"):
        Scenario.model_validate(data)


def test_a_time_step_that_is_neither_a_number_nor_auto_is_refused():
    with pytest.raises(
        ValueError, match="a valid number of seconds or 'auto', not the text 'fast'"
    ):
        Scenario.model_validate(lattice(3, {"model": "hertz"}, integrator={"dt": "fast"}))


def test_auto_dt_takes_the_viscous_damping_of_its_own_stage(tmp_path):
    """The linear lattice, then a stage with its own viscous normal damping beta = 0.2: C is
    then 2 beta sqrt(m*/k) K, so the top mode (omega = sqrt(8 k / m), m* = m / 2) is damped at
    zeta = 2 beta, and its velocity-Verlet limit shrinks by sqrt(1 + zeta^2) - zeta (Peng 2020
    Eq 30)."""
    data = lattice(3, {"model": "linear", "kn": 1.0e4}, integrator={"dt": "auto"})
    data["stages"] = [
        {"name": "plain", "steps": 10},
        {"name": "damped", "steps": 10, "contact": {"normal_damping": 0.2}},
    ]
    chosen = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path).chosen_dt
    zeta = 2 * 0.2
    assert chosen["damped"] / chosen["plain"] == pytest.approx(
        math.sqrt(1 + zeta**2) - zeta, rel=1e-9
    )


def test_the_damped_limit_of_a_run_with_the_velocity_predictor_is_the_predictors():
    """The linear lattice with viscous normal damping 0.2, stepped with the velocity predictor
    of order 2 (`integrator.scheme = "trvp"`), whose damping reads predicted velocities: its
    top mode is stable to 0.58 of velocity Verlet's damped limit (Peng 2020 Eq 30 with the
    predictor, `criteria.dt_velocity_predictor`). The packing's limit (`revdem dt --restart`,
    dt = "auto") took velocity Verlet's whatever the scheme; the engine's bracket, which
    steps the scheme, went unstable at 0.60 of it. Both now agree to 2 %."""
    from revdem_cli.timestep.criteria import dt_velocity_predictor, dt_velocity_verlet

    contact = {"model": "linear", "kn": 1.0e4, "normal_damping": 0.2}
    data = lattice(3, contact, integrator={"dt": 1e-5, "scheme": "trvp", "trvp_order": 2})
    limit, state, model = limit_of(data)
    lam, c = limit.omega_max**2, limit.mode_damping
    assert limit.damped_dt == dt_velocity_predictor(lam, c, 1.0, 2)
    assert limit.damped_dt / dt_velocity_verlet(lam, c, 1.0) == pytest.approx(0.584, abs=0.005)
    check = packing.engine_bracket(state, model, limit)
    assert 1.0 <= check.dt / limit.damped_dt < 1.03


def test_dt_restart_says_its_damped_limit_reads_the_velocity_predictor(tmp_path):
    contact = {"model": "linear", "kn": 1.0e4, "normal_damping": 0.2}
    data = lattice(3, contact, integrator={"dt": 1e-5, "scheme": "trvp", "trvp_order": 2})
    outputs = run_scenario(Scenario.model_validate(data), "", ".toml", tmp_path)
    result = invoke("dt", "--restart", str(outputs.restart), "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["predictor_order"] == 2
    shown = CliRunner().invoke(
        app, ["dt", "--restart", str(outputs.restart)], env={"COLUMNS": "300"}
    )
    assert "viscous damping φᵀCφ, read from the velocity predictor of order 2" in shown.output


def test_a_state_without_contacts_and_figures_beside_a_restart_are_refused(tmp_path):
    """Two spheres apart after their collision: no contact, so no stiffness to bound the
    step (the table showed ∞, ratios of nan and 0, and --json wrote Infinity and NaN, which
    JSON lacks); --figures beside --restart drew the paper's figures, ignoring the file."""
    from tests.conftest import CONFIGS, assert_one_line_error

    apart = CliRunner().invoke(
        app, ["run", str(CONFIGS / "collision.toml"), "--out", str(tmp_path), "-q", "--no-reverse"]
    )
    assert apart.exit_code == 0, apart.output
    restart = tmp_path / "collision.restart.h5"
    for extra in ([], ["--json"], ["--verify"]):
        result = CliRunner().invoke(app, ["dt", "--restart", str(restart), *extra])
        assert_one_line_error(result, f"{restart}: no sphere touches another or a wall at step")
    result = CliRunner().invoke(
        app, ["dt", "--restart", str(restart), "--figures", str(tmp_path / "figures")]
    )
    assert_one_line_error(result, "--figures writes Peng 2020's figures, not a packing's")
    assert not (tmp_path / "figures").exists()
