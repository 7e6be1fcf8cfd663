"""Contact forces and net forces on particles.

Each pair's force is computed once into its own slot, then gathered per particle in a fixed
order (weight, pairs by partner index, walls in order), so sums do not depend on the thread
count. Each parallel loop body is one call to a serial compiled function that does all the
work of one item: numba's parallel-loop transformation has been seen to drop array stores
made directly in a loop body over bundles.
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
"""Systems of at least this many particles step with parallel loops; smaller ones serially,
without the cost of waking threads. Results are the same either way."""


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
def pair_contact(k, p, pairs, law, mode, dt):
    """Force and torques of pair slot k at the current positions (Hanley 2020 Eq 4-10)."""
    x, radius = p.x, p.radius
    i = pairs.i[k]
    j = pairs.j[k]
    d = axpy(-1.0, row(x, i), row(x, j))
    dist = norm(d)
    overlap = radius[i] + radius[j] - dist
    history = row(pairs.history, k)
    if overlap > 0.0:
        n = scaled(1.0 / dist, d)
        arm_i = radius[i] - 0.5 * overlap
        arm_j = radius[j] - 0.5 * overlap
        w_i = row(p.omega, i)
        w_j = row(p.omega, j)
        f, fn, u, slipped, history = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            radius[i] * radius[j] / (radius[i] + radius[j]),
            p.mass[i] * p.mass[j] / (p.mass[i] + p.mass[j]),
            (p.material[i], p.material[j]),
            relative_velocity(n, arm_i, arm_j, row(p.v, i), w_i, row(p.v, j), w_j),
            0.5 * (dot(w_i, n) + dot(w_j, n)),
            history,
            row(pairs.pending, k),
            row(pairs.normal_new, k),
        )
        put(pairs.torque_i, k, cross(scaled(arm_i, n), f))  # Hanley 2020 Eq 5
        put(pairs.torque_j, k, cross(scaled(arm_j, n), f))
        dropped = 0.0
    else:
        f = ZERO
        fn = 0.0
        u = 0.0
        slipped = 0.0
        dropped = norm(history) if mode == FORWARD else 0.0
        history = ZERO
        put(pairs.torque_i, k, ZERO)
        put(pairs.torque_j, k, ZERO)
    put(pairs.history, k, history)
    put(pairs.force, k, f)
    pairs.normal[k] = fn
    pairs.energy[k] = u
    pairs.slip[k] = slipped
    pairs.lost[k] = dropped


@jit
def wall_contact(q, b, p, walls, law, mode, dt):
    """Force and torque on particle q from wall b, returned as (force, torque)."""
    overlap, n = wall_overlap(walls, b, row(p.x, q), p.radius[q])
    history = cell(walls.history, q, b)
    if overlap > 0.0:
        arm = p.radius[q] - 0.5 * overlap
        w_q = row(p.omega, q)
        f, fn, u, slipped, history = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            p.radius[q],
            p.mass[q],
            (p.material[q], walls.material[b]),
            relative_velocity(n, arm, 0.0, row(p.v, q), w_q, row(walls.velocity, b), ZERO),
            0.5 * dot(w_q, n),
            history,
            cell(walls.pending, q, b),
            cell(walls.normal_new, q, b),
        )
        t = cross(scaled(arm, n), f)
        dropped = 0.0
    else:
        f = ZERO
        t = ZERO
        fn = 0.0
        u = 0.0
        slipped = 0.0
        dropped = norm(history) if mode == FORWARD else 0.0
        history = ZERO
    walls.history[q, b, 0], walls.history[q, b, 1], walls.history[q, b, 2] = history
    walls.force[q, b, 0], walls.force[q, b, 1], walls.force[q, b, 2] = f
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
            f = axpy(1.0, row(pairs.force, k), f)
            t = axpy(1.0, row(pairs.torque_i, k), t)
        else:
            f = axpy(-1.0, row(pairs.force, k), f)
            t = axpy(1.0, row(pairs.torque_j, k), t)
    for b in range(walls.force.shape[1]):
        wf, wt = wall_contact(q, b, p, walls, law, mode, dt)
        f = axpy(1.0, wf, f)
        t = axpy(1.0, wt, t)
    local = dyn.local_damping
    for d in range(3):
        p.f[q, d] = f[d] - local * abs(f[d]) * sign(p.v[q, d])  # Hanley 2020 Eq 21
        p.torque[q, d] = t[d] - local * abs(t[d]) * sign(p.omega[q, d])


@jit
def unwind_pair(k, p, pairs, law, dt):
    """Reversed step, before drifting back: undo Eq 10 and 9 for pair slot k."""
    x, radius = p.x, p.radius
    i = pairs.i[k]
    j = pairs.j[k]
    d = axpy(-1.0, row(x, i), row(x, j))
    dist = norm(d)
    overlap = radius[i] + radius[j] - dist
    n = scaled(1.0 / dist, d)
    w_i = row(p.omega, i)
    w_j = row(p.omega, j)
    vrel = relative_velocity(
        n, radius[i] - 0.5 * overlap, radius[j] - 0.5 * overlap, row(p.v, i), w_i, row(p.v, j), w_j
    )
    put(
        pairs.pending,
        k,
        unwind_shear(
            law,
            dt,
            overlap,
            n,
            radius[i] * radius[j] / (radius[i] + radius[j]),
            (p.material[i], p.material[j]),
            vrel,
            0.5 * (dot(w_i, n) + dot(w_j, n)),
            row(pairs.history, k),
        ),
    )
    put(pairs.normal_new, k, n)


@jit
def unwind_walls(q, p, walls, law, dt):
    """Reversed step, before drifting back: undo Eq 10 and 9 for particle q's wall contacts."""
    w_q = row(p.omega, q)
    for b in range(walls.history.shape[1]):
        overlap, n = wall_overlap(walls, b, row(p.x, q), p.radius[q])
        vrel = relative_velocity(
            n, p.radius[q] - 0.5 * overlap, 0.0, row(p.v, q), w_q, row(walls.velocity, b), ZERO
        )
        history = cell(walls.history, q, b)
        pending = unwind_shear(
            law,
            dt,
            overlap,
            n,
            p.radius[q],
            (p.material[q], walls.material[b]),
            vrel,
            0.5 * dot(w_q, n),
            history,
        )
        walls.pending[q, b, 0], walls.pending[q, b, 1], walls.pending[q, b, 2] = pending
        walls.normal_new[q, b, 0], walls.normal_new[q, b, 1], walls.normal_new[q, b, 2] = n


