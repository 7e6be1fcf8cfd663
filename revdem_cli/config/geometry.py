"""The spheres of a scenario: generated from its tables, and checked where they start
(inside the cell, inside the walls, not overlapping). `loader` runs the checks on every
scenario file; a scenario stored in an output was checked when it was run."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from revdem_cli import wall_shapes
from revdem_cli.assembly.spheres import Spheres, numbered
from revdem_cli.config.checks import FieldError


def check_spheres(scenario) -> None:
    """Generate the scenario's spheres and check where they start; FieldError naming the
    first sphere that cannot start there."""
    check_resolved(scenario)
    check_inside_cell(scenario)
    check_overlaps(scenario)
    check_walls(scenario)


def generate(scenario) -> Spheres:
    """The spheres of a scenario's tables: those given one by one, then the packings' and the
    lattices'; FieldError where a packing's region cannot take its spheres."""
    from revdem_cli.assembly.packing import PackingError

    materials = tuple(scenario.materials)
    given = Spheres(
        np.array([p.radius for p in scenario.particles], dtype=np.float64),
        np.array([p.position for p in scenario.particles], dtype=np.float64).reshape(-1, 3),
        np.array([p.velocity for p in scenario.particles], dtype=np.float64).reshape(-1, 3),
        np.array([p.angular_velocity for p in scenario.particles], dtype=np.float64).reshape(-1, 3),
        np.array([materials.index(p.material) for p in scenario.particles], dtype=np.int64),
        materials,
        numbered(len(scenario.particles)),
    )
    parts = [given]
    for i, packing in enumerate(scenario.packings):
        try:
            parts.append(packing_spheres(packing, materials))
        except PackingError as exc:
            raise FieldError(f"packings[{i}]", str(exc)) from None
    parts += [lattice_spheres(lattice, materials) for lattice in scenario.lattices]
    parts += [
        spheres_from(source, f"particles_from[{i}]", scenario, materials)
        for i, source in enumerate(scenario.particles_from)
    ]
    spheres = Spheres.join(parts, materials)
    if not len(spheres):
        raise FieldError(
            "particles",
            "no spheres: give [[particles]], [[packings]], [[lattices]] or [[particles_from]]",
        )
    return spheres


def packing_spheres(packing, materials: tuple[str, ...]) -> Spheres:
    """The spheres of a [[packings]] table, numbered in space (`spatial_order`); raises
    PackingError if its region cannot take them."""
    from revdem_cli.assembly.packing import place_spheres, spatial_order
    from revdem_cli.assembly.spheres import uniform

    rng = np.random.default_rng(packing.seed)
    radii = rng.uniform(packing.radius_min, packing.radius_max, packing.count)
    region = packing.region
    centres = place_spheres(radii, region.shape, region.origin, region.extent, packing.seed + 1)
    order = spatial_order(centres, 2.0 * packing.radius_max)
    radii, centres = radii[order], centres[order]
    material = materials.index(packing.material)
    return uniform(packing.count, radii, material, materials, centres, packing.velocity)


def lattice_spheres(lattice, materials: tuple[str, ...]) -> Spheres:
    """The spheres of a [[lattices]] table."""
    from revdem_cli.assembly.spheres import fcc_positions, uniform

    x = fcc_positions(lattice.cells, lattice.lattice_constant, lattice.origin)
    v = np.array(lattice.velocity) + np.random.default_rng(lattice.seed).uniform(
        -lattice.random_velocity, lattice.random_velocity, x.shape
    )
    return uniform(len(x), lattice.radius, materials.index(lattice.material), materials, x, v)


def spheres_from(source, path: str, scenario, materials: tuple[str, ...]) -> Spheres:
    """The spheres of a [[particles_from]] table, read from its LAMMPS data file: each atom
    type's material, each density that material's (to DENSITY_RTOL); positions as the file
    has them, in an open box inside it with no image flag, in a periodic box (the scenario's
    cell) inside it, from the box's lower corner, their image flags set aside; in the order
    of the atoms' ids, or numbered in space (`spatial_order`)."""
    from revdem_cli.assembly.packing import spatial_order
    from revdem_cli.errors import InputError
    from revdem_cli.io.lammps_data import read_lammps_data

    try:
        data = read_lammps_data(source.lammps_data)
    except InputError as exc:
        raise FieldError(f"{path}.lammps_data", str(exc)) from None
    if len(data) != source.count:
        raise FieldError(f"{path}.count", f"{source.count}, but {data.path} has {len(data)} atoms")
    names = [source.materials.get(str(t)) for t in data.type]
    if None in names:
        missing = int(data.type[names.index(None)])
        raise FieldError(f"{path}.materials", f"no material for atom type {missing} of {data.path}")
    material = np.array([materials.index(name) for name in names], dtype=np.int64)
    density = np.array([scenario.materials[name].density for name in materials])[material]
    off = np.flatnonzero(~(np.abs(data.density - density) <= DENSITY_RTOL * density))
    if len(off):
        k = int(off[0])
        raise FieldError(
            f"{path}.materials.{data.type[k]}",
            f"atom {data.id[k]} of {data.path} has density {data.density[k]:.17g} kg/m^3, its "
            f"material '{names[k]}' {density[k]:.17g}: a sphere's mass comes from its material",
        )
    position = data.position
    if source.periodic:
        edges = data.upper - data.lower
        if not np.allclose(edges, scenario.cell.size, rtol=1e-12, atol=0.0):
            raise FieldError(
                "cell.size",
                f"{list(scenario.cell.size)}, but the periodic box of {data.path} has edges "
                f"{edges.tolist()}",
            )
        # inside the cell, as the file has them, the box moved to start at 0 (the cell's
        position = data.position - data.lower  # [0, L)); displacements count from here
    else:  # an open box holds its atoms, as LAMMPS' read_data demands on a non-periodic axis
        flagged = np.flatnonzero(data.image.any(1))
        if len(flagged):  # a periodic run's: LAMMPS would reset them to 0, moving the atom
            k = int(flagged[0])
            raise FieldError(
                f"{path}.lammps_data",
                f"atom {data.id[k]} of {data.path} has image flags {data.image[k].tolist()}, "
                "but periodic = false: no axis wraps; give periodic = true with the box as "
                "[cell], or image flags 0",
            )
        outside = np.flatnonzero(
            ((data.position < data.lower) | (data.position > data.upper)).any(1)
        )
        if len(outside):
            k = int(outside[0])
            raise FieldError(
                f"{path}.lammps_data",
                f"atom {data.id[k]} of {data.path} lies at {data.position[k].tolist()}, outside "
                f"its box {data.lower.tolist()} to {data.upper.tolist()} (periodic = false: no "
                "axis wraps)",
            )
    spheres = Spheres(
        data.radius, position, data.velocity, data.angular_velocity, material, materials, data.id
    )
    if source.order == "space":
        return spheres.taken(spatial_order(position, 2.0 * data.radius.max()))
    return spheres


