"""Observables of the whole system, summed in a fixed order."""

import math

from revdem_cli.kernels import jit

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
wall (the force on it, N), then 3 per wall (its reference point, m)."""

WALL_FORCES = 1 + len(SCALARS)
"""Column of an observables row where the first wall's force begins; the wall positions
follow the forces of all walls."""


@jit
def observe(p, pairs, walls, dyn, row):
    """Fill row[1:] with SCALARS, each wall's force, then each wall's position (row[0] holds
    the step)."""
    g = dyn.gravity
    kinetic = 0.0
    potential = 0.0
    for q in range(p.x.shape[0]):
        v2 = p.v[q, 0] ** 2 + p.v[q, 1] ** 2 + p.v[q, 2] ** 2
        w2 = p.omega[q, 0] ** 2 + p.omega[q, 1] ** 2 + p.omega[q, 2] ** 2
        kinetic += 0.5 * p.mass[q] * v2 + 0.5 * p.inertia[q] * w2
        potential -= p.mass[q] * (g[0] * p.x[q, 0] + g[1] * p.x[q, 1] + g[2] * p.x[q, 2])
    elastic = 0.0
    max_normal = 0.0
    max_shear = 0.0
    contacts = 0
    for k in range(pairs.count[0]):
        if pairs.energy[k] > 0.0:
            contacts += 1
            elastic += pairs.energy[k]
            f2 = pairs.force[k, 0] ** 2 + pairs.force[k, 1] ** 2 + pairs.force[k, 2] ** 2
            max_normal = max(max_normal, abs(pairs.normal[k]))
            max_shear = max(max_shear, math.sqrt(max(f2 - pairs.normal[k] ** 2, 0.0)))
    nwalls = walls.force.shape[1]
    for b in range(nwalls):
        row[WALL_FORCES + 3 * b : WALL_FORCES + 3 * b + 3] = 0.0
    for q in range(p.x.shape[0]):
        for b in range(nwalls):
            if walls.energy[q, b] > 0.0:
                elastic += walls.energy[q, b]
                f = walls.force[q, b]
                f2 = f[0] ** 2 + f[1] ** 2 + f[2] ** 2
                max_normal = max(max_normal, abs(walls.normal[q, b]))
                max_shear = max(max_shear, math.sqrt(max(f2 - walls.normal[q, b] ** 2, 0.0)))
                for d in range(3):
                    row[WALL_FORCES + 3 * b + d] -= f[d]
    for b in range(nwalls):
        for d in range(3):
            row[WALL_FORCES + 3 * (nwalls + b) + d] = walls.point[b, d]
    row[1] = kinetic
    row[2] = elastic
    row[3] = potential
    row[4] = kinetic + elastic + potential
    row[5] = max_normal
    row[6] = max_shear
    row[7] = 2.0 * contacts / p.x.shape[0]
