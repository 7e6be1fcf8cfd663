"""Observables of the whole system, summed in a fixed order.

Contact energies and force components are recomputed here from the positions and the
stored contact forces, so the stepping loop stores no more per contact than it steps with.
"""

import math

from revdem_cli.kernels import jit
from revdem_cli.kernels.cell import images
from revdem_cli.kernels.contact import NO_SHEAR, contact_energy, dot
from revdem_cli.kernels.forces import (
    ZERO,
    cell_of,
    pair_overlap,
    row,
    separation,
    stress_of,
    wall_normal,
)

SCALARS = (
    "kinetic_energy",  # translational and rotational, J
    "elastic_energy",  # normal and tangential springs, J
    "potential_energy",  # gravitational, -m g.x, J
    "total_energy",  # J
    "max_normal_force",  # largest normal force magnitude over all contacts, N
    "max_shear_force",  # largest shear force magnitude over all contacts, N
    "coordination_number",  # 2 x particle-particle contacts / particles
)
"""Scalar columns of an observables row after its leading step column; then 3 columns per
wall (the force on it, N), then 3 per wall (its reference point, m); then, in a periodic
cell, the 9 of the average stress (Pa, row by row) and the 3 edge lengths (m)."""

WALL_FORCES = 1 + len(SCALARS)
"""Column of an observables row where the first wall's force begins; the wall positions
follow the forces of all walls."""


@jit
def normal_and_shear(f, n):
    """(|normal component|, |shear component|) of a contact force f across normal n."""
    fn = dot(f, n)
    return abs(fn), math.sqrt(max(dot(f, f) - fn * fn, 0.0))


@jit
def observe(p, pairs, walls, cell, law, moduli, dyn, row_out):
    """Fill row_out[1:] with SCALARS, each wall's force, each wall's position, and in a
    periodic cell the stress and the edges (row_out[0] holds the step)."""
    g = dyn.gravity
    kinetic = 0.0
    potential = 0.0
    for q in range(p.x.shape[0]):
        v2 = p.v[q, 0] ** 2 + p.v[q, 1] ** 2 + p.v[q, 2] ** 2
        w2 = p.omega[q, 0] ** 2 + p.omega[q, 1] ** 2 + p.omega[q, 2] ** 2
        kinetic += 0.5 * p.mass[q] * v2 + 0.5 * p.inertia[q] * w2
        potential -= p.mass[q] * (g[0] * p.x[q, 0] + g[1] * p.x[q, 1] + g[2] * p.x[q, 2])
    shear_law = law.tangential != NO_SHEAR
    elastic = 0.0
    max_normal = 0.0
    max_shear = 0.0
    contacts = 0
    image = images(cell)
    for k in range(pairs.count[0]):
        i, j = pairs.i[k], pairs.j[k]
        d = separation(p.x, i, j, image)
        reach = p.radius[i] + p.radius[j]
        overlap, dist = pair_overlap(d, reach)  # as the pair loop decides contact
        if overlap <= 0.0:
            continue
        contacts += 1
        a, b = p.material[i], p.material[j]
        shear = row(pairs.history, k) if shear_law else ZERO
        rstar = p.radius[i] * p.radius[j] / reach
        elastic += contact_energy(
            law, overlap, rstar, moduli.estar[a, b], moduli.gstar[a, b], shear
        )
        n = (d[0] / dist, d[1] / dist, d[2] / dist)
        fn, fs = normal_and_shear(row(pairs.force, k), n)
        max_normal = max(max_normal, fn)
        max_shear = max(max_shear, fs)
    nwalls = walls.force.shape[1]
    for b in range(nwalls):
        row_out[WALL_FORCES + 3 * b : WALL_FORCES + 3 * b + 3] = 0.0
    for q in range(p.x.shape[0]):
        for b in range(nwalls):
            overlap = walls.overlap[q, b]
            if overlap > 0.0:
                n = wall_normal(p, walls, q, b)
                m, mw = p.material[q], walls.material[b]
                shear = cell_of(walls.history, q, b)
                elastic += contact_energy(
                    law, overlap, p.radius[q], moduli.estar[m, mw], moduli.gstar[m, mw], shear
                )
                f = cell_of(walls.force, q, b)
                fn, fs = normal_and_shear(f, n)
                max_normal = max(max_normal, fn)
                max_shear = max(max_shear, fs)
                for c in range(3):
                    row_out[WALL_FORCES + 3 * b + c] -= f[c]
    for b in range(nwalls):
        for c in range(3):
            row_out[WALL_FORCES + 3 * (nwalls + b) + c] = walls.point[b, c]
    row_out[1] = kinetic
    row_out[2] = elastic
    row_out[3] = potential
    row_out[4] = kinetic + elastic + potential
    row_out[5] = max_normal
    row_out[6] = max_shear
    row_out[7] = 2.0 * contacts / p.x.shape[0]
    if cell.periodic[0] or cell.periodic[1] or cell.periodic[2]:
        stress_of(p, pairs, cell)
        at = WALL_FORCES + 6 * nwalls
        for a in range(3):
            for c in range(3):
                row_out[at + 3 * a + c] = cell.stress[a, c]
            row_out[at + 9 + a] = cell.length[a]