DENSITY_RTOL = 1e-9
"""How far a data file's density may be from its material's, relative: LAMMPS writes the
density it recomputes from each sphere's mass, to its last digit or two."""

RESOLUTION = 1e-6
"""A position must be resolved by float64 to this fraction of its sphere's radius (the
spacing of float64 at |x| is |x| 2^-52): at most about 4.5e9 radii from the origin."""


def check_resolved(scenario) -> None:
    """Every sphere starts where float64 resolves its position to RESOLUTION of its radius:
    farther out, a step's motion is lost to round-off (at 1e17 m a position moves in steps
    of 16 m)."""
    spheres = scenario.spheres
    spacing = np.spacing(np.abs(spheres.position)).max(axis=1)
    far = np.nonzero(~(spacing <= RESOLUTION * spheres.radius))[0]
    if len(far):
        k = int(far[0])
        where, sphere = located(scenario, k)
        raise FieldError(
            where,
            f"{sphere} starts {float(np.abs(spheres.position[k]).max()):.3g} m from the "
            f"origin, where float64 resolves a position only to {float(spacing[k]):.3g} m, "
            f"more than {RESOLUTION:g} of its radius {float(spheres.radius[k]):.3g} m: move "
            "the scenario's origin closer",
        )


def check_inside_cell(scenario) -> None:
    """Every sphere starts inside the periodic box, which is more than twice as wide as
    the contact reach (2 r_max + skin), so that two spheres touch through one image."""
    if scenario.cell is None:
        return
    x = scenario.spheres.position
    size = np.array(scenario.cell.size)
    outside = np.nonzero(((x < 0.0) | (x >= size)).any(axis=1))[0]
    if len(outside):
        where, sphere = located(scenario, int(outside[0]))
        raise FieldError(where, f"{sphere} starts outside the cell [0, L) of size {size.tolist()}")
    r_max = float(scenario.spheres.radius.max())
    reach = 2.0 * r_max + (scenario.neighbours.skin or 0.1 * r_max)
    for axis, edge in zip("xyz", size, strict=True):
        if edge <= 2.0 * reach:
            raise FieldError(
                "cell.size",
                f"edge {axis} = {edge:.4g} m is not more than twice the contact reach "
                f"2 r_max + skin = {reach:.4g} m",
            )


