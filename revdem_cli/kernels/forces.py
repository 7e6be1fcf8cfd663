"""Contact forces and net forces on particles.

Each pair's force is computed once into its own slot, then gathered per particle in a fixed
order (weight, pairs by partner index, walls in order), so sums do not depend on the thread
count. Each parallel loop body is one call to a serial compiled function that does all the
work of one item: numba's parallel-loop transformation has been seen to drop array stores
made directly in a loop body over bundles.
"""

import numba

from revdem_cli.kernels import jit, pjit
from revdem_cli.kernels.contact import (
    FORWARD,
    NO_SHEAR,
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


@jit
def store(row, vector):
    row[0], row[1], row[2] = vector


@jit
def add(a, row, s):
    """a + s row, for a 3-tuple a and an array row."""
    return (a[0] + s * row[0], a[1] + s * row[1], a[2] + s * row[2])


@jit
def sign(a):
    return 1.0 if a > 0.0 else (-1.0 if a < 0.0 else 0.0)


@jit
def pair_contact(k, p, pairs, law, mode, dt):
    """Force and torques of pair slot k at the current positions (Hanley 2020 Eq 4-10)."""
    x, v, w, radius = p.x, p.v, p.omega, p.radius
    i = pairs.i[k]
    j = pairs.j[k]
    d = (x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2])
    dist = norm(d)
    overlap = radius[i] + radius[j] - dist
    history = pairs.history[k]
    if overlap > 0.0:
        n = scaled(1.0 / dist, d)
        arm_i = radius[i] - 0.5 * overlap
        arm_j = radius[j] - 0.5 * overlap
        f, fn, u, slipped = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            radius[i] * radius[j] / (radius[i] + radius[j]),
            p.mass[i] * p.mass[j] / (p.mass[i] + p.mass[j]),
            (p.material[i], p.material[j]),
            relative_velocity(n, arm_i, arm_j, v[i], w[i], v[j], w[j]),
            0.5 * (dot(w[i], n) + dot(w[j], n)),
            history,
            pairs.pending[k],
            pairs.normal_new[k],
        )
        ti = cross(scaled(arm_i, n), f)  # Hanley 2020 Eq 5
        tj = cross(scaled(arm_j, n), f)
        dropped = 0.0
    else:
        f = ZERO
        ti = ZERO
        tj = ZERO
        fn = 0.0
        u = 0.0
        slipped = 0.0
        dropped = norm((history[0], history[1], history[2])) if mode == FORWARD else 0.0
        history[:] = 0.0
    store(pairs.force[k], f)
    store(pairs.torque_i[k], ti)
    store(pairs.torque_j[k], tj)
    pairs.normal[k] = fn
    pairs.energy[k] = u
    pairs.slip[k] = slipped
    pairs.lost[k] = dropped


@jit
def wall_contact(q, b, p, walls, law, mode, dt):
    """Force and torque on particle q from wall b; returns them as (force, torque)."""
    overlap, n = wall_overlap(walls, b, p.x[q], p.radius[q])
    history = walls.history[q, b]
    if overlap > 0.0:
        arm = p.radius[q] - 0.5 * overlap
        f, fn, u, slipped = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            p.radius[q],
            p.mass[q],
            (p.material[q], walls.material[b]),
            relative_velocity(n, arm, 0.0, p.v[q], p.omega[q], walls.velocity[b], ZERO),
            0.5 * dot(p.omega[q], n),
            history,
            walls.pending[q, b],
            walls.normal_new[q, b],
        )
        t = cross(scaled(arm, n), f)
        dropped = 0.0
    else:
        f = ZERO
        t = ZERO
        fn = 0.0
        u = 0.0
        slipped = 0.0
        dropped = norm((history[0], history[1], history[2])) if mode == FORWARD else 0.0
        history[:] = 0.0
    store(walls.force[q, b], f)
    walls.normal[q, b] = fn
    walls.energy[q, b] = u
    walls.slip[q, b] = slipped
    walls.lost[q, b] = dropped
    return f, t


