"""The two-body rigid integrator: free tumbling, reversal, and its stability limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from revdem_cli.kernels import rigid_pair as kernel
from revdem_cli.timestep import contact_kinematics as kinematics
from revdem_cli.timestep import criteria, rigid_pair, shapes, verify
from revdem_cli.timestep.criteria import Contact

LIMIT_RTOL = 2e-3  # bisection to 1e-4; slow growth within a trial near the limit


@pytest.fixture(scope="module")
def ellipsoid(paper):
    numbers = paper["ellipsoid_pair"]
    return shapes.ellipsoid(*numbers["semi_axes"], numbers["density"])


def _arrays(body, positions, velocities, quaternions, momenta, law):
    """The kernel's arguments for two copies of `body`."""
    shapes_ = np.array([body.surface, body.surface])
    rotations = kernel.rotations_of(quaternions)
    return (
        (positions, velocities, quaternions, momenta),
        np.zeros((2, 2, 3)),
        np.asarray(law, dtype=float),
        shapes_,
        np.array([body.axis_moments] * 2),
        np.array([body.mass] * 2),
        np.zeros((2, 3)),
        kernel.cold_contact(shapes_, positions, rotations),
    )


def test_free_tumbling_keeps_energy_and_angular_momentum(ellipsoid):
    """Spin about the intermediate axis, slightly off it: the body flips (the intermediate-axis
    instability), energy stays within the splitting's O(Δt²) band, L and |q| to round-off."""
    spin = np.array([1e-3, 1.0, 1e-3])  # rad/s, body frame
    momenta = np.array([np.asarray(ellipsoid.axis_moments) * spin, np.zeros(3)])
    positions = np.array([np.zeros(3), [100.0, 0.0, 0.0]])  # far apart: no contact
    quaternions = np.array([kinematics.IDENTITY, kinematics.IDENTITY])
    arrays = _arrays(ellipsoid, positions, np.zeros((2, 3)), quaternions, momenta, [0] * 6)
    rows, along_y = [], []
    for _ in range(60):  # 60 s in chunks of 1 s, the body-frame π_y after each
        chunk, converged = kernel.trajectory(*arrays, 0.01, 100, 10)
        assert converged
        rows.append(chunk)
        along_y.append(momenta[0, 1] / (ellipsoid.axis_moments[1] * spin[1]))
    rows = np.concatenate(rows)
    energy, angular = rows[:, 0], rows[:, 4:7]
    assert np.abs(energy / energy[0] - 1.0).max() < 1e-4
    assert np.abs(angular - angular[0]).max() < 1e-12 * np.linalg.norm(angular[0])
    assert np.linalg.norm(quaternions[0]) == pytest.approx(1.0, abs=1e-13)
    assert min(along_y) < -0.9  # turned over: the spin about y has reversed in the body


def _colliding(body, law):
    """Two ellipsoids approaching off-centre, turned, so the collision also spins them."""
    q2 = kinematics.compose(kinematics.axis_angle((1.0, 1.0, 0.0), 0.7))
    positions = np.array([np.zeros(3), [5.5, 0.8, 0.5]])
    velocities = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    quaternions = np.array([kinematics.IDENTITY, q2])
    return _arrays(body, positions, velocities, quaternions, np.zeros((2, 3)), law)


def test_collision_reverses_to_round_off(ellipsoid):
    law = [1e8, 0.0, 0.0, 0.0, 0.0, 1.0]  # a collision: normal spring only
    arrays = _colliding(ellipsoid, law)
    start = [a.copy() for a in arrays[0]]
    forward, ok = kernel.trajectory(*arrays, 1e-3, 3000, 1)
    assert ok
    touching = np.flatnonzero(forward[:, 0] - forward[0, 0] != 0.0)
    angular = np.linalg.norm(forward[0, 4:7])
    assert touching.size and np.abs(forward[-1, 4:7] - forward[0, 4:7]).max() < 1e-12 * angular
    spins = arrays[0][3]
    assert np.abs(spins).max() > 1.0  # the off-centre contact set them turning
    end = [a.copy() for a in arrays[0]]
    _, ok = kernel.trajectory(*arrays, -1e-3, 3000, 1)
    assert ok
    for now, then, reached in zip(arrays[0], start, end, strict=True):
        scale = max(np.abs(then).max(), np.abs(reached).max())  # round-off is relative to it
        assert np.abs(now - then).max() < 1e-11 * scale


