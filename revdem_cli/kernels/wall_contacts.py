"""Sphere-wall contacts: the force and moment on each particle from each wall (Hanley 2020
Eq 4-10 with R* = r), each particle's contacts in wall order."""

import numba

from revdem_cli.kernels import by_size, jit
from revdem_cli.kernels.contact import (
    FORWARD,
    NO_ROLLING,
    NO_SHEAR,
    capped_away,
    contact_force,
    lever_arm,
    relative_velocity,
    rolling_moment,
)
from revdem_cli.kernels.vectors import (
    ZERO,
    axpy,
    cell_of,
    cross,
    dot,
    norm,
    place,
    put,
    row,
    scaled,
)
from revdem_cli.kernels.walls import wall_overlap


@jit
def wall_kinematics(q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity):
    """(overlap, normal n towards the wall, lever arm, velocity of the wall relative to the
    particle at the contact, half the particle's spin about n) of particle q and wall b."""
    overlap, n = wall_overlap(
        kind[b], row(point, b), row(axis, b), wall_radius[b], row(x, q), radius[q]
    )
    arm = lever_arm(radius[q], overlap)
    w_q = row(w, q)
    vrel = relative_velocity(n, arm, 0.0, row(v, q), w_q, row(wall_velocity, b), ZERO)
    return overlap, n, arm, vrel, 0.5 * dot(w_q, n)


def _wall_loop(
    x,
    v,
    w,
    v_damp,
    w_damp,
    predicted,
    radius,
    mass,
    material,
    estar,
    gstar,
    kind,
    point,
    axis,
    wall_radius,
    wall_velocity,
    wall_material,
    force,
    torque,
    overlaps,
    history,
    destroyed,
    rolling,
    rolled,
    normal_new,
    law,
    mode,
    dt,
):
    """Force and moment on each particle from each wall (Hanley 2020 Eq 4-10, R* = r; the
    wall does not turn), the moment with the rolling moment of a rolling law; viscous
    damping reads `v_damp`, `w_damp` where `predicted` (a velocity predictor's). Returns the
    counts of `events.note_destroyed`, contacts numbered q W + b (a slip where it destroys
    information, `contact.capped_away`; with viscous damping, the contacts touching)."""
    shear_law = law.tangential != NO_SHEAR
    damped = law.beta_n > 0.0 or law.beta_t > 0.0
    rolling_law = law.rolling != NO_ROLLING
    walls = kind.shape[0]
    slips = 0
    last_slip = -1
    losses = 0
    last_loss = -1
    caps = 0
    last_cap = -1
    drops = 0
    last_drop = -1
    dashpots = 0
    last_dashpot = -1
    if walls == 0:  # no parallel region for nothing: each costs microseconds a step
        counts = (slips, last_slip, losses, last_loss, caps, last_cap, drops, last_drop)
        return counts + (dashpots, last_dashpot)
    for q in numba.prange(x.shape[0]):
        for b in range(walls):
            overlap, n, arm, vrel, spin = wall_kinematics(
                q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity
            )
            overlaps[q, b] = overlap
            carried = cell_of(history, q, b)
            shear = carried
            if overlap > 0.0:
                m = wall_material[b]
                vdamp = vrel
                if predicted:  # the viscous damping reads the predicted velocities
                    vdamp = relative_velocity(
                        n, arm, 0.0, row(v_damp, q), row(w_damp, q), row(wall_velocity, b), ZERO
                    )
                n_new = cell_of(normal_new, q, b) if normal_new.shape[0] > 0 else ZERO
                f, shear, slipped, normal, elastic = contact_force(
                    law,
                    mode,
                    dt,
                    overlap,
                    n,
                    radius[q],
                    mass[q],
                    estar[material[q], m],
                    gstar[material[q], m],
                    vrel,
                    vdamp,
                    spin,
                    shear,
                    n_new,
                )
                t = cross(scaled(arm, n), f) if shear_law else ZERO
                dropped = 0.0
                if rolling_law:
                    old = cell_of(rolling, q, b)
                    turned, capped = rolling_moment(
                        law, mode, dt, overlap, n, radius[q], normal, elastic, row(w, q), ZERO,
                        spin, old, n_new,
                    )  # fmt: skip
                    t = axpy(1.0, turned, t)
                    place(rolling, q, b, turned)
                    rolled[q, b] = capped
            else:
                f = ZERO
                t = ZERO
                slipped = 0.0
                dropped = norm(shear) if mode == FORWARD else 0.0
                shear = ZERO
                if rolling_law:
                    rolled[q, b] = norm(cell_of(rolling, q, b)) if mode == FORWARD else 0.0
                    place(rolling, q, b, ZERO)
            place(history, q, b, shear)
            place(force, q, b, f)
            place(torque, q, b, t)
            destroyed[q, b] = slipped + dropped
            contact = q * walls + b
            if slipped > 0.0 and not capped_away(law, carried):
                slips += 1
                last_slip = max(last_slip, contact)
            if damped and overlap > 0.0:
                dashpots += 1
                last_dashpot = max(last_dashpot, contact)
            if dropped > 0.0:
                losses += 1
                last_loss = max(last_loss, contact)
            if rolling_law and overlap > 0.0 and rolled[q, b] > 0.0:
                caps += 1
                last_cap = max(last_cap, contact)
            if rolling_law and overlap <= 0.0 and rolled[q, b] > 0.0:
                drops += 1
                last_drop = max(last_drop, contact)
    counts = (slips, last_slip, losses, last_loss, caps, last_cap, drops, last_drop)
    return counts + (dashpots, last_dashpot)


wall_loop = by_size(_wall_loop)


@jit
def wall_normal(p, walls, q, b):
    """Unit normal from particle q towards wall b (for observables, not per step)."""
    point, axis = row(walls.point, b), row(walls.axis, b)
    return wall_overlap(walls.kind[b], point, axis, walls.radius[b], row(p.x, q), p.radius[q])[1]


@jit
def wall_normals(p, walls, q, b, normals):
    """`wall_normal` of each sphere q[k] on wall b[k], into normals[k] (the contact list's:
    one compiled call a frame)."""
    for k in range(q.shape[0]):
        put(normals, k, wall_normal(p, walls, q[k], b[k]))
