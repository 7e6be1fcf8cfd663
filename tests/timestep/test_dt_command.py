"""`revdem dt` as a user meets it: the table, JSON, sweeps, and one-line errors."""

from __future__ import annotations

import csv
import io
import json
import math

import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import assert_one_line_error

runner = CliRunner()
ELLIPSOID_SIZE = ("--shape", "ellipsoid", "--semi-axes", 3, 2, 1)
ELLIPSOID = (*ELLIPSOID_SIZE, "--density", 1000, "--kn", 1e10)
SPHERE = ("--shape", "sphere", "--radius", 0.01, "--density", 2500)
SUPERQUADRIC = ("--shape", "superquadric", "--semi-axes")
CUBE = "\n".join(f"{x} {y} {z}" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1))


def invoke(*args):
    return runner.invoke(app, ["dt", *(str(a) for a in args)])


def as_json(*args) -> dict:
    result = invoke(*args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_ellipsoid_example_prints_mass_a_max_and_time_step(paper):
    result = invoke(*ELLIPSOID)
    assert result.exit_code == 0, result.output
    case = paper["ellipsoid_pair"]
    assert f"{case['mass_over_pi'] * math.pi:.6g}" in result.output
    assert f"= {case['a_max_times_mass']:.4g} / m₁" in result.output
    assert f"{case['dt_undamped']:.3e}"[:4] in result.output
    dt = as_json(*ELLIPSOID)["recommended_dt"]
    assert f"{dt:.4e}" in result.output


def test_ellipsoid_example_as_json(paper):
    case = paper["ellipsoid_pair"]
    data = as_json(*ELLIPSOID)
    mass = data["particles"][0]["mass"]
    assert mass == pytest.approx(case["mass_over_pi"] * math.pi)
    assert data["a_max"] * mass == pytest.approx(case["a_max_times_mass"])
    for key in ("amplification", "belytschko", "velocity_verlet"):
        assert data["criteria"][key]["dt"] == pytest.approx(
            case["dt_undamped"], rel=case["dt_rtol"]
        )
    assert data["recommended_dt"] == pytest.approx(case["dt_undamped"], rel=case["dt_rtol"])
    [finding] = data["findings"]
    assert finding.startswith("Peng 2020 Eq 36") and finding.endswith("unsafe.")


def test_damped_verification_recommends_the_integrated_limit():
    data = as_json(*ELLIPSOID, "--damping", 2, "--verify")
    integrated = data["checks"]["velocity_verlet_integrated"]["dt"]
    formula = data["criteria"]["velocity_verlet"]["dt"]
    assert integrated == pytest.approx(formula, rel=1e-3)
    assert data["recommended_dt"] == min(integrated, formula)
    assert data["criteria"]["amplification"]["dt"] > 5.0 * integrated
    assert data["checks"]["eq40_real_eigenvalue"]["dt"] == pytest.approx(
        data["criteria"]["amplification"]["dt"], rel=1e-5
    )
    assert any(f.startswith("Peng 2020 Eq 46") and f.endswith("unsafe.") for f in data["findings"])
    rigid = {k: v["dt"] for k, v in data["checks"].items() if k.startswith("rigid_body_")}
    rows = [f"rigid_body_{name}_integrated" for name in ("A", "B", "C", "tips", "random")]
    assert sorted(rigid) == sorted([*rows, "rigid_body_integrated"])
    assert rigid["rigid_body_integrated"] == min(rigid[row] for row in rows)
    assert formula < rigid["rigid_body_integrated"] < data["criteria"]["amplification"]["dt"]
    assert any(f.startswith("Peng 2020 Eq 46") and "unsafe for them" in f for f in data["findings"])


def test_sphere_pair_recommends_eq49(paper):
    data = as_json("--shape", "sphere", "--radius", 0.01, "--density", 2500, "--kn", 1e6)
    mass = data["particles"][0]["mass"]
    expected = paper["sphere"]["eq49_alpha"] * math.sqrt(mass / 1e6)
    assert data["recommended_dt"] == pytest.approx(expected)


def test_frictionless_spheres_are_bounded_by_the_normal_spring_alone():
    """--ks 0 (frictionless): no shear direction. Two spheres' normal force has no moment,
    A_n = 1/m + 1/m (Peng 2020 Eq 26 with r × n = 0): the formulas, the engine and the rigid
    pair integrated all give 2 / sqrt(kn A_n) = sqrt(2) sqrt(m / kn), not Peng's 7/m bound,
    sqrt(3.5) below. With shear springs the shear direction, A_max = 7/m, sets every limit.
    Non-spherical bodies keep A_max in the normal direction too."""
    args = ("--shape", "sphere", "--radius", 0.01, "--density", 1000, "--kn", 1e6, "--verify")
    data = as_json(*args, "--ks", 0)
    mass = data["particles"][0]["mass"]
    assert data["a_normal"] == pytest.approx(2.0 / mass, rel=1e-12)
    two_body = 2.0 / math.sqrt(1e6 * 2.0 / mass)
    assert data["criteria"]["velocity_verlet"]["dt"] == pytest.approx(two_body, rel=1e-12)
    assert data["checks"]["engine_integrated"]["dt"] == pytest.approx(two_body, rel=1e-3)
    assert data["checks"]["rigid_body_integrated"]["dt"] == pytest.approx(two_body, rel=1e-3)
    assert data["recommended_dt"] == pytest.approx(two_body, rel=1e-3)
    sticking = as_json(*args)  # with shear springs: the shear direction's 7/m
    formula = sticking["criteria"]["velocity_verlet"]["dt"]
    assert formula == pytest.approx(2.0 / math.sqrt(1e6 * 7.0 / mass), rel=1e-12)
    assert sticking["checks"]["engine_integrated"]["dt"] == pytest.approx(formula, rel=1e-3)
    ellipsoid = as_json(*ELLIPSOID, "--ks", 0)
    assert ellipsoid["a_normal"] == ellipsoid["a_max"]
    undamped = 2.0 / math.sqrt(1e10 * ellipsoid["a_max"])
    assert ellipsoid["recommended_dt"] == pytest.approx(undamped, rel=1e-12)


def test_superquadric_with_unit_exponents_gives_the_ellipsoid_numbers():
    ellipsoid = as_json(*ELLIPSOID)
    quadric = as_json("--shape", "superquadric", *ELLIPSOID[2:], "--exponents", 1, 1)
    assert quadric["a_max"] == pytest.approx(ellipsoid["a_max"], rel=1e-12)
    assert quadric["recommended_dt"] == pytest.approx(ellipsoid["recommended_dt"], rel=1e-12)


def test_cube_polyhedron_matches_the_superquadric_box(tmp_path):
    vertices = tmp_path / "cube.txt"
    vertices.write_text(CUBE)
    common = ("--density", 1000, "--kn", 1e8)
    cube = as_json("--shape", "polyhedron", "--vertices", vertices, *common)
    box = as_json(
        "--shape", "superquadric", "--semi-axes", 1, 1, 1, "--exponents", 1e-4, 1e-4, *common
    )
    assert cube["particles"][0]["moments"] == pytest.approx(
        box["particles"][0]["moments"], rel=1e-3
    )
    assert cube["recommended_dt"] == pytest.approx(box["recommended_dt"], rel=1e-3)


def test_other_particle_takes_what_it_is_not_given():
    data = as_json(*ELLIPSOID, "--other-shape", "sphere", "--other-radius", 1, "--omega-max", 1)
    ellipsoid, sphere = data["particles"]
    assert sphere["shape"] == "sphere"
    assert sphere["mass"] == pytest.approx(1000 * 4 / 3 * math.pi)
    expected = 9 / ellipsoid["moments"][0] + 1 / ellipsoid["mass"] + 1 / sphere["moments"][0]
    assert data["a_max"] == pytest.approx(expected + 1 / sphere["mass"])
    # B_max of the ellipsoid is 0.8 and of the sphere 0 (Eq 54): Δt = 2 / (1 × 0.8) (Eq 56)
    assert data["criteria"]["rotation"]["dt"] == pytest.approx(2.5)


def test_rotation_limit_of_a_sphere_pair_is_absent_not_infinite():
    data = as_json(
        "--shape", "sphere", "--radius", 1, "--density", 1000, "--kn", 1e8, "--omega-max", 5
    )
    assert data["criteria"]["rotation"]["dt"] is None
    assert data["recommended_dt"] == data["criteria"]["velocity_verlet"]["dt"]


def test_stiffness_sweep_writes_csv(tmp_path):
    out = tmp_path / "sweep.csv"
    result = invoke(*ELLIPSOID[:-2], "--damping", 1, "--sweep", "kn=1e10:1e11:4", "--out", out)
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(out.open()))
    assert [float(r["kn"]) for r in rows] == pytest.approx([1e10, 4e10, 7e10, 1e11])
    steps = [float(r["recommended_dt"]) for r in rows]
    assert steps == pytest.approx([steps[0] / math.sqrt(float(r["kn"]) / 1e10) for r in rows])


