"""Observables of the whole system, summed in a fixed order.

Contact energies and force components are recomputed here from the positions and the
stored contact forces, so the stepping loop stores no more per contact than it steps with.
"""

import math
from dataclasses import dataclass

import numba
import numpy as np

from revdem_cli.kernels import jit
from revdem_cli.kernels.cell import images
from revdem_cli.kernels.contact import NO_ROLLING, NO_SHEAR, contact_energy
from revdem_cli.kernels.pairs import pair_geometry, separation
from revdem_cli.kernels.stress import stress_of
from revdem_cli.kernels.sums import blocks_of, by_blocks, span
from revdem_cli.kernels.tape import MECHANISMS
from revdem_cli.kernels.vectors import ZERO, axpy, cell_of, dot, norm, row
from revdem_cli.kernels.wall_contacts import wall_normal

SCALARS = (
    "kinetic_energy",  # translational and rotational, J
    "elastic_energy",  # normal and tangential springs, J
    "potential_energy",  # gravitational, -m g.x, J
    "total_energy",  # J
    "max_normal_force",  # largest normal force magnitude over all contacts, N
    "max_shear_force",  # largest shear force magnitude over all contacts, N
    "coordination_number",  # 2 x particle-particle contacts / particles
)
"""The first columns of an observables row (`Layout`)."""

CONTACT_FABRIC = (
    ("fabric", (3, 3)),  # <n (x) n> over the sphere contacts, -
    ("mechanical_coordination_number", ()),  # rattlers excluded (Thornton 2000)
    ("sliding_fraction", ()),  # contacts at the Coulomb cap in the last step, -
)
"""Columns `observe` writes after the cell's (`contact_fabric`)."""

CELL_STATE = (
    ("void_ratio", ()),  # cell volume / spheres' volume - 1, -
    ("mean_stress", ()),  # p, Pa (compression positive)
    ("deviator_stress", ()),  # q, Pa
)
"""Columns the engine derives in a periodic cell (`stage.Model.complete`)."""

WALL_FORCES = len(SCALARS)
"""Column of an observables row where the first wall's force begins; the wall positions
follow the forces of all walls."""


@dataclass(frozen=True)
class Layout:
    """The columns of an observables row, the one layout `observe` writes, the engine
    completes and stops on, the trajectory stores and the figures read: SCALARS, the force
    on each wall (N, 3 columns) and its reference point (m, 3); in a periodic cell the
    average stress (Pa, 9, row by row) and the edge lengths (m, 3); the fabric of the
    sphere contacts, the mechanical coordination number and the sliding fraction
    (CONTACT_FABRIC); then the observables derived from those by the engine: the solid
    fraction of a [solid_fraction] container, in a periodic cell the principal stresses
    (Pa, 3, largest first) and CELL_STATE, and the fabric's deviatoric invariant; with an
    information tape, the bits it recorded from the stage's start, by mechanism (written by
    the engine going forward, NaN reversed)."""

    walls: tuple[str, ...]
    periodic: bool
    container: bool  # a [solid_fraction] container
    taped: bool = False  # an information tape: the bits it recorded (`kernels.tape`)

    def series(self) -> list[tuple[str, tuple[int, ...]]]:
        """(name, shape) of every observable, in column order."""
        return (
            [(name, ()) for name in SCALARS]
            + [(f"wall_force/{name}", (3,)) for name in self.walls]
            + [(f"wall_position/{name}", (3,)) for name in self.walls]
            + ([("stress", (3, 3)), ("cell_length", (3,))] if self.periodic else [])
            + list(CONTACT_FABRIC)
            + ([("solid_fraction", ())] if self.container else [])
            + ([("principal_stress", (3,))] if self.periodic else [])
            + (list(CELL_STATE) if self.periodic else [])
            + [("fabric_deviator", ())]
            + ([("bits_destroyed", (len(MECHANISMS),))] if self.taped else [])
        )

    @property
    def width(self) -> int:
        """Columns of a row."""
        return sum(_size(shape) for _, shape in self.series())

    def column(self, name: str) -> int:
        """Column where observable `name` begins."""
        series = self.series()
        k = [n for n, _ in series].index(name)
        return sum(_size(shape) for _, shape in series[:k])