def _pair_loop(p, pairs, law, mode, dt):
    for k in numba.prange(pairs.count[0]):
        pair_contact(k, p, pairs, law, mode, dt)


def _particle_loop(p, pairs, walls, law, dyn, mode, dt):
    for q in numba.prange(p.x.shape[0]):
        particle_net_force(q, p, pairs, walls, law, dyn, mode, dt)


def _unwind_loop(p, pairs, walls, law, dt):
    for k in numba.prange(pairs.count[0]):
        unwind_pair(k, p, pairs, law, dt)
    for q in numba.prange(p.x.shape[0]):
        unwind_walls(q, p, walls, law, dt)


pair_loop, pair_loop_parallel = serial_and_parallel(_pair_loop)
particle_loop, particle_loop_parallel = serial_and_parallel(_particle_loop)
unwind_loop, unwind_loop_parallel = serial_and_parallel(_unwind_loop)


@jit
def compute_forces(p, pairs, walls, law, dyn, mode, dt):
    """Forces at the current positions: Hanley 2020 Eq 4-10 and 21 forward, Eq 19 reversed."""
    if p.x.shape[0] >= PARALLEL_FROM:
        pair_loop_parallel(p, pairs, law, mode, dt)
        particle_loop_parallel(p, pairs, walls, law, dyn, mode, dt)
    else:
        pair_loop(p, pairs, law, mode, dt)
        particle_loop(p, pairs, walls, law, dyn, mode, dt)


@jit
def unwind_shear_history(p, pairs, walls, law, dt):
    """Undo the shear update of the forward step (inverse of Eq 10, 9) at the later positions."""
    if law.tangential == NO_SHEAR:
        return
    if p.x.shape[0] >= PARALLEL_FROM:
        unwind_loop_parallel(p, pairs, walls, law, dt)
    else:
        unwind_loop(p, pairs, walls, law, dt)