def test_density_sweep_goes_to_stdout():
    result = invoke(*ELLIPSOID_SIZE, "--kn", 1e10, "--sweep", "density=500:2000:3")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO(result.output)))
    masses_ratio = [float(r["density"]) / 500 for r in rows]
    steps = [float(r["dt_amplification"]) for r in rows]
    assert steps == pytest.approx([steps[0] * math.sqrt(q) for q in masses_ratio])


def test_shear_stiffness_sweep_starts_at_frictionless():
    """--ks 0 is a frictionless contact; a sweep from it was refused as "must be a positive
    number, got 0"."""
    result = invoke(*ELLIPSOID, "--sweep", "ks=0:1e10:3")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO(result.output)))
    assert [float(r["ks"]) for r in rows] == [0.0, 5e9, 1e10]
    frictionless = as_json(*ELLIPSOID, "--ks", 0)["recommended_dt"]
    assert float(rows[0]["recommended_dt"]) == pytest.approx(frictionless, rel=1e-12)


@pytest.mark.parametrize(
    "args, fragments",
    [
        (("--shape", "cube", "--density", 1, "--kn", 1), ["--shape", "'cube'"]),
        (("--density", 1, "--kn", 1), ["--shape", "is required"]),
        (("--shape", "ellipsoid", "--density", 1, "--kn", 1), ["--semi-axes", "required"]),
        (
            ("--shape", "sphere", "--radius", 1, "--density", -5, "--kn", 1),
            ["--density", "positive"],
        ),
        (("--shape", "sphere", "--radius", 1, "--density", 5), ["--kn", "required"]),
        (
            ("--shape", "ellipsoid", "--semi-axes", 3, 0, 1, "--density", 1, "--kn", 1),
            ["--semi-axes"],
        ),
        (
            ("--shape", "superquadric", *ELLIPSOID[2:], "--exponents", 3, 1),
            ["--exponents", "(0, 2]"],
        ),
        ((*ELLIPSOID, "--other-shape", "sphere"), ["--other-radius", "required"]),
        (
            (*SPHERE, "--kn", 1, "--other-shape", "ellipsoid"),
            ["--other-semi-axes is required for an ellipsoid"],
        ),
        (
            ("--shape", "sphere", "--radius", 1, "--semi-axes", 1, 1, 1, "--density", 1, "--kn", 1),
            ["--semi-axes does not size a sphere; it takes --radius"],
        ),
        (
            (*ELLIPSOID, "--exponents", 1, 1),
            ["--exponents does not size an ellipsoid; it takes --semi-axes"],
        ),
        (
            (*ELLIPSOID, "--other-shape", "sphere", "--other-radius", 1, "--other-vertices", "v"),
            ["--other-vertices does not size a sphere; it takes --other-radius"],
        ),
        (
            (*SUPERQUADRIC, 1, 1, 1, "--exponents", 1e-300, 1, "--density", 1000, "--kn", 1),
            ["--exponents with --density 1000", "give exponents above about 1e-150"],
        ),  # blamed --semi-axes
        (
            (*SUPERQUADRIC, 1e300, 1e300, 1e300, "--exponents", 1, 1, "--density", 1, "--kn", 1),
            ["--semi-axes with --density 1", "give sizes in metres"],
        ),
        ((*ELLIPSOID, "--damping", -1), ["--damping"]),
        ((*ELLIPSOID, "--ks", -1), ["--ks must be zero or positive"]),
        ((*ELLIPSOID, "--omega-max", 0), ["--omega-max"]),
        ((*ELLIPSOID, "--sweep", "mass=1:2:3"), ["--sweep", "one of"]),
        ((*ELLIPSOID, "--sweep", "kn=1:2"), ["--sweep", "START:STOP:COUNT"]),
        ((*ELLIPSOID, "--sweep", "kn=1:0:5"), ["--sweep 'kn=1:0:5': kn must be", "got 0"]),
        ((*ELLIPSOID, "--sweep", "density=-1:1:3"), ["--sweep 'density=-1:1:3': density"]),
        ((*ELLIPSOID, "--sweep", "kn=nan:1:5"), ["--sweep 'kn=nan:1:5': kn", "got nan"]),
        ((*ELLIPSOID, "--sweep", "damping=-1:1:2"), ["--sweep 'damping=-1:1:2': damping"]),
        ((*ELLIPSOID, "--sweep", "ks=-1:1:2"), ["--sweep 'ks=-1:1:2': ks must be zero or"]),
        ((*ELLIPSOID, "--sweep", "kn=1:2:3", "--json"), ["--sweep", "--json"]),
        ((*ELLIPSOID, "--out", "x.csv"), ["--out", "--sweep"]),
        (
            (*ELLIPSOID[:-2], "--sweep", "kn=1:2:2", "--out", "/no/such/dir/x.csv"),
            ["--out", "cannot write"],
        ),
        # options that would be dropped: one the sweep sets, a repeated one, --force alone
        ((*ELLIPSOID, "--sweep", "kn=1e10:1e11:2"), ["--sweep 'kn=1e10:1e11:2' sets --kn"]),
        ((*ELLIPSOID, "--sweep", "damping=0:1:2", "--damping", 1), ["sets --damping"]),
        (
            (*ELLIPSOID_SIZE, "--kn", 1, "--other-density", 1, "--sweep", "density=1:4:2"),
            ["both particles' density", "leave out --other-density"],
        ),
        ((*ELLIPSOID[:-2], "--sweep", "kn=1:2:2", "--sweep", "ks=1:2:2"), ["--sweep is given 2"]),
        ((*ELLIPSOID, "--kn", 2e10), ["--kn is given 2 times"]),
        ((*ELLIPSOID, "--semi-axes", 1, 1, 1), ["--semi-axes is given 2 times"]),
        ((*ELLIPSOID, "--force"), ["--force", "give --out or --figures too"]),
    ],
)
def test_bad_options_exit_2_naming_the_option(args, fragments):
    assert_one_line_error(invoke(*args), *fragments)


