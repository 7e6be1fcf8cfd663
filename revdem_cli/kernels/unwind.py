"""The reversed step's first half at the later positions: the shear update of the forward
step undone (the inverse of Hanley 2020 Eq 10 and 9), and the rolling spring's alike, for
every pair and wall contact."""

import numba

from revdem_cli.kernels import by_size, inline, jit
from revdem_cli.kernels.cell import deforms, images, strain_rates
from revdem_cli.kernels.contact import NO_ROLLING, NO_SHEAR, unwind_rolling, unwind_shear
from revdem_cli.kernels.pairs import pair_geometry, pair_velocity, separation
from revdem_cli.kernels.vectors import ZERO, axpy, cell_of, place, put, row
from revdem_cli.kernels.wall_contacts import wall_kinematics


@inline
def unwind_contact(d, r_i, r_j, v_ij, w_i, w_j, gs, shear, moment, law, dt, strain, deforming):
    """A pair at the later positions, separation d, radii r_i, r_j, its centres' relative
    half-step velocity v_ij = v_j - v_i and spins w_i, w_j, G* gs: its shear history `shear`
    with Eq 10 and 9 undone, its rolling history `moment` likewise (as it is without a
    rolling law), and its contact normal there, across which they were unwound (zero where
    the pair is apart, `pair_geometry`: a history turned from it is zero)."""
    overlap, n, rstar = pair_geometry(d, r_i, r_j)
    vrel, spin = pair_velocity(d, n, overlap, r_i, r_j, v_ij, w_i, w_j, strain, deforming)
    shear = unwind_shear(law, dt, overlap, n, rstar, gs, vrel, spin, shear)
    if law.rolling != NO_ROLLING:
        moment = unwind_rolling(law, dt, overlap, n, rstar, w_i, w_j, spin, moment)
    return shear, moment, n


def _unwind_pair_loop(
    x,
    v,
    w,
    radius,
    material,
    gstar,
    image,
    rate,
    length,
    deforming,
    pi,
    pj,
    n_pairs,
    history,
    rolling,
    normal_new,
    law,
    dt,
):
    """Reversed step, before drifting back: undo Eq 10 and 9 for every pair, in place."""
    rolls = law.rolling != NO_ROLLING
    strain = strain_rates(rate, length)
    for k in numba.prange(n_pairs):
        i = pi[k]
        j = pj[k]
        shear, moment, n = unwind_contact(
            separation(x, i, j, image), radius[i], radius[j], axpy(-1.0, row(v, i), row(v, j)),
            row(w, i), row(w, j), gstar[material[i], material[j]], row(history, k),
            row(rolling, k) if rolls else ZERO, law, dt, strain, deforming,
        )  # fmt: skip
        put(history, k, shear)
        if rolls:
            put(rolling, k, moment)
        put(normal_new, k, n)


def _unwind_wall_loop(
    x,
    v,
    w,
    radius,
    material,
    gstar,
    kind,
    point,
    axis,
    wall_radius,
    wall_velocity,
    wall_material,
    history,
    rolling,
    normal_new,
    law,
    dt,
):
    """Reversed step, before drifting back: undo Eq 10 and 9 for every wall contact."""
    rolls = law.rolling != NO_ROLLING
    for q in numba.prange(x.shape[0]):
        for b in range(kind.shape[0]):
            overlap, n, _, vrel, spin = wall_kinematics(
                q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity
            )
            gs = gstar[material[q], wall_material[b]]
            shear = unwind_shear(
                law, dt, overlap, n, radius[q], gs, vrel, spin, cell_of(history, q, b)
            )
            place(history, q, b, shear)
            if rolls:
                moment = cell_of(rolling, q, b)
                turned = unwind_rolling(
                    law, dt, overlap, n, radius[q], row(w, q), ZERO, spin, moment
                )
                place(rolling, q, b, turned)
            place(normal_new, q, b, n)


unwind_pair_loop = by_size(_unwind_pair_loop)
unwind_wall_loop = by_size(_unwind_wall_loop)


@jit
def unwind_shear_history(p, pairs, walls, cell, law, moduli, dt):
    """Undo the shear update of the forward step (inverse of Eq 10, 9) at the later positions."""
    if law.tangential == NO_SHEAR:
        return
    pair_args = (
        p.x,
        p.v,
        p.omega,
        p.radius,
        p.material,
        moduli.gstar,
        images(cell),
        cell.rate,
        cell.length,
        deforms(cell),
        pairs.i,
        pairs.j,
        pairs.count[0],
        pairs.history,
        pairs.rolling,
        pairs.normal_new,
        law,
        dt,
    )
    wall_args = (
        p.x,
        p.v,
        p.omega,
        p.radius,
        p.material,
        moduli.gstar,
        walls.kind,
        walls.point,
        walls.axis,
        walls.radius,
        walls.velocity,
        walls.material,
        walls.history,
        walls.rolling,
        walls.normal_new,
        law,
        dt,
    )
    unwind_pair_loop(p.x.shape[0], *pair_args)
    unwind_wall_loop(p.x.shape[0], *wall_args)
