"""Convex, centrally symmetric particles: volume, mass, principal moments, bounding box.

Every shape is reduced to a `Body`: what the critical time step criteria of Peng, Burns &
Hanley (2020) need to know about a particle. Lengths in m, density in kg/m³.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from revdem_cli.errors import InputError, check_regular

# Relative tolerance (times the particle diameter) of the polyhedron checks.
GEOMETRY_RTOL = 1e-6


@dataclass(frozen=True)
class Body:
    """A rigid particle in its principal frame.

    `moments` are the principal moments of inertia in ascending order (kg m²);
    `half_lengths` are the half-lengths of the bounding box in the principal frame in
    descending order, the paper's a ≥ b ≥ c (m); `reach` is the distance from the centre to
    the farthest point of the surface (m), the lever arm Eq 26 takes (`criteria.a_max`): a
    for an ellipsoid, a corner of a box-like superquadric or of a polyhedron. A superquadric
    (an ellipsoid or sphere included) also keeps its `surface`, (a, b, c, ε1, ε2) on its body
    axes x, y, z as given, and its principal moments on those axes, `axis_moments` (kg m²);
    a polyhedron has None.
    """

    shape: str
    volume: float
    mass: float
    moments: tuple[float, float, float]
    half_lengths: tuple[float, float, float]
    reach: float
    surface: tuple[float, float, float, float, float] | None = None
    axis_moments: tuple[float, float, float] | None = None


def _body(shape, volume, density, second_moments, half_lengths, reach, exponents=None) -> Body:
    """A Body from its volume and the principal second moments of volume ∫x², ∫y², ∫z²;
    with `exponents` (ε1, ε2), a superquadric that keeps its surface and axis moments."""
    jx, jy, jz = second_moments
    moments = tuple(
        float(i) for i in (density * (jy + jz), density * (jx + jz), density * (jx + jy))
    )
    surface = None if exponents is None else tuple(float(v) for v in (*half_lengths, *exponents))
    return Body(
        shape=shape,
        volume=float(volume),
        mass=float(density * volume),
        moments=tuple(sorted(moments)),
        half_lengths=tuple(sorted((float(h) for h in half_lengths), reverse=True)),
        reach=float(reach),
        surface=surface,
        axis_moments=None if exponents is None else moments,
    )


def ellipsoid(a: float, b: float, c: float, density: float) -> Body:
    """Solid ellipsoid with semi-axes a, b, c."""
    volume = 4.0 / 3.0 * math.pi * a * b * c
    second_moments = (volume * a**2 / 5.0, volume * b**2 / 5.0, volume * c**2 / 5.0)
    reach = superquadric_reach(a, b, c, 1.0, 1.0)
    return _body("ellipsoid", volume, density, second_moments, (a, b, c), reach, (1.0, 1.0))


def sphere(radius: float, density: float) -> Body:
    """Solid sphere (I = 2/5 m r²)."""
    return replace(ellipsoid(radius, radius, radius, density), shape="sphere")


def _superquadric_octant_integral(p: float, q: float, r: float, eps1: float, eps2: float):
    """∫ X^(p-1) Y^(q-1) Z^(r-1) dV over the positive octant of the unit superquadric.

    Two nested Dirichlet integrals (Prudnikov, Brychkov & Marichev 1986, 3.2.2.2): the
    superellipse (X^s + Y^s)^(1/s) ≤ ρ in the plane, then ρ^t + Z^t ≤ 1, s = 2/ε2, t = 2/ε1.
    """
    s, t = 2.0 / eps2, 2.0 / eps1
    planar = math.gamma(p / s) * math.gamma(q / s) / (s**2 * math.gamma((p + q) / s + 1.0))
    axial = math.gamma((p + q) / t) * math.gamma(r / t) / (t**2 * math.gamma((p + q + r) / t + 1.0))
    return (p + q) * planar * axial


def superquadric(a: float, b: float, c: float, eps1: float, eps2: float, density: float) -> Body:
    """Solid superquadric (Barr 1981) ((|x/a|^(2/ε2) + |y/b|^(2/ε2))^(ε2/ε1) + |z/c|^(2/ε1) ≤ 1.

    ε1 = ε2 = 1 is the ellipsoid, ε → 0 the box, ε1 = ε2 = 2 the octahedron; convex for
    0 < ε ≤ 2. The blockiness exponents n of DEM codes are n = 2/ε.
    """
    octant = 8.0 * a * b * c
    volume = octant * _superquadric_octant_integral(1, 1, 1, eps1, eps2)
    second_moments = (
        octant * a**2 * _superquadric_octant_integral(3, 1, 1, eps1, eps2),
        octant * b**2 * _superquadric_octant_integral(1, 3, 1, eps1, eps2),
        octant * c**2 * _superquadric_octant_integral(1, 1, 3, eps1, eps2),
    )
    reach = superquadric_reach(a, b, c, eps1, eps2)
    return _body("superquadric", volume, density, second_moments, (a, b, c), reach, (eps1, eps2))


def _farthest(big: float, small: float, eps: float) -> float:
    """max of A u^ε + B (1 - u)^ε over 0 ≤ u ≤ 1, A, B ≥ 0: the squared distance to the
    farthest point of the superellipse (|x|/√A)^(2/ε) + (|y|/√B)^(2/ε) = 1, in the direction
    u = cos² of its angle. For ε ≥ 1 (convex in u) an end, the larger; else (concave) the
    inner maximum (A^(1/(1-ε)) + B^(1/(1-ε)))^(1-ε) (Hölder's inequality, attained), written
    over the larger term so that no power overflows."""
    larger, smaller = max(big, small), min(big, small)
    if eps >= 1.0 or smaller == 0.0:
        return larger
    return larger * (1.0 + (smaller / larger) ** (1.0 / (1.0 - eps))) ** (1.0 - eps)


def superquadric_reach(a: float, b: float, c: float, eps1: float, eps2: float) -> float:
    """The distance from the centre to the farthest point of Barr's surface x = a cos^ε1 η
    cos^ε2 ω, y = b cos^ε1 η sin^ε2 ω, z = c sin^ε1 η: |x|² = cos^2ε1 η (a² cos^2ε2 ω +
    b² sin^2ε2 ω) + c² sin^2ε1 η, greatest over ω first, then over η (`_farthest` twice):
    a for an ellipsoid or an octahedron (ε ≥ 1), the corner √(a² + b² + c²) as ε → 0."""
    return math.sqrt(_farthest(_farthest(a * a, b * b, eps2), c * c, eps1))


def _tetrahedra_moments(tetrahedra: np.ndarray) -> tuple[float, np.ndarray]:
    """Volume and second-moment tensor ∫ x xᵀ dV of tetrahedra with one vertex at the origin.

    `tetrahedra` has shape (n, 3, 3): the three other vertices of each tetrahedron.
    For a tetrahedron with vertices v0..v3: ∫ x xᵀ dV = V/20 (Σ vᵢvᵢᵀ + (Σ vᵢ)(Σ vᵢ)ᵀ).
    """
    volumes = np.abs(np.linalg.det(tetrahedra)) / 6.0
    vertex_sum = tetrahedra.sum(axis=1)
    outer = np.einsum("nki,nkj->nij", tetrahedra, tetrahedra)
    outer += np.einsum("ni,nj->nij", vertex_sum, vertex_sum)
    return float(volumes.sum()), np.einsum("n,nij->ij", volumes / 20.0, outer)


SYMMETRY_BASES = 8  # hull vertices whose midpoints with every other propose a centre
SYMMETRY_CANDIDATES = 16  # the most proposed centres, each tested


def _symmetry_centre(corners: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """The centre of a centrally symmetric set of hull vertices and which of them have a
    mirror image through it (within `tolerance`). Their mean where every vertex has one; else
    the centre through which most do, so that a vertex without a mirror does not move it: each
    vertex paired with its mirror proposes the centre as their midpoint, and the midpoints of
    SYMMETRY_BASES vertices with every vertex proposed most often are tried; the mean again
    where none is shared by more than half of them (a tetrahedron)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(corners)

    def mirrored(centre: np.ndarray) -> np.ndarray:
        return tree.query(2.0 * centre - corners)[0] <= tolerance

    centre = corners.mean(axis=0)
    if mirrored(centre).all():
        return centre, np.ones(len(corners), dtype=bool)
    bases = corners[:SYMMETRY_BASES]
    midpoints = (0.5 * (bases[:, None, :] + corners[None, :, :])).reshape(-1, 3)
    _, first, counts = np.unique(
        np.round(midpoints / tolerance), axis=0, return_index=True, return_counts=True
    )
    proposed = midpoints[first[np.argsort(-counts, kind="stable")[:SYMMETRY_CANDIDATES]]]
    best = max(proposed, key=lambda candidate: mirrored(candidate).sum())
    if 2 * mirrored(best).sum() <= len(corners):  # no centre that most vertices share (a
        return centre, mirrored(centre)  # tetrahedron's edge midpoint pairs 2 of 4): the mean
    return best, mirrored(best)


def polyhedron(vertices: np.ndarray, density: float, source: str) -> Body:
    """Solid convex, centrally symmetric polyhedron: the convex hull of `vertices`.

    The hull is decomposed into tetrahedra that share its centre. `source` names the
    vertices in error messages (the vertex file). Refuses vertex sets that do not span a
    volume, that have a vertex strictly inside the hull of the others (not convex), or
    whose hull vertices have no mirror image through the centre (not centrally symmetric).
    """
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(vertices, dtype=float)
    try:
        hull = ConvexHull(points)
    except QhullError:
        raise InputError(
            f"{source}: the vertices span no volume (need 4 or more points not in one plane)"
        ) from None
    corners = points[hull.vertices]
    tolerance = GEOMETRY_RTOL * np.ptp(corners, axis=0).max()

    depth = (points @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=1)
    inside = np.flatnonzero(depth < -tolerance)
    if inside.size:
        raise InputError(
            f"{source}: vertex {inside[0] + 1} lies inside the hull of the others; "
            "the polyhedron is not convex"
        )

    centre, mirrored = _symmetry_centre(corners, tolerance)
    asymmetric = np.flatnonzero(~mirrored)
    if asymmetric.size:
        raise InputError(
            f"{source}: vertex {hull.vertices[asymmetric[0]] + 1} has no mirror image through "
            f"the centre {np.round(centre, 12).tolist()}; the polyhedron is not centrally symmetric"
        )

    volume, second_moment = _tetrahedra_moments(points[hull.simplices] - centre)
    principal, axes = np.linalg.eigh(second_moment)
    half_lengths = np.abs((corners - centre) @ axes).max(axis=0)
    reach = np.sqrt(((corners - centre) ** 2).sum(axis=1)).max()  # its farthest vertex
    return _body("polyhedron", volume, density, principal, half_lengths, reach)


def _vertex_rows(text: str, path: Path) -> list[tuple[str, object]]:
    """(where, row) of each vertex of a vertex file: JSON ([[x, y, z], ...] or
    {"vertices": [...]}; where: `vertex k`, from 1 as `polyhedron` numbers them) or plain
    text (where: `line n`)."""
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(
                f"vertex file {path}: not valid JSON ({exc.msg}, line {exc.lineno})"
            ) from None
        rows = data["vertices"] if isinstance(data, dict) and "vertices" in data else data
        if not isinstance(rows, list):
            raise InputError(f"vertex file {path}: expected a list of vertices [x, y, z]")
        return [(f"vertex {k}", row) for k, row in enumerate(rows, start=1)]
    lines = (line.split("#", 1)[0].replace(",", " ").split() for line in text.splitlines())
    return [(f"line {n}", fields) for n, fields in enumerate(lines, start=1) if fields]


def read_vertices(path: Path) -> np.ndarray:
    """Vertices (n, 3) from a JSON or plain-text file (one `x y z` a line, # comments)."""
    check_regular(path, "vertex file")
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise InputError(f"vertex file {path}: cannot read it ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise InputError(f"vertex file {path}: not a text file") from None
    rows = _vertex_rows(text, Path(path))
    if not rows:
        raise InputError(
            f"vertex file {path}: holds no vertices (a polyhedron needs 4 or more points not "
            "in one plane)"
        )
    for where, row in rows:
        try:
            point = np.array(row, dtype=float)
        except (TypeError, ValueError):
            point = None
        if point is None or point.shape != (3,):
            raise InputError(
                f"vertex file {path}: {where}: expected three numbers x y z, got {row!r}"
            )
    vertices = np.array([row for _, row in rows], dtype=float).reshape(-1, 3)
    if not np.isfinite(vertices).all():
        raise InputError(f"vertex file {path}: vertex coordinates must be finite numbers")
    return vertices
