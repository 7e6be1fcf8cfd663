"""Time-step study files through `revdem run`: the paper's Figures 3-6 as PNG and CSV."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.errors import InputError
from revdem_cli.timestep import figures, shapes
from revdem_cli.timestep.study import PAPER, read_study, study_from_text
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()
STUDY = CONFIGS / "ellipsoid_dt.toml"
PNG = b"\x89PNG\r\n\x1a\n"

# The paper's study with few points, each replacement once and in order: integration only
# at the first k_n of Figure 4.
CHEAP = (
    ('name = "ellipsoid_dt"', 'name = "cheap_study"'),
    ("count = 301 }", "count = 4 }"),
    ("integrate_every = 25", "integrate_every = 0"),
    ("count = 37 }   # N/m", "count = 3 }"),
    ("integrate_every = 12", "integrate_every = 99"),
    ("count = 37 }   # kg/m^3", "count = 4 }"),
    ("integrate_every = 12", "integrate_every = 0"),
    ("count = 41 }", "count = 5 }"),
)


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def cheap_text() -> str:
    text = STUDY.read_text()
    for old, new in CHEAP:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


def read_csv(path) -> dict[str, np.ndarray]:
    with open(path) as stream:
        rows = list(csv.DictReader(stream))
    return {key: np.array([float(r[key] or "nan") for r in rows]) for key in rows[0]}


def dt_json(*args) -> dict:
    result = invoke("dt", *args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The cheap study run once through `revdem run`: its output folder and printed lines."""
    folder = tmp_path_factory.mktemp("study")
    path = folder / "cheap.toml"
    path.write_text(cheap_text())
    result = invoke("run", path, "--out", folder / "out")
    assert result.exit_code == 0, result.output
    return folder / "out", result.output.strip().splitlines()


def test_the_config_is_the_paper_study_and_its_defaults_are_the_papers(paper):
    study = read_study(STUDY)
    assert study.model_dump(exclude={"name", "description"}) == PAPER.model_dump(
        exclude={"name", "description"}
    )
    assert study.name == "ellipsoid_dt" and study.figures == (3, 4, 5, 6)
    pair, fig4, fig5, fig6 = (paper[k] for k in ("ellipsoid_pair", "figure4", "figure5", "figure6"))
    assert PAPER.particle.semi_axes == tuple(pair["semi_axes"])
    assert PAPER.particle.density == pair["density"] == fig4["density"] == fig6["density"]
    assert PAPER.contact.kn == pair["kn"] == fig5["kn"] == fig6["kn"]
    assert list(PAPER.contact.damping_numbers) == fig4["damping_numbers"]
    assert [PAPER.figure4.kn.start, PAPER.figure4.kn.stop] == fig4["kn"]
    assert [PAPER.figure5.density.start, PAPER.figure5.density.stop] == fig5["density"]
    ratios = PAPER.figure6.aspect_ratios
    assert [ratios.start, ratios.stop] == fig6["aspect_ratios"]
    assert PAPER.figure6.volume == pytest.approx(fig6["volume_over_pi"] * math.pi, rel=1e-15)
    assert PAPER.figure6.omega_max == fig6["omega_max"]


def test_run_writes_a_png_and_a_csv_per_figure(written):
    out, lines = written
    names = [f"cheap_study.figure{n}.{ext}" for n in (3, 4, 5, 6) for ext in ("csv", "png")]
    assert lines == [f"wrote {out / name}" for name in names]
    for name in names:
        if name.endswith(".png"):
            assert (out / name).read_bytes()[:8] == PNG


