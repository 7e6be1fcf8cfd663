"""Volume, mass, principal moments and bounding boxes against closed forms and Monte Carlo."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from revdem_cli.errors import InputError
from revdem_cli.timestep import shapes

DENSITY = 1500.0
SAMPLES = 400_000
MC_RTOL = 0.015


def cube_vertices(half: float = 1.0) -> np.ndarray:
    return half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


def octahedron_vertices(a: float, b: float, c: float) -> np.ndarray:
    return np.array([[a, 0, 0], [-a, 0, 0], [0, b, 0], [0, -b, 0], [0, 0, c], [0, 0, -c]], float)


def monte_carlo(inside, half_lengths, seed: int = 7):
    """Volume and principal moments of {inside} by uniform sampling of its bounding box."""
    rng = np.random.default_rng(seed)
    half = np.asarray(half_lengths, float)
    points = rng.uniform(-half, half, size=(SAMPLES, 3))
    box = 8.0 * half.prod()
    hits = points[inside(points)]
    volume = box * len(hits) / SAMPLES
    second = box * np.einsum("ni,nj->ij", hits, hits) / SAMPLES
    inertia = DENSITY * (np.trace(second) * np.eye(3) - second)
    return volume, np.sort(np.linalg.eigvalsh(inertia))


def assert_body_matches(body, volume, moments, rtol):
    assert body.volume == pytest.approx(volume, rel=rtol)
    assert body.mass == pytest.approx(DENSITY * volume, rel=rtol)
    assert body.moments == pytest.approx(tuple(moments), rel=rtol)


def test_ellipsoid_matches_closed_form_and_monte_carlo():
    a, b, c = 3.0, 2.0, 1.0
    body = shapes.ellipsoid(a, b, c, DENSITY)
    mass = DENSITY * 4.0 / 3.0 * math.pi * a * b * c
    closed = sorted(mass * (p**2 + q**2) / 5.0 for p, q in ((b, c), (a, c), (a, b)))
    assert_body_matches(body, 4.0 / 3.0 * math.pi * a * b * c, closed, 1e-12)

    def inside(p):
        return (p[:, 0] / a) ** 2 + (p[:, 1] / b) ** 2 + (p[:, 2] / c) ** 2 <= 1.0

    assert_body_matches(body, *monte_carlo(inside, (a, b, c)), MC_RTOL)
    assert body.half_lengths == (a, b, c)


def test_sphere_has_two_fifths_m_r_squared():
    body = shapes.sphere(0.5, DENSITY)
    assert body.moments == pytest.approx((0.4 * body.mass * 0.25,) * 3, rel=1e-12)


@pytest.mark.parametrize("eps1, eps2", [(0.4, 1.6), (1.5, 0.6), (2.0, 1.0)])
def test_superquadric_matches_monte_carlo(eps1, eps2):
    a, b, c = 2.5, 1.5, 1.0
    body = shapes.superquadric(a, b, c, eps1, eps2, DENSITY)

    def inside(p):
        planar = np.abs(p[:, 0] / a) ** (2 / eps2) + np.abs(p[:, 1] / b) ** (2 / eps2)
        return planar ** (eps2 / eps1) + np.abs(p[:, 2] / c) ** (2 / eps1) <= 1.0

    assert_body_matches(body, *monte_carlo(inside, (a, b, c)), MC_RTOL)


def test_superquadric_with_unit_exponents_is_the_ellipsoid():
    quadric, ellipsoid = (
        shapes.superquadric(3, 2, 1, 1, 1, DENSITY),
        shapes.ellipsoid(3, 2, 1, DENSITY),
    )
    assert_body_matches(quadric, ellipsoid.volume, ellipsoid.moments, 1e-12)
    assert quadric.half_lengths == ellipsoid.half_lengths


def test_cube_polyhedron_matches_superquadric_box_limit():
    cube = shapes.polyhedron(cube_vertices(1.0), DENSITY, "cube")
    assert_body_matches(cube, 8.0, [DENSITY * 8.0 * 2.0 / 3.0] * 3, 1e-12)
    box = shapes.superquadric(1, 1, 1, 1e-4, 1e-4, DENSITY)
    assert_body_matches(box, cube.volume, cube.moments, 1e-3)
    assert box.half_lengths == cube.half_lengths


def test_octahedron_polyhedron_is_the_superquadric_with_exponents_two():
    octahedron = shapes.polyhedron(octahedron_vertices(3, 2, 1), DENSITY, "octahedron")
    quadric = shapes.superquadric(3, 2, 1, 2, 2, DENSITY)
    assert_body_matches(octahedron, quadric.volume, quadric.moments, 1e-12)
    assert octahedron.half_lengths == pytest.approx(quadric.half_lengths)


def test_rotated_polyhedron_is_found_in_its_principal_frame():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(12, 3)) * [3.0, 2.0, 1.0]
    cloud = np.vstack([points, -points])
    symmetric = cloud[ConvexHull(cloud).vertices]
    rotated = Rotation.random(random_state=5).apply(symmetric) + [10.0, -4.0, 2.0]
    body = shapes.polyhedron(rotated, DENSITY, "cloud")
    plain = shapes.polyhedron(symmetric, DENSITY, "cloud")
    assert_body_matches(body, plain.volume, plain.moments, 1e-10)

    hull = ConvexHull(rotated)

    def inside(p):
        return (p @ hull.equations[:, :3].T + hull.equations[:, 3] <= 0.0).all(axis=1)

    centre = rotated[hull.vertices].mean(axis=0)
    reach = np.abs(rotated - centre).max(axis=0)

    def inside_centred(p):
        return inside(p + centre)

    assert_body_matches(body, *monte_carlo(inside_centred, reach), MC_RTOL)


def test_box_half_lengths_come_back_after_rotation():
    box = cube_vertices(1.0) * [3.0, 2.0, 0.5]
    rotated = Rotation.from_euler("xyz", [30, 50, 70], degrees=True).apply(box)
    body = shapes.polyhedron(rotated, DENSITY, "box")
    assert body.half_lengths == pytest.approx((3.0, 2.0, 0.5), rel=1e-9)


def test_a_rotated_cube_has_the_same_critical_time_step():
    """A cube's inertia is the same about every axis, so its principal frame is any frame and
    its box there any box around it: A_max takes its farthest vertex, √3 half-edges away,
    with which a corner contact moves (1/m + 3 h²/I a body), in every orientation."""
    from revdem_cli.timestep.criteria import a_max

    plain = shapes.polyhedron(cube_vertices(1.0), DENSITY, "cube")
    expected = 2.0 * (1.0 / plain.mass + 3.0 / plain.moments[0])
    for seed in range(5):
        turned = Rotation.random(random_state=seed).apply(cube_vertices(1.0))
        cube = shapes.polyhedron(turned, DENSITY, "cube")
        assert cube.reach == pytest.approx(math.sqrt(3.0), rel=1e-12)
        assert a_max(cube, cube) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(
    ("exponents", "corner"),
    [((1.0, 1.0), False), ((2.0, 2.0), False), ((0.5, 0.5), False), ((0.3, 1.4), False),
     ((1e-4, 1e-4), True)],
)  # fmt: skip
def test_the_farthest_point_of_a_superquadric_is_found(exponents, corner):
    """`Body.reach` against the surface sampled on a fine grid of Barr's angles: the
    semi-axis a for an ellipsoid or an octahedron, the corner of a box."""
    eps1, eps2 = exponents
    body = shapes.superquadric(3.0, 2.0, 1.0, eps1, eps2, DENSITY)
    eta, omega = np.meshgrid(*(np.linspace(0.0, math.pi / 2, 2001),) * 2)
    ce, se, co, so = np.cos(eta), np.sin(eta), np.cos(omega), np.sin(omega)
    squared = ce ** (2 * eps1) * (9.0 * co ** (2 * eps2) + 4.0 * so ** (2 * eps2))
    sampled = np.sqrt((squared + se ** (2 * eps1)).max())
    assert sampled <= body.reach * (1.0 + 1e-12)
    assert body.reach == pytest.approx(sampled, rel=1e-5)
    if exponents[0] >= 1.0 and exponents[1] >= 1.0:
        assert body.reach == 3.0
    if corner:
        assert body.reach == pytest.approx(math.sqrt(14.0), rel=1e-3)


def test_non_convex_vertex_set_is_refused():
    dented = np.vstack([cube_vertices(), [[0.2, 0.0, 0.0], [-0.2, 0.0, 0.0]]])
    with pytest.raises(InputError, match=r"dented: vertex 9 lies inside .* not convex"):
        shapes.polyhedron(dented, DENSITY, "dented")


def test_not_centrally_symmetric_polyhedron_is_refused():
    tetrahedron = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    with pytest.raises(InputError, match="tetra: vertex .* not centrally symmetric"):
        shapes.polyhedron(tetrahedron, DENSITY, "tetra")


def test_flat_vertex_set_is_refused():
    square = np.array([[1, 1, 0], [1, -1, 0], [-1, 1, 0], [-1, -1, 0]], float)
    with pytest.raises(InputError, match="flat: the vertices span no volume"):
        shapes.polyhedron(square, DENSITY, "flat")


def test_vertex_files_in_text_and_json(tmp_path):
    text = tmp_path / "cube.txt"
    text.write_text("# a cube\n" + "\n".join(f"{x}, {y} {z}" for x, y, z in cube_vertices()))
    listed = tmp_path / "cube.json"
    listed.write_text(json.dumps(cube_vertices().tolist()))
    keyed = tmp_path / "keyed.json"
    keyed.write_text(json.dumps({"vertices": cube_vertices().tolist()}))
    for path in (text, listed, keyed):
        assert np.array_equal(shapes.read_vertices(path), cube_vertices())


@pytest.mark.parametrize(
    "name, content, message",
    [
        (
            "short.txt",
            "1 2 3\n# a comment\n4 5\n",
            r"line 3: expected three numbers x y z, got \['4', '5'\]",
        ),
        ("words.txt", "1 2 x\n", "line 1: expected three numbers"),
        (
            "ragged.json",
            "[[1, 2, 3], [1, 2]]",
            r"vertex 2: expected three numbers x y z, got \[1, 2\]",
        ),
        ("scalar.json", "3", "expected a list of vertices"),
        ("broken.json", "[[1, 2, 3],", "not valid JSON"),
        ("nan.txt", "1 2 nan\n", "finite"),
    ],
)
def test_malformed_vertex_files_are_refused(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(InputError, match=f"vertex file .*{name}: .*{message}"):
        shapes.read_vertices(path)


def test_missing_or_binary_vertex_file_is_refused(tmp_path):
    with pytest.raises(InputError, match="vertex file .*absent.txt: cannot read"):
        shapes.read_vertices(tmp_path / "absent.txt")
    binary = tmp_path / "shape.bin"
    binary.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(InputError, match="vertex file .*shape.bin: not a text file"):
        shapes.read_vertices(binary)
