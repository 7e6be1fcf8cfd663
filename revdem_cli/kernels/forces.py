"""Contact forces and net forces on particles.

Three loops, each writing only its own slots: pairs (each pair's force computed once), wall
contacts (each particle's, wall by wall), and the gather (each particle sums its weight,
its pairs in the order of its partners' indices, and its walls in order), so sums do not
depend on the thread count.

The loops take plain arrays and do each item's work in the loop body, with helpers over
scalars and 3-tuples: a compiled call that receives array bundles pays an atomic
reference-count update per array, which would dominate the cost per item. Each loop is
built serial and parallel; small systems step serially, without waking threads.
"""

import numba

from revdem_cli.kernels import jit, serial_and_parallel
from revdem_cli.kernels.contact import (
    FORWARD,
    NO_SHEAR,
    axpy,
    contact_force,
    cross,
    dot,
    norm,
    relative_velocity,
    scaled,
    unwind_shear,
)
from revdem_cli.kernels.walls import wall_overlap

ZERO = (0.0, 0.0, 0.0)

PARALLEL_FROM = 256
"""Systems of at least this many particles step with parallel loops; smaller ones serially.
Results are the same either way."""


@jit
def sign(a):
    return 1.0 if a > 0.0 else (-1.0 if a < 0.0 else 0.0)


@jit
def row(a, k):
    """Row k of an (n, 3) array as a 3-tuple."""
    return (a[k, 0], a[k, 1], a[k, 2])


@jit
def put(a, k, vector):
    a[k, 0], a[k, 1], a[k, 2] = vector


@jit
def cell(a, q, b):
    """Entry (q, b) of an (n, m, 3) array as a 3-tuple."""
    return (a[q, b, 0], a[q, b, 1], a[q, b, 2])


@jit
def place(a, q, b, vector):
    a[q, b, 0], a[q, b, 1], a[q, b, 2] = vector


@jit
def pair_kinematics(i, j, x, v, w, radius):
    """(overlap, normal n from i to j, lever arms of i and j, velocity of j relative to i at
    the contact, mean spin about n) of the pair (i, j)."""
    d = axpy(-1.0, row(x, i), row(x, j))
    dist = norm(d)
    overlap = radius[i] + radius[j] - dist
    n = scaled(1.0 / dist, d)
    arm_i = radius[i] - 0.5 * overlap
    arm_j = radius[j] - 0.5 * overlap
    w_i = row(w, i)
    w_j = row(w, j)
    vrel = relative_velocity(n, arm_i, arm_j, row(v, i), w_i, row(v, j), w_j)
    return overlap, n, arm_i, arm_j, vrel, 0.5 * (dot(w_i, n) + dot(w_j, n))


@jit
def wall_kinematics(q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity):
    """(overlap, normal n towards the wall, lever arm, velocity of the wall relative to the
    particle at the contact, half the particle's spin about n) of particle q and wall b."""
    overlap, n = wall_overlap(
        kind[b], row(point, b), row(axis, b), wall_radius[b], row(x, q), radius[q]
    )
    arm = radius[q] - 0.5 * overlap
    w_q = row(w, q)
    vrel = relative_velocity(n, arm, 0.0, row(v, q), w_q, row(wall_velocity, b), ZERO)
    return overlap, n, arm, vrel, 0.5 * dot(w_q, n)


