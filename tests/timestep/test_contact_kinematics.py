"""Relative acceleration at a contact (Peng 2020 Eq 1-19): Eq 22-24 and Appendix A."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import maximum_filter

from revdem_cli.timestep import contact_kinematics as kinematics
from revdem_cli.timestep import criteria, shapes

COUNT = 31  # grid of each Appendix A scan, per angle


@pytest.fixture(scope="module")
def pair(paper):
    body = shapes.ellipsoid(
        *paper["ellipsoid_pair"]["semi_axes"], paper["ellipsoid_pair"]["density"]
    )
    return body, body


def test_figure2_mobilities_are_eq22_to_24(pair):
    body1, body2 = pair
    (a1, _, c1), (a2, b2, _) = body1.surface[:3], body2.surface[:3]
    (ixx1, iyy1, izz1), (ixx2, iyy2, izz2) = body1.axis_moments, body2.axis_moments
    masses = 1.0 / body1.mass + 1.0 / body2.mass
    expected = {  # the diagonal of Eq 22, 23, 24 (Eq 24 with body 2's lever arm b₂)
        "A": (a2**2 / iyy2, a1**2 / izz1 + a2**2 / izz2, a1**2 / iyy1),
        "B": (c1**2 / iyy1 + a2**2 / iyy2, c1**2 / ixx1 + a2**2 / izz2, 0.0),
        "C": (c1**2 / iyy1 + b2**2 / ixx2, c1**2 / ixx1 + b2**2 / izz2, 0.0),
    }
    for name, placement in kinematics.figure2(body1, body2).items():
        mobility = kinematics.mobility(pair, placement)
        diagonal = np.diag(np.array(expected[name]) + masses)
        assert mobility == pytest.approx(diagonal, rel=1e-12, abs=1e-12 * masses), name


def test_every_mobility_is_bounded_by_a_max(pair):
    """Eq 26: no configuration's largest inverse inertia exceeds A_max."""
    body1, body2 = pair
    rng = np.random.default_rng(7)
    bound = criteria.a_max(body1, body2)
    for _ in range(200):
        q2 = rng.normal(size=4)
        q2 /= np.linalg.norm(q2)
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        point = kinematics.support_point(body1, kinematics.IDENTITY, normal)
        centre2 = point - kinematics.support_point(body2, q2, -normal)
        placement = kinematics.Placement((np.zeros(3), centre2), (kinematics.IDENTITY, q2), point)
        mobility = kinematics.mobility(pair, placement)
        assert mobility == pytest.approx(mobility.T, abs=1e-12 * bound)
        assert np.linalg.eigvalsh(mobility).max() <= bound


def test_spin_adds_the_centripetal_term_of_eq17():
    """A sphere spinning at ω about z with the contact on x: ẍ_c gains ω² r toward the centre."""
    sphere = shapes.sphere(1.0, 1.0)
    placement = kinematics.Placement(
        (np.zeros(3), np.array([2.0, 0.0, 0.0])),
        (kinematics.IDENTITY, kinematics.IDENTITY),
        np.array([1.0, 0.0, 0.0]),
    )
    spins = np.array([[0.0, 0.0, 3.0], np.zeros(3)])
    still = kinematics.contact_acceleration((sphere, sphere), placement, np.zeros(3))
    spun = kinematics.contact_acceleration((sphere, sphere), placement, np.zeros(3), spins)
    assert still == pytest.approx(np.zeros(3))
    assert spun == pytest.approx([9.0, 0.0, 0.0])  # -(ω × (ω × r₁)) = +ω² r₁ x̂


def _appendix_pair(paper):
    numbers = paper["appendix_a"]
    body = shapes.ellipsoid(*numbers["semi_axes"], numbers["density"])
    return body, numbers


@pytest.mark.parametrize("scenario", [1, 2])
def test_figure_a2_maximum_is_at_the_tip_of_ellipsoid_1(paper, scenario):
    body, numbers = _appendix_pair(paper)
    scan = kinematics.scan_contact_points(body, body, scenario, COUNT)
    top = np.argmax(scan["acceleration"])
    where = [scan[axis][top] for axis in "xyz"]
    assert where == pytest.approx(numbers["maximum_contact_point"], abs=1e-12)


@pytest.mark.parametrize("scenario", [1, 2])
def test_figure_a4_has_three_similar_maxima_one_orthogonal(paper, scenario):
    body, numbers = _appendix_pair(paper)
    scan = kinematics.scan_orientations(body, body, scenario, COUNT)
    surface = scan["acceleration"].reshape(COUNT, COUNT)
    peaks = surface == maximum_filter(surface, size=3, mode="nearest")
    centres = np.stack([scan[f"centre2_{axis}"] for axis in "xyz"], -1).reshape(COUNT, COUNT, 3)
    found = {tuple(np.round(c, 9)) for c in centres[peaks]}
    assert len(found) == numbers["orientation_maxima"]
    values = surface[peaks]
    assert values.min() >= 0.85 * values.max()  # "a similar maximum value"
    assert any(c[2] == pytest.approx(numbers["orthogonal_maximum_centre_z"]) for c in found)


def test_committed_appendix_figures_hold_the_papers_maxima(paper, committed):
    numbers = paper["appendix_a"]
    contact_points = committed("figureA2_contact_points")
    orientations = committed("figureA4_orientations")
    for scenario in (1.0, 2.0):
        rows = contact_points["scenario"] == scenario
        top = np.argmax(contact_points["acceleration"][rows])
        where = [contact_points[axis][rows][top] for axis in "xyz"]
        assert where == pytest.approx(numbers["maximum_contact_point"], abs=1e-9)
        rows = orientations["scenario"] == scenario
        orthogonal = np.isclose(orientations["centre2_z"][rows], 3.0)
        largest = orientations["acceleration"][rows].max()
        assert orientations["acceleration"][rows][orthogonal].max() >= 0.85 * largest
    mobility = committed("figure2_mobility")
    assert np.all(mobility["largest_m1"] <= paper["ellipsoid_pair"]["a_max_times_mass"])