def check_overlaps(scenario) -> None:
    """Spheres may touch, or overlap by up to 1 % of the smaller radius (a contact already
    loaded), no more, but two of one data file by up to its `max_overlap` (a loaded packing,
    `ParticlesFrom`); in a periodic cell, through the nearest image."""
    from scipy.spatial import cKDTree

    from revdem_cli.config.schema import OVERLAP_AT_START

    x, r = scenario.spheres.position, scenario.spheres.radius
    size = np.array(scenario.cell.size) if scenario.cell else None
    pairs = cKDTree(x, boxsize=size).query_pairs(2.0 * r.max(), output_type="ndarray")
    if not len(pairs):
        return
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    i, j = pairs[:, 0], pairs[:, 1]
    d = x[j] - x[i]
    if size is not None:
        d -= size * np.round(d / size)
    gap = np.linalg.norm(d, axis=1) - r[i] - r[j]
    source, allowed = _data_files(scenario)
    own = (source[i] == source[j]) & (source[i] >= 0)
    depth = np.where(own, allowed[np.maximum(source[i], 0)], OVERLAP_AT_START)
    bad = np.nonzero(gap < -depth * np.minimum(r[i], r[j]))[0]
    if len(bad):
        k = bad[0]
        where, sphere = located(scenario, int(j[k]))
        share = -gap[k] / min(r[i[k]], r[j[k]])
        more = f"; a loaded packing: particles_from[{source[j[k]]}].max_overlap" if own[k] else ""
        raise FieldError(
            where,
            f"{sphere} overlaps {located(scenario, int(i[k]))[1]} by {-gap[k]:.3g} m, "
            f"{100 * share:.2g} % of the smaller radius (at most {100 * depth[k]:g} %{more})",
        )


def _data_files(scenario) -> tuple[np.ndarray, np.ndarray]:
    """(the index in particles_from of each sphere's data file, -1 for a sphere of another
    table; each data file's max_overlap)."""
    source = np.full(len(scenario.spheres.radius), -1, dtype=np.int64)
    start = len(scenario.particles) + sum(t.count for t in (*scenario.packings, *scenario.lattices))
    for k, table in enumerate(scenario.particles_from):
        source[start : start + table.count] = k
        start += table.count
    return source, np.array([t.max_overlap for t in scenario.particles_from] or [0.0])


def check_walls(scenario) -> None:
    """Every sphere starts inside the walls (`wall_shapes`: on the inner side of every plane,
    inside every cylinder), reaching past a wall by at most 1 % of its radius."""
    if not scenario.walls:
        return
    x, r = scenario.spheres.position, scenario.spheres.radius
    for wall in scenario.walls:
        shape = wall_shapes.SHAPES[wall.type]
        with np.errstate(all="ignore"):
            past = shape.reach_past(wall, x, r)
            outside = np.nonzero(~(past <= 1e-2 * r))[0]
        if len(outside):
            j = int(outside[0])
            where, sphere = located(scenario, j)
            raise FieldError(
                where,
                f"{sphere} (radius {r[j]:.3g} m) reaches {past[j]:.3g} m past the {wall.type} "
                f"wall '{wall.name}', more than 1 % of its radius: spheres must start "
                f"{shape.SIDE}",
            )


def located(scenario, index: int) -> tuple[str, str]:
    """(field path, name) of sphere `index` of `spheres`: particles[i].position and
    'sphere i of particles', packings[k] and 'sphere m of packings[k]', or particles_from[k]
    and 'atom a of FILE', the atom's id in its data file (named without its folder)."""
    if index < len(scenario.particles):
        return f"particles[{index}].position", f"sphere {index} of particles"
    sources = [("packings", k, p) for k, p in enumerate(scenario.packings)]
    sources += [("lattices", k, g) for k, g in enumerate(scenario.lattices)]
    sources += [("particles_from", k, g) for k, g in enumerate(scenario.particles_from)]
    start = len(scenario.particles)  # the table's first sphere
    for kind, k, source in sources:
        if index < start + source.count:
            if kind == "particles_from":
                atom = scenario.spheres.table_id(index, start)
                return f"{kind}[{k}]", f"atom {atom} of {Path(source.lammps_data).name}"
            return f"{kind}[{k}]", f"sphere {index - start} of {kind}[{k}]"
        start += source.count
    raise IndexError(index)