def _pair_loop(
    x,
    v,
    w,
    radius,
    mass,
    material,
    estar,
    gstar,
    pi,
    pj,
    n_pairs,
    history,
    pending,
    normal_new,
    force,
    torque_i,
    torque_j,
    normal,
    energy,
    slip,
    lost,
    law,
    mode,
    dt,
):
    """Force on i from j and the moments about both centres, for every listed pair
    (Hanley 2020 Eq 4-10); contact history zeroed on separation."""
    for k in numba.prange(n_pairs):
        i = pi[k]
        j = pj[k]
        overlap, n, arm_i, arm_j, vrel, spin = pair_kinematics(i, j, x, v, w, radius)
        shear = row(history, k)
        if overlap > 0.0:
            a, b = material[i], material[j]
            f, fn, u, slipped, shear = contact_force(
                law,
                mode,
                dt,
                overlap,
                n,
                radius[i] * radius[j] / (radius[i] + radius[j]),
                mass[i] * mass[j] / (mass[i] + mass[j]),
                (estar[a, b], gstar[a, b]),
                vrel,
                spin,
                shear,
                row(pending, k),
                row(normal_new, k),
            )
            put(torque_i, k, cross(scaled(arm_i, n), f))  # Hanley 2020 Eq 5
            put(torque_j, k, cross(scaled(arm_j, n), f))
            dropped = 0.0
        else:
            f = ZERO
            fn = 0.0
            u = 0.0
            slipped = 0.0
            dropped = norm(shear) if mode == FORWARD else 0.0
            shear = ZERO
            put(torque_i, k, ZERO)
            put(torque_j, k, ZERO)
        put(history, k, shear)
        put(force, k, f)
        normal[k] = fn
        energy[k] = u
        slip[k] = slipped
        lost[k] = dropped


def _wall_loop(
    x,
    v,
    w,
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
    history,
    pending,
    normal_new,
    force,
    torque,
    normal,
    energy,
    slip,
    lost,
    law,
    mode,
    dt,
):
    """Force and moment on each particle from each wall (Hanley 2020 Eq 4-10, R* = r)."""
    for q in numba.prange(x.shape[0]):
        for b in range(kind.shape[0]):
            overlap, n, arm, vrel, spin = wall_kinematics(
                q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity
            )
            shear = cell(history, q, b)
            if overlap > 0.0:
                m = wall_material[b]
                f, fn, u, slipped, shear = contact_force(
                    law,
                    mode,
                    dt,
                    overlap,
                    n,
                    radius[q],
                    mass[q],
                    (estar[material[q], m], gstar[material[q], m]),
                    vrel,
                    spin,
                    shear,
                    cell(pending, q, b),
                    cell(normal_new, q, b),
                )
                t = cross(scaled(arm, n), f)
                dropped = 0.0
            else:
                f = ZERO
                t = ZERO
                fn = 0.0
                u = 0.0
                slipped = 0.0
                dropped = norm(shear) if mode == FORWARD else 0.0
                shear = ZERO
            place(history, q, b, shear)
            place(force, q, b, f)
            place(torque, q, b, t)
            normal[q, b] = fn
            energy[q, b] = u
            slip[q, b] = slipped
            lost[q, b] = dropped


def _gather_loop(
    mass,
    v,
    w,
    gravity,
    local,
    pi,
    start,
    slots,
    pair_force,
    torque_i,
    torque_j,
    wall_force,
    wall_torque,
    f_out,
    t_out,
):
    """Net force and moment on each particle: weight, pairs by partner index, walls in order
    (Hanley 2020 Eq 4-5), then local damping of each component, f - gamma_l |f| sgn(v)
    (Eq 21)."""
    for q in numba.prange(f_out.shape[0]):
        f = scaled(mass[q], (gravity[0], gravity[1], gravity[2]))
        t = ZERO
        for s in range(start[q], start[q + 1]):
            k = slots[s]
            if pi[k] == q:
                f = axpy(1.0, row(pair_force, k), f)
                t = axpy(1.0, row(torque_i, k), t)
            else:
                f = axpy(-1.0, row(pair_force, k), f)
                t = axpy(1.0, row(torque_j, k), t)
        for b in range(wall_force.shape[1]):
            f = axpy(1.0, cell(wall_force, q, b), f)
            t = axpy(1.0, cell(wall_torque, q, b), t)
        for d in range(3):
            f_out[q, d] = f[d] - local * abs(f[d]) * sign(v[q, d])  # Hanley 2020 Eq 21
            t_out[q, d] = t[d] - local * abs(t[d]) * sign(w[q, d])