@pytest.mark.parametrize(
    "content, fragments",
    [
        (CUBE + "\n0.1 0 0\n-0.1 0 0\n", ["vertex 9", "not convex"]),
        # a regular tetrahedron: named through its centroid, not an edge's midpoint
        (
            "1 1 1\n1 -1 -1\n-1 1 -1\n-1 -1 1\n",
            ["through the centre [0.0, 0.0, 0.0]", "not centrally symmetric"],
        ),
        # a cube with a bump on one face: the bump has no mirror through the cube's centre
        (CUBE + "\n1.5 0 0\n", ["vertex 9 has no mirror", "[0.0, 0.0, 0.0]", "not centrally"]),
        ("1.5 0 0\n" + CUBE, ["vertex 1 has no mirror", "[0.0, 0.0, 0.0]", "not centrally"]),
        ("1 2\n", ["expected three numbers"]),
    ],
)
def test_bad_vertex_files_exit_2_naming_the_file(tmp_path, content, fragments):
    path = tmp_path / "shape.txt"
    path.write_text(content)
    result = invoke("--shape", "polyhedron", "--vertices", path, "--density", 1, "--kn", 1)
    assert_one_line_error(result, str(path), *fragments)


@pytest.mark.parametrize(
    "name, content",
    [("empty.txt", ""), ("comments.txt", "# nothing\n\n"), ("empty.json", "[]"),
     ("empty.json", '{"vertices": []}')],
)  # fmt: skip
def test_a_vertex_file_without_vertices_exits_2_naming_it(tmp_path, name, content):
    """Once a ValueError traceback from Qhull: "No points given"."""
    path = tmp_path / name
    path.write_text(content)
    result = invoke("--shape", "polyhedron", "--vertices", path, "--density", 1000, "--kn", 1e6)
    assert_one_line_error(result, f"vertex file {path}: holds no vertices")