@jit
def particle_net_force(q, p, pairs, walls, law, dyn, mode, dt):
    """Net force and moment on particle q: weight, pair contacts by partner index, walls in
    order (Eq 4-5), then local damping of each component, f - gamma_l |f| sgn(v) (Eq 21)."""
    g = dyn.gravity
    f = (p.mass[q] * g[0], p.mass[q] * g[1], p.mass[q] * g[2])
    t = ZERO
    for s in range(pairs.start[q], pairs.start[q + 1]):
        k = pairs.slots[s]
        if pairs.i[k] == q:
            f = add(f, pairs.force[k], 1.0)
            t = add(t, pairs.torque_i[k], 1.0)
        else:
            f = add(f, pairs.force[k], -1.0)
            t = add(t, pairs.torque_j[k], 1.0)
    for b in range(walls.force.shape[1]):
        wf, wt = wall_contact(q, b, p, walls, law, mode, dt)
        f = add(f, wf, 1.0)
        t = add(t, wt, 1.0)
    local = dyn.local_damping
    for d in range(3):
        p.f[q, d] = f[d] - local * abs(f[d]) * sign(p.v[q, d])  # Hanley 2020 Eq 21
        p.torque[q, d] = t[d] - local * abs(t[d]) * sign(p.omega[q, d])


@jit
def unwind_pair(k, p, pairs, law, dt):
    """Reversed step, before drifting back: undo Eq 10 and 9 for pair slot k."""
    x, v, w, radius = p.x, p.v, p.omega, p.radius
    i = pairs.i[k]
    j = pairs.j[k]
    d = (x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2])
    dist = norm(d)
    overlap = radius[i] + radius[j] - dist
    n = scaled(1.0 / dist, d)
    vrel = relative_velocity(
        n, radius[i] - 0.5 * overlap, radius[j] - 0.5 * overlap, v[i], w[i], v[j], w[j]
    )
    unwind_shear(
        law,
        dt,
        overlap,
        n,
        radius[i] * radius[j] / (radius[i] + radius[j]),
        (p.material[i], p.material[j]),
        vrel,
        0.5 * (dot(w[i], n) + dot(w[j], n)),
        pairs.history[k],
        pairs.pending[k],
        pairs.normal_new[k],
    )


@jit
def unwind_walls(q, p, walls, law, dt):
    """Reversed step, before drifting back: undo Eq 10 and 9 for particle q's wall contacts."""
    for b in range(walls.history.shape[1]):
        overlap, n = wall_overlap(walls, b, p.x[q], p.radius[q])
        vrel = relative_velocity(
            n, p.radius[q] - 0.5 * overlap, 0.0, p.v[q], p.omega[q], walls.velocity[b], ZERO
        )
        unwind_shear(
            law,
            dt,
            overlap,
            n,
            p.radius[q],
            (p.material[q], walls.material[b]),
            vrel,
            0.5 * dot(p.omega[q], n),
            walls.history[q, b],
            walls.pending[q, b],
            walls.normal_new[q, b],
        )


@pjit
def pair_forces(p, pairs, law, mode, dt):
    for k in numba.prange(pairs.count[0]):
        pair_contact(k, p, pairs, law, mode, dt)


@pjit
def particle_forces(p, pairs, walls, law, dyn, mode, dt):
    for q in numba.prange(p.x.shape[0]):
        particle_net_force(q, p, pairs, walls, law, dyn, mode, dt)


@pjit
def unwind_all(p, pairs, walls, law, dt):
    for k in numba.prange(pairs.count[0]):
        unwind_pair(k, p, pairs, law, dt)
    for q in numba.prange(p.x.shape[0]):
        unwind_walls(q, p, walls, law, dt)


@jit
def compute_forces(p, pairs, walls, law, dyn, mode, dt):
    """Forces at the current positions: Hanley 2020 Eq 4-10 and 21 forward, Eq 19 reversed."""
    pair_forces(p, pairs, law, mode, dt)
    particle_forces(p, pairs, walls, law, dyn, mode, dt)


@jit
def unwind_shear_history(p, pairs, walls, law, dt):
    """Undo the shear update of the forward step (inverse of Eq 10, 9) at the later positions."""
    if law.tangential != NO_SHEAR:
        unwind_all(p, pairs, walls, law, dt)