def test_collision_energy_change_is_the_contact_laws_not_the_integrators(ellipsoid):
    """The Perram-Wertheim overlap's force is the gradient of ½ k δ² only to first order in
    δ/size (2e-3 here): the energy after the collision differs from before by a few 1e-4,
    the same at Δt and Δt/2, so the integrator adds nothing that shrinks with Δt."""
    law = [1e8, 0.0, 0.0, 0.0, 0.0, 1.0]
    changes = []
    for dt in (2e-4, 1e-4):
        rows, ok = kernel.trajectory(*_colliding(ellipsoid, law), dt, round(3.0 / dt), 10)
        assert ok
        changes.append(rows[-1, 0] / rows[0, 0] - 1.0)
    assert abs(changes[1]) < 1e-3
    assert changes[0] == pytest.approx(changes[1], abs=5e-5)


def _mobility(body, configuration):
    """The configuration's A of Eq 25 (Eq 1-19), at its contact point."""
    rotations = [kinematics.matrix(q) for q in configuration.orientations]
    point = rotations[0] @ configuration.points[0]
    centres = (np.zeros(3), point - rotations[1] @ configuration.points[1])
    placement = kinematics.Placement(centres, configuration.orientations, point)
    return kinematics.mobility((body, body), placement)


@pytest.mark.parametrize("number", [0.0, 2.0])
def test_integrated_limit_is_velocity_verlet_on_the_configurations_mobility(ellipsoid, number):
    """Bonded contact, k_n = k_s: the limit is that of Eq 30 with A the largest eigenvalue of
    the configuration's own mobility, not A_max; Eq 48 is then safe by √(A_max/A)."""
    kn = 1e10
    a_max = criteria.a_max(ellipsoid, ellipsoid)
    c = criteria.damping_from_number(number, kn, a_max)
    for configuration in rigid_pair.tangent_configurations(ellipsoid, ellipsoid)[1:]:
        largest = np.linalg.eigvalsh(_mobility(ellipsoid, configuration)).max()
        expected = criteria.dt_velocity_verlet(kn, c, largest)
        found = rigid_pair.configuration_limit(
            ellipsoid, ellipsoid, Contact(kn, kn, c, c), configuration
        )
        assert found == pytest.approx(expected, rel=LIMIT_RTOL)
        assert found > criteria.dt_velocity_verlet(kn, c, a_max)


def test_random_draws_are_seeded_and_touch(ellipsoid):
    first = rigid_pair.random_configurations(ellipsoid, ellipsoid, 3, 11)
    again = rigid_pair.random_configurations(ellipsoid, ellipsoid, 3, 11)
    for one, other in zip(first, again, strict=True):
        assert np.array_equal(one.points, other.points)
        pair = rigid_pair.place(ellipsoid, ellipsoid, one, rigid_pair.bonded_law(Contact(1, 1)))
        rotations = kernel.rotations_of(pair.bodies[2])
        *_, overlap = kernel.contact_geometry(pair.shapes, pair.bodies[0], rotations, pair.solution)
        size = max(ellipsoid.half_lengths)
        kick = rigid_pair.DISPLACEMENT * size
        assert abs(overlap) <= kick * (1.0 + 1e-6)


def test_polyhedra_have_no_rigid_limit():
    cube = shapes.polyhedron(
        np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3), 1.0, "cube"
    )
    assert rigid_pair.rigid_body_limits(cube, cube, Contact(1.0, 1.0)) is None
    assert math.isfinite(criteria.a_max(cube, cube))