def test_json_vertices_are_numbered_from_1_in_every_error(tmp_path):
    """A malformed JSON vertex was numbered from 0 ("vertex 8") and one inside the hull
    from 1 ("vertex 9") for the ninth alike."""
    cube = [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    path = tmp_path / "shape.json"
    for ninth, named in (([0.1, 0], "vertex 9: expected three numbers"), ([0, 0, 0], "vertex 9")):
        path.write_text(json.dumps(cube + [ninth]))
        result = invoke("--shape", "polyhedron", "--vertices", path, "--density", 1, "--kn", 1)
        assert_one_line_error(result, str(path), named)


def test_missing_vertex_file_exits_2(tmp_path):
    path = tmp_path / "absent.json"
    result = invoke("--shape", "polyhedron", "--vertices", path, "--density", 1, "--kn", 1)
    assert_one_line_error(result, str(path), "cannot read")


@pytest.mark.parametrize(
    "extra, named",
    [
        (("--shape", "sphere", "--radius", -1, "--kn", 5), "--shape, --radius, --kn"),
        (("--verify", "--json"), "--verify, --json"),
        (("--damping", 0), "--damping"),
    ],
)
def test_figures_take_no_other_option(tmp_path, extra, named):
    """--figures draws the paper's own cases: particle and contact options beside it, even
    invalid ones, were ignored and the figures written with exit 0."""
    folder = tmp_path / "figures"
    result = invoke("--figures", folder, *extra)
    assert_one_line_error(result, "--figures writes Peng 2020's figures", f"leave out {named}")
    assert not folder.exists()


@pytest.mark.parametrize(
    "args, named",
    [
        ((*SPHERE, "--kn", 1e305), "--kn 1e+305 with"),  # showed ∞ recommended
        ((*SPHERE, "--kn", 1e308), "--kn 1e+308 with"),  # showed nan
        ((*SPHERE, "--kn", 1e306, "--json"), "--kn 1e+306 with"),  # wrote NaN, not JSON
        ((*SPHERE, "--kn", 1e6, "--ks", 1e307), "--ks 1e+307 with"),
        ((*SPHERE, "--kn", 1e6, "--damping", 1e300), "--damping 1e+300 with"),  # blamed --kn
        ((*ELLIPSOID, "--omega-max", 1.5e308), "--omega-max 1.5e+308 with"),  # showed 0
        (
            (*ELLIPSOID_SIZE, "--density", 1000, "--kn", 1e308),
            "error: --kn 1e+308 with",
        ),  # blamed --damping 0
        ((*SPHERE, "--sweep", "kn=1:1e307:2"), "--kn 1e+307 with"),
    ],
)
def test_criteria_outside_float64_are_refused_naming_the_option(args, named):
    """Products of the criteria that overflow to ∞ without raising gave ∞, 0 and NaN time
    steps with exit 0, findings of "nan × the reference: stable but conservative" and JSON
    with bare NaN."""
    result = invoke(*args)
    assert_one_line_error(
        result, named, "the particles' sizes and densities", "outside float64's range"
    )


def test_dt_verify_says_its_kernels_compile_only_when_they_will(monkeypatch):
    """`dt --verify` integrates the pair, a minute or more the first time while the kernels
    compile, and said nothing; a --sweep with it, seconds a value, neither."""
    from revdem_cli.report import progress

    pair = ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "2500", "--kn", "1e6"]
    said = {}
    for compiled in (True, False):
        monkeypatch.setattr(progress, "kernels_compiled", lambda *k, compiled=compiled: compiled)
        for args in ([*pair, "--verify"], [*pair[:-2], "--verify", "--sweep", "kn=1e5:1e6:2"]):
            result = CliRunner().invoke(app, args)
            assert result.exit_code == 0, result.output
            said[compiled, "--sweep" in args] = progress.COMPILING in result.output
    assert said == {
        (True, False): False,
        (True, True): False,
        (False, False): True,
        (False, True): True,
    }