def test_figure4_csv_matches_revdem_dt_and_the_closed_form(written, paper):
    out, _ = written
    data = read_csv(out / "cheap_study.figure4.csv")
    assert data["kn"].tolist() == [1e10] * 6 + [5.5e10] * 6 + [1e11] * 6
    first = data["kn"] == 1e10
    # Undamped pair a, b, c = 3, 2, 1 m, ρ = 1000 kg/m³: m = 8000π kg, I_xx = m (b² + c²)/5
    # = m, A_max = 2 a²/I_xx + 2/m = 20/m (Peng 2020 Eq 26), Δt = 2/√(k_n A_max) (Eq 48).
    mass = 1000.0 * 4.0 / 3.0 * math.pi * 3.0 * 2.0 * 1.0
    undamped = 2.0 / math.sqrt(1e10 * 20.0 / mass)
    assert undamped == pytest.approx(paper["ellipsoid_pair"]["dt_undamped"], rel=1e-3)
    row = first & (data["N"] == 0)
    for key in ("eq46_amplification", "velocity_verlet", "velocity_verlet_integrated"):
        assert data[key][row] == pytest.approx([undamped], rel=1e-4)
    assert np.isnan(data["velocity_verlet_integrated"][~first]).all()
    stiffest = (data["kn"] == 1e11) & (data["N"] == 0)  # Δt ∝ 1/√k_n (Eq 48)
    assert data["eq46_amplification"][stiffest] == pytest.approx([undamped / math.sqrt(10.0)])
    for number in (0, 2, 5):
        report = dt_json(
            "--shape", "ellipsoid", "--semi-axes", 3, 2, 1, "--density", 1000,
            "--kn", 1e10, "--damping", number,
        )  # fmt: skip
        row = first & (data["N"] == number)
        assert data["a_max"][row] == pytest.approx([report["a_max"]], rel=1e-9)
        eq46 = report["criteria"]["amplification"]["dt"]
        assert data["eq46_amplification"][row] == pytest.approx([eq46], rel=1e-9)
        verlet = report["criteria"]["velocity_verlet"]["dt"]
        assert data["velocity_verlet"][row] == pytest.approx([verlet], rel=1e-9)


def test_figure5_csv_matches_revdem_dt_at_another_density(written):
    out, _ = written
    data = read_csv(out / "cheap_study.figure5.csv")
    row = (data["density"] == 3500.0) & (data["N"] == 3)
    report = dt_json(
        "--shape", "ellipsoid", "--semi-axes", 3, 2, 1, "--density", 3500,
        "--kn", 1e10, "--damping", 3,
    )  # fmt: skip
    assert data["eq46_amplification"][row] == pytest.approx(
        [report["criteria"]["amplification"]["dt"]], rel=1e-9
    )
    assert np.isnan(data["velocity_verlet_integrated"]).all()  # integrate_every = 0


def test_figures_3_and_6_csv_hold_the_sphere_limits(written):
    out, _ = written
    fig3 = read_csv(out / "cheap_study.figure3.csv")
    assert fig3["beta"].tolist() == [0.0, 1.0, 2.0, 3.0]
    alpha = 2.0 / math.sqrt(7.0)  # Peng 2020 Eq 49
    for key in ("eq58_belytschko", "eq60_amplification", "velocity_verlet"):
        assert fig3[key][0] == pytest.approx(alpha, rel=1e-9)  # CSV: 10 digits
    assert fig3["eq60_amplification"][3] == pytest.approx(3.0 + math.sqrt(9.0 + 4.0 / 7.0))
    fig6 = read_csv(out / "cheap_study.figure6.csv")
    assert len(fig6["e1"]) == 25
    # e1 = e2 = 1: a sphere of volume 8π m³, r³ = 6 m³; Eq 49 and no rotation limit.
    mass = 1000.0 * 8.0 * math.pi
    assert fig6["a"][0] == pytest.approx(6.0 ** (1.0 / 3.0))
    assert fig6["dt_translation_eq48"][0] == pytest.approx(alpha * math.sqrt(mass / 1e10))
    assert math.isinf(fig6["dt_rotation_eq56"][0])


def test_set_overrides_and_yaml_choose_what_is_written(tmp_path):
    yaml_study = tmp_path / "aspect.yaml"
    yaml_study.write_text(
        "kind: critical_time_step\nname: aspect\nfigures: [6]\n"
        "figure6: {aspect_ratios: {start: 1, stop: 2, count: 3}, plotted_e2: [1, 2]}\n"
    )
    result = invoke("run", yaml_study, "--out", tmp_path / "a", "--set", "figure6.omega_max=2")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == [
        "aspect.figure6.csv",
        "aspect.figure6.png",
    ]
    fig6 = read_csv(tmp_path / "a" / "aspect.figure6.csv")
    body = figures.body_of_aspect_ratios(PAPER, 2.0, 1.5)
    row = (fig6["e1"] == 2.0) & (fig6["e2"] == 1.5)
    i1, i2, i3 = body.moments
    b_max = max(abs(i1 - i2) / i3, abs(i1 - i3) / i2, abs(i2 - i3) / i1)  # Peng 2020 Eq 54
    assert fig6["dt_rotation_eq56"][row] == pytest.approx([2.0 / (2.0 * 2.0 * b_max)])  # Eq 56