def _size(shape: tuple[int, ...]) -> int:
    return math.prod(shape)


@jit
def normal_and_shear(f, n, shear_law):
    """(|normal component|, |shear component|) of a contact force f across normal n: the
    shear component as |f - (f.n) n|, to round-off of |f| (from |f|^2 - (f.n)^2 it was of
    order 1e-8 |f|), and 0 without a shear law, which exerts none."""
    fn = dot(f, n)
    if not shear_law:
        return abs(fn), 0.0
    return abs(fn), norm(axpy(-fn, n, f))


def _particle_energies(x, v, w, mass, inertia, gravity, partials):
    """Kinetic and gravitational energy of each block of particles, partials[b, 0:2]."""
    n = x.shape[0]
    g = (gravity[0], gravity[1], gravity[2])
    for b in numba.prange(blocks_of(n)):
        kinetic = 0.0
        potential = 0.0
        lo, hi = span(b, n)
        for q in range(lo, hi):
            v2 = v[q, 0] ** 2 + v[q, 1] ** 2 + v[q, 2] ** 2
            w2 = w[q, 0] ** 2 + w[q, 1] ** 2 + w[q, 2] ** 2
            kinetic += 0.5 * mass[q] * v2 + 0.5 * inertia[q] * w2
            potential -= mass[q] * (g[0] * x[q, 0] + g[1] * x[q, 1] + g[2] * x[q, 2])
        partials[b, 0] = kinetic
        partials[b, 1] = potential


def _pair_energies(
    x, radius, material, estar, gstar, image, pi, pj, first, force, history, rolling, law,
    partials,
):  # fmt: skip
    """Of the pairs listed under each block of particles, in list order: elastic energy,
    largest normal and shear force, contacts, partials[b, 0:4]. A pair is in contact where
    the pair loop takes it to be."""
    n = x.shape[0]
    shear_law = law.tangential != NO_SHEAR
    rolls = law.rolling != NO_ROLLING
    for b in numba.prange(blocks_of(n)):
        elastic = 0.0
        max_normal = 0.0
        max_shear = 0.0
        contacts = 0
        lo, hi = span(b, n)
        for k in range(first[lo], first[hi]):
            i, j = pi[k], pj[k]
            overlap, n_ij, rstar = pair_geometry(separation(x, i, j, image), radius[i], radius[j])
            if overlap <= 0.0:
                continue
            contacts += 1
            m_i, m_j = material[i], material[j]
            shear = row(history, k) if shear_law else ZERO
            turned = row(rolling, k) if rolls else ZERO
            e, g = estar[m_i, m_j], gstar[m_i, m_j]
            elastic += contact_energy(law, overlap, rstar, e, g, shear, turned)
            fn, fs = normal_and_shear(row(force, k), n_ij, shear_law)
            max_normal = max(max_normal, fn)
            max_shear = max(max_shear, fs)
        partials[b, 0] = elastic
        partials[b, 1] = max_normal
        partials[b, 2] = max_shear
        partials[b, 3] = contacts