@pytest.mark.parametrize("number", [1e8, 1e9])
def test_heavy_damping_recommends_the_velocity_verlet_limit(number):
    """N far above 2: the limit 4/(ω(√(4 + N²) + N)) (Peng 2020 Eq 30 by velocity Verlet),
    about 4/(Nω), neither above it nor refused as an overflow."""
    data = as_json(*ELLIPSOID, "--damping", number)
    omega = math.sqrt(1e10 * data["a_max"])
    exact = 4.0 / (omega * (math.sqrt(4.0 + number**2) + number))
    assert data["recommended_dt"] == pytest.approx(exact, rel=1e-9, abs=0.0)


def test_frictionless_damped_spheres_give_the_predictor_table_limit():
    """Equal frictionless spheres at the engine's β = 0.5 (N = 2β√3.5, A_n = 2/m): velocity
    Verlet 0.6180 and the predictor of order 2 0.3333 of 2/ω, ω² = k_n A_n (README's table);
    the engine and the rigid pair, without a shear dashpot, confirm them."""
    args = ("--shape", "sphere", "--radius", 0.01, "--density", 2500, "--kn", 1e6, "--ks", 0)
    data = as_json(*args, "--damping", 2 * 0.5 * math.sqrt(3.5), "--trvp-order", 2, "--verify")
    unit = 2.0 / math.sqrt(1e6 * data["a_normal"])
    assert data["criteria"]["velocity_verlet"]["dt"] / unit == pytest.approx(0.6180, abs=1e-4)
    assert data["recommended_dt"] / unit == pytest.approx(0.3333, abs=1e-4)
    checks = {key: check["dt"] / unit for key, check in data["checks"].items()}
    assert checks["engine_predictor_integrated"] == pytest.approx(0.3333, rel=3e-3)
    assert checks["engine_integrated"] == pytest.approx(0.6180, rel=1e-3)
    assert checks["rigid_body_integrated"] == pytest.approx(0.6180, rel=1e-3)


