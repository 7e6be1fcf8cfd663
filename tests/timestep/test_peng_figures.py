"""Peng 2020 Figures 3-6: the trends the paper describes, and the committed CSVs match the code."""

from __future__ import annotations

import math

import numpy as np
import pytest

from revdem_cli.timestep import criteria, figures, shapes
from revdem_cli.timestep.study import PAPER


def test_figure3_curves_meet_when_undamped_and_part_with_damping(paper):
    data = figures.figure3_data(np.array([0.0, 0.5, 1.0]), every=10)
    undamped = [data[k][0] for k in ("eq58_belytschko", "eq60_amplification", "velocity_verlet")]
    assert undamped == pytest.approx([paper["sphere"]["eq49_alpha"]] * 3)
    assert data["velocity_verlet_integrated"][0] == pytest.approx(undamped[0], rel=1e-6)
    assert np.all(np.diff(data["eq60_amplification"]) > 0)
    assert np.all(np.diff(data["velocity_verlet"]) < 0)
    assert math.isnan(data["eq58_belytschko"][2])  # beyond β = 2/√7 (Eq 37)


@pytest.mark.parametrize(
    "figure, parameter, sign", [("figure4", "kn", -1), ("figure5", "density", 1)]
)
def test_figures4_and_5_follow_stiffness_and_density(paper, figure, parameter, sign):
    low, high = paper[figure][parameter]
    data = figures.damping_sweep_data(PAPER, parameter, np.linspace(low, high, 3), every=99)
    for number in paper[figure]["damping_numbers"]:
        rows = data["N"] == number
        for key in ("eq46_amplification", "velocity_verlet"):
            assert np.all(sign * np.diff(data[key][rows]) > 0)
        integrated = data["velocity_verlet_integrated"][rows]
        assert integrated[0] == pytest.approx(data["velocity_verlet"][rows][0], rel=1e-3)
        assert np.isnan(integrated[1:]).all()
        ratio = data["eq46_amplification"][rows] / data["velocity_verlet"][rows]
        expected = (number + math.sqrt(number**2 + 4)) / (math.sqrt(number**2 + 4) - number)
        assert ratio == pytest.approx(np.full(3, expected))


def test_figure6_shrinks_with_aspect_ratio_and_rotation_is_orders_slower(paper):
    case = paper["figure6"]
    ratios = np.linspace(*case["aspect_ratios"], 5)
    data = figures.figure6_data(PAPER, ratios)
    body = figures.body_of_aspect_ratios(PAPER, 2.0, 3.0)
    assert body.volume == pytest.approx(case["volume_over_pi"] * math.pi)
    shape = (ratios.size, ratios.size)
    for key in ("dt_translation_eq48", "dt_rotation_eq56"):
        grid = data[key].reshape(shape)  # rows: e1, columns: e2
        assert np.all(np.diff(grid, axis=0) < 0) and np.all(np.diff(grid, axis=1) < 0)
    sphere = data["dt_translation_eq48"][0]
    mass = body.mass
    assert sphere == pytest.approx(paper["sphere"]["eq49_alpha"] * math.sqrt(mass / case["kn"]))
    orders = np.log10(data["dt_rotation_eq56"][1:] / data["dt_translation_eq48"][1:])
    assert 3.0 < orders.min() < case["orders_of_magnitude_stated"]


@pytest.mark.parametrize(
    "name, parameter", [("figure4_stiffness", "kn"), ("figure5_density", "density")]
)
def test_committed_damping_figures_match_the_code(paper, committed, name, parameter):
    pair = paper["ellipsoid_pair"]
    data = committed(name)
    for value, number, eq46, vv, integrated in zip(
        data[parameter],
        data["N"],
        data["eq46_amplification"],
        data["velocity_verlet"],
        data["velocity_verlet_integrated"],
        strict=True,
    ):
        kn = value if parameter == "kn" else pair["kn"]
        density = value if parameter == "density" else pair["density"]
        body = shapes.ellipsoid(*pair["semi_axes"], density)
        inverse_mass = criteria.a_max(body, body)
        c = criteria.damping_from_number(number, kn, inverse_mass)
        assert eq46 == pytest.approx(criteria.dt_amplification(kn, c, inverse_mass), rel=1e-9)
        assert vv == pytest.approx(criteria.dt_velocity_verlet(kn, c, inverse_mass), rel=1e-9)
        assert math.isnan(integrated) or integrated == pytest.approx(vv, rel=1e-3)


def test_committed_figures_3_and_6_match_the_code(committed):
    fig3 = committed("figure3_damping")
    fresh = figures.figure3_data(fig3["beta"], every=len(fig3["beta"]) + 1)
    for key in ("eq58_belytschko", "eq59_collision", "eq60_amplification", "velocity_verlet"):
        assert np.allclose(fig3[key], fresh[key], rtol=1e-9, equal_nan=True)
    fig6 = committed("figure6_aspect_ratio")
    size = round(math.sqrt(len(fig6["e1"])))
    fresh = figures.figure6_data(PAPER, fig6["e1"][::size])
    for key in ("dt_translation_eq48", "dt_rotation_eq56"):
        assert np.allclose(fig6[key], fresh[key], rtol=1e-9)


def test_figure_plots_are_written(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    path = tmp_path / "figure3.png"
    figures._plot_figure3(figures.figure3_data(np.linspace(0, 3, 7), every=99), path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "name, parameter", [("figure4_stiffness", "kn"), ("figure5_density", "density")]
)
def test_committed_rigid_body_curves_lie_between_velocity_verlet_and_eq46(
    committed, name, parameter
):
    """The two rigid bodies integrated: above the velocity-Verlet limit with A_max (safe), and
    below Eq 46 once damped (Eq 46 unsafe for them too)."""
    data = committed(name)
    rigid = data["rigid_body_integrated"]
    marked = np.isfinite(rigid)
    assert marked.sum() >= 2 * len(set(data["N"]))  # two or more values of the parameter
    assert np.all(rigid[marked] > data["velocity_verlet"][marked])
    damped = marked & (data["N"] > 0)
    assert np.all(rigid[damped] < data["eq46_amplification"][damped])