@jit
def contact_fabric(x, radius, image, pi, pj, count, destroyed, shear_law, out):
    """Of the sphere contacts, in pair-list order: out[0:9] the fabric tensor of their unit
    normals, Phi = <n (x) n> (Satake 1982), 0 without contacts; out[9] the mechanical
    coordination number, rattlers excluded, Z_m = (2C - N_1) / (N - N_0 - N_1) with N_0 and
    N_1 the spheres of no and of one contact (Thornton 2000), 0 where every sphere is one;
    out[10] the fraction of the contacts whose shear force the Coulomb cap cut in the last
    step (Hanley 2020 §5.1), 0 without a shear law. A pair is in contact where the pair loop
    takes it to be."""
    n = x.shape[0]
    touches = np.zeros(n, dtype=np.int64)
    phi = np.zeros(9)
    contacts = 0
    sliding = 0
    for k in range(count):
        i, j = pi[k], pj[k]
        overlap, nk, _ = pair_geometry(separation(x, i, j, image), radius[i], radius[j])
        if overlap <= 0.0:
            continue
        contacts += 1
        touches[i] += 1
        touches[j] += 1
        for a in range(3):
            for b in range(3):
                phi[3 * a + b] += nk[a] * nk[b]
        if shear_law and destroyed[k] > 0.0:
            sliding += 1
    none = 0
    one = 0
    for q in range(n):
        if touches[q] == 0:
            none += 1
        elif touches[q] == 1:
            one += 1
    for c in range(11):
        out[c] = 0.0
    if contacts > 0:
        for c in range(9):
            out[c] = phi[c] / contacts
        out[10] = sliding / contacts
    if n - none - one > 0:
        out[9] = (2.0 * contacts - one) / (n - none - one)


particle_energies = by_blocks(_particle_energies)
pair_energies = by_blocks(_pair_energies)


@jit
def observe(p, pairs, walls, cell, law, moduli, dyn, row_out):
    """Fill the columns `Layout` gives `observe` of row_out: SCALARS, each wall's force, each
    wall's position, and in a periodic cell the stress and the edges. Particles and pairs
    are summed in blocks (`kernels.sums`), then the wall contacts in order."""
    count = p.x.shape[0]
    parts = pairs.partials
    bodies = (p.x, p.v, p.omega, p.mass, p.inertia, dyn.gravity, parts)
    particle_energies(count, *bodies)
    kinetic = 0.0
    potential = 0.0
    for b in range(blocks_of(count)):
        kinetic += parts[b, 0]
        potential += parts[b, 1]
    contact_args = (
        p.x, p.radius, p.material, moduli.estar, moduli.gstar, images(cell), pairs.i, pairs.j,
        pairs.first, pairs.force, pairs.history, pairs.rolling, law, parts,
    )  # fmt: skip
    pair_energies(count, *contact_args)
    elastic = 0.0
    max_normal = 0.0
    max_shear = 0.0
    contacts = 0
    for b in range(blocks_of(count)):
        elastic += parts[b, 0]
        max_normal = max(max_normal, parts[b, 1])
        max_shear = max(max_shear, parts[b, 2])
        contacts += int(parts[b, 3])
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
                turned = cell_of(walls.rolling, q, b) if law.rolling != NO_ROLLING else ZERO
                e, g = moduli.estar[m, mw], moduli.gstar[m, mw]
                elastic += contact_energy(law, overlap, p.radius[q], e, g, shear, turned)
                f = cell_of(walls.force, q, b)
                fn, fs = normal_and_shear(f, n, law.tangential != NO_SHEAR)
                max_normal = max(max_normal, fn)
                max_shear = max(max_shear, fs)
                for c in range(3):
                    row_out[WALL_FORCES + 3 * b + c] -= f[c]
    for b in range(nwalls):
        for c in range(3):
            row_out[WALL_FORCES + 3 * (nwalls + b) + c] = walls.point[b, c]
    row_out[0] = kinetic
    row_out[1] = elastic
    row_out[2] = potential
    row_out[3] = kinetic + elastic + potential
    row_out[4] = max_normal
    row_out[5] = max_shear
    row_out[6] = 2.0 * contacts / p.x.shape[0]
    at = WALL_FORCES + 6 * nwalls
    if cell.periodic[0] or cell.periodic[1] or cell.periodic[2]:
        stress = np.zeros((3, 3))  # the cell's own, which a servo reads, left as it is
        stress_of(p, pairs, cell, stress)
        for a in range(3):
            for c in range(3):
                row_out[at + 3 * a + c] = stress[a, c]
            row_out[at + 9 + a] = cell.length[a]
        at += 12
    fabric_args = (p.x, p.radius, images(cell), pairs.i, pairs.j, pairs.count[0], pairs.destroyed)
    contact_fabric(*fabric_args, law.tangential != NO_SHEAR, row_out[at : at + 11])