def test_the_predictors_reference_is_its_own_limit_not_velocity_verlets():
    """Ellipsoids with the predictor of order 2, checked: the reference was the velocity
    Verlet limit integrated, so the predictor's own limit, 0.54 of it, read "stable but
    conservative" (inviting a step 1.85 times its limit), and the rigid pair's Verlet limit
    called the criteria conservative. The predictor's formula is the reference there."""
    data = as_json(*ELLIPSOID, "--damping", 1, "--trvp-order", 2, "--verify")
    assert data["reference"] == "velocity_predictor"
    assert data["recommended_dt"] == data["criteria"]["velocity_predictor"]["dt"]
    assert not [f for f in data["findings"] if "conservative" in f]
    [verlet] = [f for f in data["findings"] if f.startswith("Eq 30, velocity Verlet")]
    assert "1.85 × the reference, velocity-Verlet limit, trvp k = 2: unsafe" in verlet


def test_a_rigid_pair_far_above_the_criteria_is_named_conservative():
    """The two ellipsoids integrated are stable 1.35 times longer than Eq 30 with A_max: a
    finding says the criteria are conservative for them; for spheres (k_s = k_n) the engine
    agrees with the criteria and none does."""
    findings = as_json(*ELLIPSOID, "--verify")["findings"]
    [line] = [f for f in findings if "conservative for this pair" in f]
    assert line.startswith("The rigid pair, integrated")
    spheres = as_json(*SPHERE, "--kn", 1e6, "--verify")["findings"]
    assert not [f for f in spheres if "conservative for this pair" in f]


