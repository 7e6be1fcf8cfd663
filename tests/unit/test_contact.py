import math

import numpy as np
import pytest

from revdem_cli.config import Material
from revdem_cli.kernels.contact import (
    normal_law,
    remap,
    rotate_about,
    turn_onto,
    unmap,
)
from revdem_cli.state import contact_law, effective_modulus, effective_shear_modulus, moduli
from tests.conftest import two_spheres

SPHERE = Material(density=1000, shear_modulus=2e6, poisson_ratio=0.2)


def test_equal_materials_give_the_papers_hertz_stiffness():
    # Hanley 2020 Eq 6: H = 4G/(3(1-nu)) sqrt(r_a r_b/(r_a+r_b)) for identical particles
    law = contact_law(two_spheres())
    g, nu, r, overlap = 2e6, 0.2, 0.005, 1e-5
    force, stiffness, _ = normal_law(law, overlap, r / 2, moduli(two_spheres()).estar[0, 0])
    h = 4 * g / (3 * (1 - nu)) * math.sqrt(r * r / (2 * r))
    assert force == pytest.approx(h * overlap**1.5, rel=1e-14)
    assert stiffness == pytest.approx(1.5 * h * overlap**0.5, rel=1e-14)


def test_mindlin_stiffness_matches_the_papers_form():
    # Hanley 2020 Eq 10: H^s = H^n sqrt(U^n) 3(1-nu)/(2-nu) with H^n as in Eq 6
    g, nu, rstar, overlap = 2e6, 0.2, 0.0025, 1e-5
    gstar = effective_shear_modulus(SPHERE, SPHERE)
    hn = 4 * g / (3 * (1 - nu)) * math.sqrt(rstar)
    assert 8 * gstar * math.sqrt(rstar * overlap) == pytest.approx(
        hn * math.sqrt(overlap) * 3 * (1 - nu) / (2 - nu), rel=1e-14
    )


def test_a_rigid_wall_halves_the_compliance_sum():
    rigid = Material(density=1000, shear_modulus=1e15, poisson_ratio=0.2)
    assert effective_modulus(SPHERE, rigid) == pytest.approx(
        2 * effective_modulus(SPHERE, SPHERE), rel=1e-8
    )


@pytest.mark.parametrize("contact", [{"model": "hertz"}, {"model": "linear", "kn": 1e4}])
def test_force_is_minus_the_derivative_of_the_stored_energy(contact):
    law = contact_law(two_spheres(contact=contact))
    for overlap in np.geomspace(1e-7, 1e-4, 5):
        h = overlap * 1e-5
        up, down = (
            normal_law(law, overlap + h, 0.0025, 2.5e6),
            normal_law(law, overlap - h, 0.0025, 2.5e6),
        )
        assert (up[2] - down[2]) / (2 * h) == pytest.approx(
            normal_law(law, overlap, 0.0025, 2.5e6)[0], rel=1e-7
        )


def unit(v):
    return tuple(np.asarray(v) / np.linalg.norm(v))


def test_remap_keeps_magnitude_and_unmap_inverts_it():
    rng = np.random.default_rng(3)
    for _ in range(50):
        n_old = unit(rng.normal(size=3))
        n_new = unit(np.asarray(n_old) + 0.05 * rng.normal(size=3))
        shear = np.cross(n_old, rng.normal(size=3))  # lies in the old contact plane
        mapped = remap(tuple(shear), n_new)  # Hanley 2020 Eq 7-8
        assert np.dot(mapped, n_new) == pytest.approx(0, abs=1e-15)
        assert np.linalg.norm(mapped) == pytest.approx(np.linalg.norm(shear), rel=1e-14)
        np.testing.assert_allclose(unmap(mapped, n_new, n_old), shear, rtol=0, atol=1e-14)


@pytest.mark.parametrize("angle", [1e-2, 1e-3])
def test_turning_with_the_contact_plane_is_eq_7_8_to_second_order_and_keeps_its_normal_part(
    angle,
):
    """The fixed-point remap: the rotation taking the old normal onto the new one. On a history
    in the old plane it keeps the magnitude and lands in the new plane as Eq 7-8 does, and
    differs from Eq 7-8's projection by less than the angle squared; a part across the
    old plane (rounding's) comes out across the new one, which the projection drops; the
    turn back from the new normal onto the old is its inverse to round-off."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        n_old = unit(rng.normal(size=3))
        axis = unit(np.cross(n_old, rng.normal(size=3)))
        n_new = tuple(np.asarray(n_old) * math.cos(angle) + np.cross(axis, n_old) * math.sin(angle))
        shear = np.cross(n_old, rng.normal(size=3))
        turned = np.asarray(turn_onto(tuple(shear), n_old, n_new))
        size = np.linalg.norm(shear)
        assert np.dot(turned, n_new) == pytest.approx(0, abs=1e-15 * size)
        assert np.linalg.norm(turned) == pytest.approx(size, rel=1e-14)
        projected = np.asarray(remap(tuple(shear), n_new))
        assert np.linalg.norm(turned - projected) < angle**2 * size
        across = shear + 1e-3 * size * np.asarray(n_old)
        kept = np.dot(turn_onto(tuple(across), n_old, n_new), n_new)
        assert kept == pytest.approx(1e-3 * size, rel=1e-9)
        assert np.dot(remap(tuple(across), n_new), n_new) == pytest.approx(0, abs=1e-15 * size)
        back = turn_onto(tuple(turned), n_new, n_old)
        np.testing.assert_allclose(back, shear, rtol=0, atol=1e-15 * size)


def test_spin_correction_rotates_within_the_contact_plane():
    n = unit([1.0, 2.0, 2.0])
    b = tuple(np.cross(n, [0.0, 0.0, 1.0]))
    turned = rotate_about(b, n, 0.3)
    assert np.dot(turned, n) == pytest.approx(0, abs=1e-15)
    assert np.dot(turned, b) / np.dot(b, b) == pytest.approx(math.cos(0.3), rel=1e-14)
    np.testing.assert_allclose(rotate_about(turned, n, -0.3), b, atol=1e-15)