def test_superquadric_with_unit_exponents_is_the_ellipsoid():
    text = "kind = 'critical_time_step'\nname = 's'\n[particle]\nshape = 'superquadric'\n"
    study = study_from_text(text + "exponents = [1.0, 1.0]\n", ".toml", "s.toml")
    values = np.array([1e10, 2e10])
    squad = figures.damping_sweep_data(study, "kn", values, every=0)
    ellipsoid = figures.damping_sweep_data(PAPER, "kn", values, every=0)
    for key in ("a_max", "eq46_amplification", "velocity_verlet"):
        assert squad[key] == pytest.approx(ellipsoid[key], rel=1e-12)
    boxy = study_from_text(text + "exponents = [0.5, 0.5]\n", ".toml", "s.toml")
    body = figures.body_of_aspect_ratios(boxy, 2.0, 3.0)
    assert body.volume == pytest.approx(8.0 * math.pi)
    assert body.half_lengths[0] / body.half_lengths[1] == pytest.approx(2.0)
    assert body.moments != shapes.ellipsoid(*body.half_lengths, 1000.0).moments


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ("[particle]", "[particle]\ncolour = 'red'", ["particle.colour: unknown field"]),
        # the hint was a scenario's field of that name: a scenario's contact has ks
        ("kn = 1e10 ", "k = 1e10 ", ["contact.k: unknown field (did you mean kn?)"]),
        ("density = 1000.0", "density = -1000.0", ["particle.density:", "greater than 0"]),
        ("figures = [3, 4, 5, 6]", "figures = [3, 7]", ["figures[1]:", "3, 4, 5 or 6"]),
        ("figures = [3, 4, 5, 6]", "figures = [3, 3]", ["figures [3, 3]: name each figure once"]),
        ('shape = "ellipsoid"', 'shape = "superquadric"', ["particle: a superquadric needs"]),
        ("count = 37 }   # N/m", "count = 0 }", ["figure4.kn.count:", "greater than or equal"]),
        ("stop = 1e11", "stop = 1e9", ["figure4.kn: stop (1e+09) must not be below start"]),
        ("plotted_e2 = [1, 2", "plotted_e2 = [1.55, 2", ["figure6: plotted_e2 = 1.55 is not"]),
        ('name = "ellipsoid_dt"', 'name = "a/b"', ["name:", "should match pattern"]),
        ("integrate_every = 25", "integrate_every = -1", ["figure3.integrate_every:"]),
    ],
)
def test_bad_study_fields_exit_2_naming_the_field(tmp_path, old, new, fragments):
    text = STUDY.read_text()
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new, 1))
    result = invoke("run", path, "--out", tmp_path / "out")
    assert_one_line_error(result, str(path), *fragments)
    assert not (tmp_path / "out").exists()


def test_a_file_of_another_kind_is_no_study_and_no_scenario(tmp_path):
    path = tmp_path / "other.toml"
    path.write_text(STUDY.read_text().replace('"critical_time_step"', '"something_else"'))
    assert read_study(path) is None
    result = invoke("run", path, "--out", tmp_path / "out")
    assert_one_line_error(result, "other.toml: kind: unknown kind 'something_else' (known: ")
    with pytest.raises(InputError, match=r"^s\.toml: kind: missing required field"):
        study_from_text("name = 's'", ".toml", "s.toml")


def test_a_study_hands_over_each_figure_as_soon_as_it_is_written(tmp_path):
    """Seconds a figure: `revdem run` says `wrote` for each as it comes, not all at the end."""
    from revdem_cli.timestep.study import run_study

    study = study_from_text(cheap_text(), ".toml", "cheap.toml")
    written = run_study(study, tmp_path)
    first = next(written)
    assert first == tmp_path / f"{study.name}.figure3.csv" and first.exists()
    assert not (tmp_path / f"{study.name}.figure4.csv").exists()  # not computed yet
    rest = list(written)
    assert len(rest) == 2 * len(study.figures) - 1 and all(path.exists() for path in rest)
