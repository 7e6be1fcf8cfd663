"""contact.wall_moduli: a sphere on a wall feels Hertz with both materials combined, or with
the wall's material alone (LAMMPS fix wall/gran, the walls of Hanley 2020's runs); a sphere
pair, with its own two materials combined."""

import math

import h5py
import numpy as np
import pytest

from revdem_cli.config import Scenario
from revdem_cli.engine import run_scenario
from revdem_cli.state import initial_state, moduli
from tests.conftest import FLOOR, PLANE, SPHERE

R, G = 0.005, 9.81
WEIGHT = 4 / 3 * math.pi * R**3 * SPHERE["density"] * G


def hertz(g: float, nu: float) -> float:
    """H of a sphere on a plane, both of shear modulus g and Poisson's ratio nu: Hanley 2020
    Eq 6 with r_b -> infinity, H = 4G/(3(1 - nu)) sqrt(r_a)."""
    return 4 * g / (3 * (1 - nu)) * math.sqrt(R)


def compliance(a: dict, b: dict) -> float:
    """1/E* by Hertz's combination, (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b with E = 2G(1 + nu)."""
    return sum((1 - m["poisson_ratio"]) / (2 * m["shear_modulus"]) for m in (a, b))


def combined() -> float:
    """H of a sphere on the plane from both materials combined (`compliance`)."""
    return 4 / 3 / compliance(SPHERE, PLANE) * math.sqrt(R)


RULES = {"combined": combined(), "wall": hertz(PLANE["shear_modulus"], PLANE["poisson_ratio"])}


def resting(rule: str, overlap: float) -> Scenario:
    """A frictionless sphere on the plane z = 0 with a given overlap, under gravity."""
    return Scenario.model_validate(
        {
            "name": "rest",
            "materials": {"sphere": SPHERE, "plane": PLANE},
            "contact": {"model": "hertz", "wall_moduli": rule},
            "particles": [{"material": "sphere", "radius": R, "position": (0, 0, R - overlap)}],
            "walls": [FLOOR],
            "gravity": (0.0, 0.0, -G),
            "integrator": {"dt": 1e-6},
            "stages": [{"name": "rest", "steps": 2000, "output_every": 100}],
        }
    )


def test_the_wall_rule_gives_a_wall_contact_the_walls_material_alone():
    table = moduli(resting("wall", 0.0))
    sphere, plane = 0, 1
    assert 4 / 3 * table.estar[sphere, plane] * math.sqrt(R) == pytest.approx(RULES["wall"])
    assert table.estar[sphere, plane] == table.estar[plane, sphere]
    # Mindlin with the wall's material: 8 G* = 4G/(2 - nu) (Hanley 2020 Eq 10)
    assert 8 * table.gstar[sphere, plane] == pytest.approx(4 * 1e9 / (2 - 0.2))
    # a sphere pair is untouched: G/(1 - nu) of the sphere (Hanley 2020 Eq 6)
    assert table.estar[sphere, sphere] == pytest.approx(2e6 / 0.8)
    assert 4 / 3 * moduli(resting("combined", 0.0)).estar[0, 1] * math.sqrt(R) == pytest.approx(
        RULES["combined"]
    )


@pytest.mark.parametrize("rule", RULES)
def test_a_sphere_rests_on_the_plane_at_its_rules_hertz_overlap(tmp_path, rule):
    """At the overlap where H d^1.5 = m g the sphere stays at rest and the plane carries its
    weight; the other rule's overlap (40 times larger or smaller) sets it bouncing."""
    overlaps = {name: (WEIGHT / h) ** (2 / 3) for name, h in RULES.items()}
    assert max(overlaps.values()) > 30 * min(overlaps.values())
    speeds = {}
    for placed, overlap in overlaps.items():
        outputs = run_scenario(
            resting(rule, overlap), "", ".toml", tmp_path / placed, reverse=False
        )
        with h5py.File(outputs.forward) as f:
            force = f["observables/wall_force/plane/value"][:, 2]
            speeds[placed] = np.abs(f["particles/all/velocity/value"][:, 0, 2]).max()
        if placed == rule:
            np.testing.assert_allclose(-force, WEIGHT, rtol=1e-6)
    other = next(name for name in RULES if name != rule)
    assert speeds[rule] < 1e-6 * speeds[other]


ELASTIC = {"soft": SPHERE, "stiff": PLANE}


def in_a_row(names: list[str], overlap: float, tangential: str) -> Scenario:
    """Spheres of radius R along x, each overlapping the next by `overlap`, of the materials
    `names` (SPHERE's and PLANE's elastic constants; the materials it has only), without
    gravity."""
    return Scenario.model_validate(
        {
            "name": "row",
            "materials": {name: ELASTIC[name] for name in dict.fromkeys(names)},
            "contact": {"model": "hertz", "tangential": tangential}
            | ({"friction": 0.5} if tangential != "none" else {}),
            "particles": [
                {"material": name, "radius": R, "position": (k * (2 * R - overlap), 0, 0)}
                for k, name in enumerate(names)
            ],
            "integrator": {"dt": 1e-7},
            "stages": [{"name": "rest", "steps": 1, "output_every": 1}],
        }
    )


@pytest.mark.parametrize("tangential", ["none", "mindlin"])
@pytest.mark.parametrize("names", [["soft", "stiff", "stiff", "soft"], ["soft"] * 4, ["stiff"] * 4])
def test_each_sphere_pair_is_pushed_apart_by_hertz_with_its_own_two_materials(names, tangential):
    """The pair loop's E* is each pair's own (one material's in every column where there is
    one, `pairs.one_material`; else looked up pair by pair): sphere k feels its neighbours'
    pushes, Hanley 2020 Eq 6 with E* of the two materials, R* = R / 2."""
    overlap = 1e-5
    state = initial_state(in_a_row(names, overlap, tangential))

    def push(a: str, b: str) -> float:
        return 4 / 3 / compliance(ELASTIC[a], ELASTIC[b]) * math.sqrt(R / 2) * overlap**1.5

    pushes = [push(a, b) for a, b in zip(names[:-1], names[1:], strict=True)]
    expected = (
        [-pushes[0]] + [l - r for l, r in zip(pushes[:-1], pushes[1:], strict=True)] + [pushes[-1]]
    )
    assert state.particles.f[:, 0] == pytest.approx(expected, rel=1e-9, abs=1e-12 * max(pushes))
    assert np.all(state.particles.f[:, 1:] == 0.0)