@pytest.mark.parametrize("exponents", [(1.0, 1.0), (0.5, 0.5), (1.8, 1.8), (0.6, 1.4)])
def test_shape_function_is_barrs_with_its_derivatives(exponents):
    """G = 1 on Barr's surface, homogeneous of degree two; gradient and Hessian match central
    differences at a point off the axes (where the Hessian is not capped)."""
    surface = np.array([3.0, 2.0, 1.0, *exponents])
    eps1, eps2 = exponents
    x, y = 3.0 * 0.6 ** (eps2 / 2), 2.0 * 0.4 ** (eps2 / 2)  # (x/a)^(2/ε2) + (y/b)^(2/ε2) = 1
    rho = 0.5 ** (eps1 / 2)  # ρ^(2/ε1) = (z/c)^(2/ε1) = 1/2
    point = np.array([rho * x, rho * y, 1.0 * rho])
    value, gradient, hessian = kernel.shape_function(surface, point)
    assert value == pytest.approx(1.0, rel=1e-12)
    assert kernel.shape_function(surface, 1.7 * point)[0] == pytest.approx(1.7**2, rel=1e-12)
    step = 1e-6
    for i in range(3):
        offset = np.eye(3)[i] * step
        up, down = (kernel.shape_function(surface, point + s * offset) for s in (1.0, -1.0))
        assert gradient[i] == pytest.approx((up[0] - down[0]) / (2 * step), rel=1e-6)
        assert hessian[i] == pytest.approx((up[1] - down[1]) / (2 * step), rel=1e-5, abs=1e-8)


def test_two_spheres_integrated_anywhere_give_eq49(paper):
    """Every contact of two equal spheres has A = 7/m, so every configuration's limit is
    Eq 49, 2/√7 √(m/k_n)."""
    sphere = shapes.sphere(0.01, 2500.0)
    kn = 1e6
    limits = rigid_pair.rigid_body_limits(sphere, sphere, Contact(kn, kn), draws=2, seed=5)
    expected = paper["sphere"]["eq49_alpha"] * math.sqrt(sphere.mass / kn)
    assert len(limits) == 6
    assert list(limits.values()) == pytest.approx([expected] * 6, rel=LIMIT_RTOL)


def test_flat_face_on_flat_face_is_a_lost_contact_not_a_limit():
    """Blocky superquadrics face to face touch in a patch: no point contact to follow."""
    blocky = shapes.superquadric(3.0, 2.0, 1.0, 0.5, 0.5, 1000.0)
    faces = rigid_pair.Configuration(
        "faces",
        (kinematics.IDENTITY, kinematics.IDENTITY),
        (np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])),
    )
    with pytest.raises(rigid_pair.ContactLost, match="configuration faces"):
        rigid_pair.configuration_limit(blocky, blocky, Contact(1e10, 1e10), faces)
    assert rigid_pair.tangent_configurations(blocky, blocky) == ()


def test_edged_superquadrics_are_not_integrated():
    octahedron = shapes.superquadric(3.0, 2.0, 1.0, 2.0, 2.0, 1000.0)
    assert rigid_pair.rigid_body_limits(octahedron, octahedron, Contact(1.0, 1.0)) is None
    assert rigid_pair.rigid_body_limit(octahedron, octahedron, Contact(1.0, 1.0)) is None


def test_a_tumbling_pair_keeps_the_limit_at_rest(ellipsoid):
    """The bonded pair (coaxial tips) turning as one body at 20 rad/s about a non-principal
    axis, the contact carrying its centripetal load: the limit moves by under 1e-3, while the
    rotation-dominant Δt (Eq 57) is 65 times larger; rotation does not couple here."""
    kn = 1e10
    tips = rigid_pair.tangent_configurations(ellipsoid, ellipsoid)[3]
    law = rigid_pair.bonded_law(Contact(kn, kn))
    law[5] = 2e-2  # room for the centripetal stretch, 3e-3 of the long semi-axis at 20 rad/s

    def limit(omega):
        pair = rigid_pair.place(ellipsoid, ellipsoid, tips, law)
        positions, velocities, quaternions, momenta = pair.bodies
        spin = omega * np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0])
        for i, rotation in enumerate(kernel.rotations_of(quaternions)):
            velocities[i] = np.cross(spin, positions[i] - positions.mean(axis=0))
            momenta[i] = np.asarray(ellipsoid.axis_moments) * (rotation.T @ spin)
        stable = lambda dt: rigid_pair.is_stable(pair, dt, tips.name)  # noqa: E731
        return verify.largest_stable_dt(stable, 1e-3, rigid_pair.BISECTION_RTOL)

    at_rest, turning = limit(0.0), limit(20.0)
    assert turning == pytest.approx(at_rest, rel=1e-3)
    rotation = criteria.dt_rotation(20.0, criteria.b_max(ellipsoid), criteria.b_max(ellipsoid))
    assert rotation > 60.0 * turning