def test_a_scheme_never_stable_is_null_with_its_reason_and_b_max_is_in_the_json():
    """The Euler scheme of Eq 40 is stable at no Δt for the undamped ellipsoids: JSON gave
    "dt": 0.0, a time step a script would take; it is null with the reason, and the table
    shows no ratio. B_max (Peng 2020 Eq 54), in the table, is in each particle's object."""
    data = as_json(*ELLIPSOID, "--verify")
    assert data["checks"]["eq40_all_eigenvalues"]["dt"] is None
    assert data["checks"]["eq40_all_eigenvalues"]["reason"] == "never stable"
    assert [p["b_max"] for p in data["particles"]] == pytest.approx([0.8, 0.8])  # I = m(1, 2, 2.6)
    [row] = [line for line in invoke(*ELLIPSOID, "--verify").output.splitlines() if "|λ|" in line]
    assert "never stable" in row and not any(c.isdigit() for c in row.split("never stable")[1])


def test_criteria_say_why_they_do_not_apply_and_which_equation_they_are():
    """At N = 2 the contact is critically damped, not overdamped (Eq 34 has no root); with
    k_s > k_n the undamped limit is Eq 47 in the shear direction, not Eq 48 (k_n)."""
    critical = as_json(*ELLIPSOID, "--damping", 2)["criteria"]["belytschko"]
    assert critical["dt"] is None and critical["reason"] == "does not apply: critically damped"
    assert "n/a (critically damped)" in invoke(*ELLIPSOID, "--damping", 2).output
    over = as_json(*ELLIPSOID, "--damping", 3)["criteria"]["belytschko"]
    assert over["reason"] == "does not apply: overdamped"
    stiff_shear = as_json(*ELLIPSOID, "--ks", 2e10)
    assert stiff_shear["criteria"]["amplification"]["source"] == "Peng 2020 Eq 47"
    assert stiff_shear["recommended_dt"] == pytest.approx(
        2.0 / math.sqrt(2e10 * stiff_shear["a_max"]), rel=1e-12
    )
    assert as_json(*ELLIPSOID)["criteria"]["amplification"]["source"] == "Peng 2020 Eq 48"


def test_figures_keep_the_files_already_there_unless_forced(tmp_path, monkeypatch):
    """`dt --figures DIR` wrote over the figures in DIR, where every other command that
    writes files keeps them unless --force: it refuses, naming the first, before it writes
    any, and --force removes them, as `revdem run` does, before they are drawn again. The
    files it keeps are every one it writes: the committed copies, which it made."""
    from revdem_cli.timestep import figures
    from revdem_cli.timestep.study import PAPER
    from tests.conftest import ROOT

    committed = ROOT / "scenarios" / "peng2020"
    files = [
        *figures.study_files(committed, PAPER, figures.PAPER_STEMS),
        *figures.appendix_files(committed),
    ]
    assert sorted(files) == sorted(p for p in committed.iterdir() if p.suffix != ".toml")
    folder = tmp_path / "figures"
    folder.mkdir()
    earlier = folder / "figureA4_orientations.png"  # the last it writes
    earlier.write_bytes(b"an earlier figure")
    result = invoke("--figures", folder)
    assert_one_line_error(result, f"{earlier}: exists; use --force to overwrite")
    assert [p.name for p in folder.iterdir()] == [earlier.name]
    assert earlier.read_bytes() == b"an earlier figure"
    drawn = []  # the figures themselves take half a minute: their writers are not the point

    def writer(name):
        def write(*args):
            drawn.append(name)
            return iter(())

        return write

    monkeypatch.setattr(figures, "write_figures", writer("3-6"))
    monkeypatch.setattr(figures, "write_appendix_figures", writer("A2, A4"))
    result = invoke("--figures", folder, "--force")
    assert result.exit_code == 0, result.output
    assert drawn == ["3-6", "A2, A4"] and not earlier.exists()
