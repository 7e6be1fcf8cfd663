"""Scalar observables of the whole system, summed in a fixed order."""

from revdem_cli.kernels import jit

NAMES = ("kinetic_energy", "elastic_energy", "potential_energy", "total_energy")
"""Column names of an observables row after its leading step column."""


@jit
def observe(p, pairs, gravity, row):
    """Fill row[1:] with the observables named in NAMES (row[0] holds the step)."""
    kinetic = 0.0
    potential = 0.0
    for q in range(p.x.shape[0]):
        v2 = p.v[q, 0] ** 2 + p.v[q, 1] ** 2 + p.v[q, 2] ** 2
        w2 = p.omega[q, 0] ** 2 + p.omega[q, 1] ** 2 + p.omega[q, 2] ** 2
        kinetic += 0.5 * p.mass[q] * v2 + 0.5 * p.inertia[q] * w2
        potential -= p.mass[q] * (
            gravity[0] * p.x[q, 0] + gravity[1] * p.x[q, 1] + gravity[2] * p.x[q, 2]
        )
    elastic = 0.0
    for k in range(pairs.count[0]):
        elastic += pairs.energy[k]
    row[1] = kinetic
    row[2] = elastic
    row[3] = potential
    row[4] = kinetic + elastic + potential