def _unwind_pair_loop(
    x, v, w, radius, material, gstar, pi, pj, n_pairs, history, pending, normal_new, law, dt
):
    """Reversed step, before drifting back: undo Eq 10 and 9 for every pair."""
    for k in numba.prange(n_pairs):
        i = pi[k]
        j = pj[k]
        overlap, n, _, _, vrel, spin = pair_kinematics(i, j, x, v, w, radius)
        rstar = radius[i] * radius[j] / (radius[i] + radius[j])
        gs = gstar[material[i], material[j]]
        put(pending, k, unwind_shear(law, dt, overlap, n, rstar, gs, vrel, spin, row(history, k)))
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
    pending,
    normal_new,
    law,
    dt,
):
    """Reversed step, before drifting back: undo Eq 10 and 9 for every wall contact."""
    for q in numba.prange(x.shape[0]):
        for b in range(kind.shape[0]):
            overlap, n, _, vrel, spin = wall_kinematics(
                q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity
            )
            gs = gstar[material[q], wall_material[b]]
            shear = unwind_shear(
                law, dt, overlap, n, radius[q], gs, vrel, spin, cell(history, q, b)
            )
            place(pending, q, b, shear)
            place(normal_new, q, b, n)


pair_loop, pair_loop_parallel = serial_and_parallel(_pair_loop)
wall_loop, wall_loop_parallel = serial_and_parallel(_wall_loop)
gather_loop, gather_loop_parallel = serial_and_parallel(_gather_loop)
unwind_pair_loop, unwind_pair_loop_parallel = serial_and_parallel(_unwind_pair_loop)
unwind_wall_loop, unwind_wall_loop_parallel = serial_and_parallel(_unwind_wall_loop)


@jit
def compute_forces(p, pairs, walls, law, moduli, dyn, mode, dt):
    """Forces at the current positions: Hanley 2020 Eq 4-10 and 21 forward, Eq 19 reversed."""
    parallel = p.x.shape[0] >= PARALLEL_FROM
    pair_args = (
        p.x,
        p.v,
        p.omega,
        p.radius,
        p.mass,
        p.material,
        moduli.estar,
        moduli.gstar,
        pairs.i,
        pairs.j,
        pairs.count[0],
        pairs.history,
        pairs.pending,
        pairs.normal_new,
        pairs.force,
        pairs.torque_i,
        pairs.torque_j,
        pairs.normal,
        pairs.energy,
        pairs.slip,
        pairs.lost,
        law,
        mode,
        dt,
    )
    wall_args = (
        p.x,
        p.v,
        p.omega,
        p.radius,
        p.mass,
        p.material,
        moduli.estar,
        moduli.gstar,
        walls.kind,
        walls.point,
        walls.axis,
        walls.radius,
        walls.velocity,
        walls.material,
        walls.history,
        walls.pending,
        walls.normal_new,
        walls.force,
        walls.torque,
        walls.normal,
        walls.energy,
        walls.slip,
        walls.lost,
        law,
        mode,
        dt,
    )
    gather_args = (
        p.mass,
        p.v,
        p.omega,
        dyn.gravity,
        dyn.local_damping,
        pairs.i,
        pairs.start,
        pairs.slots,
        pairs.force,
        pairs.torque_i,
        pairs.torque_j,
        walls.force,
        walls.torque,
        p.f,
        p.torque,
    )
    if parallel:
        pair_loop_parallel(*pair_args)
        wall_loop_parallel(*wall_args)
        gather_loop_parallel(*gather_args)
    else:
        pair_loop(*pair_args)
        wall_loop(*wall_args)
        gather_loop(*gather_args)


@jit
def unwind_shear_history(p, pairs, walls, law, moduli, dt):
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
        pairs.i,
        pairs.j,
        pairs.count[0],
        pairs.history,
        pairs.pending,
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
        walls.pending,
        walls.normal_new,
        law,
        dt,
    )
    if p.x.shape[0] >= PARALLEL_FROM:
        unwind_pair_loop_parallel(*pair_args)
        unwind_wall_loop_parallel(*wall_args)
    else:
        unwind_pair_loop(*pair_args)
        unwind_wall_loop(*wall_args)
