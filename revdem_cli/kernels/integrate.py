"""Velocity-Verlet stepping, forward and reversed, and the compiled loop of a stage."""

from revdem_cli.kernels import jit
from revdem_cli.kernels.contact import FORWARD, REVERSE
from revdem_cli.kernels.events import MOTION_LOST, note, note_contact_events, note_fixed_points
from revdem_cli.kernels.forces import compute_forces, unwind_shear_history
from revdem_cli.kernels.neighbours import (
    build_pairs,
    carry_history,
    index_by_particle,
    largest_reach,
)
from revdem_cli.kernels.observables import observe
from revdem_cli.kernels.walls import place_walls

OK = 0
PAIR_OVERFLOW = 1


@jit
def kick(v, f, inv_m, h):
    """v += h f / m: a half kick, h = +dt/2 (Hanley 2020 Eq 1-2, 11-12) or -dt/2 (Eq 17, 20)."""
    for q in range(v.shape[0]):
        for d in range(3):
            v[q, d] += h * f[q, d] * inv_m[q]


@jit
def drift(x, v, h, events, step):
    """x += h v with the half-step velocity, h = +dt (Hanley 2020 Eq 3) or -dt (Eq 18).

    A nonzero displacement too small to change a position is lost to round-off: logged.
    """
    for q in range(x.shape[0]):
        lost = 0.0
        for d in range(3):
            moved = x[q, d] + h * v[q, d]
            if moved == x[q, d] and v[q, d] != 0.0:
                lost = max(lost, abs(h * v[q, d]))
            x[q, d] = moved
        if lost > 0.0:
            note(events, MOTION_LOST, step, q, -1, lost)


@jit
def scale(v, factor):
    """v *= factor: drag, factor gamma_d (Hanley 2020 Eq 25), undone with 1/gamma_d (Eq 28)."""
    for q in range(v.shape[0]):
        for d in range(3):
            v[q, d] *= factor


@jit
def forward_step(p, pairs, walls, law, moduli, dyn, events, dt, step, wall_time):
    """One forward step from `step` (Hanley 2020 Eq 1-12, with drag Eq 25-26)."""
    kick(p.v, p.f, p.inv_mass, 0.5 * dt)
    kick(p.omega, p.torque, p.inv_inertia, 0.5 * dt)
    if dyn.drag != 1.0:
        scale(p.v, dyn.drag)
        note_fixed_points(p.v, p.v_drift, step + 1, events)
    drift(p.x, p.v, dt, events, step + 1)
    place_walls(walls, wall_time)
    compute_forces(p, pairs, walls, law, moduli, dyn, FORWARD, dt)
    note_contact_events(pairs, walls, law, dyn, step + 1, events)
    kick(p.v, p.f, p.inv_mass, 0.5 * dt)
    kick(p.omega, p.torque, p.inv_inertia, 0.5 * dt)


@jit
def reverse_step(p, pairs, walls, law, moduli, dyn, events, dt, step, wall_time):
    """One reversed step from `step`: the forward step's operations undone in reverse order.

    Kick back with the stored force (Eq 17, 27); undo the shear increment and spin
    correction at the later positions (inverse of Eq 10, 9); drift back with the velocity
    the forward step drifted with (Eq 18); undo drag (Eq 28); forces at the earlier
    positions, the shear history mapped back onto their contact planes (Eq 19, inverse of
    Eq 7-8); kick back (Eq 20). Mechanisms that destroy information (Coulomb cap, local and
    viscous damping, shear force lost at separation) run mirrored and are logged.
    """
    kick(p.v, p.f, p.inv_mass, -0.5 * dt)
    kick(p.omega, p.torque, p.inv_inertia, -0.5 * dt)
    unwind_shear_history(p, pairs, walls, law, moduli, dt)
    drift(p.x, p.v, -dt, events, step - 1)
    place_walls(walls, wall_time)
    if dyn.drag != 1.0:
        note_fixed_points(p.v, p.v_drift, step - 1, events)
        scale(p.v, 1.0 / dyn.drag)
    compute_forces(p, pairs, walls, law, moduli, dyn, REVERSE, dt)
    note_contact_events(pairs, walls, law, dyn, step - 1, events)
    kick(p.v, p.f, p.inv_mass, -0.5 * dt)
    kick(p.omega, p.torque, p.inv_inertia, -0.5 * dt)


@jit
def rebuild_pairs(p, pairs, skin):
    """Rebuild the pair list at the current positions, carrying contact history.

    Returns False, leaving the list as it was, when the new list does not fit; the number
    needed is then in pairs.count[1].
    """
    needed = build_pairs(p.x, p.radius, skin, pairs.new_i, pairs.new_j)
    pairs.count[1] = needed
    if needed > pairs.i.shape[0]:
        return False
    old = pairs.count[0]
    carry_history(
        pairs.i, pairs.j, pairs.history, old, pairs.new_i, pairs.new_j, pairs.new_history, needed
    )
    pairs.i[:needed] = pairs.new_i[:needed]
    pairs.j[:needed] = pairs.new_j[:needed]
    pairs.history[:needed] = pairs.new_history[:needed]
    pairs.count[0] = needed
    index_by_particle(pairs.i, pairs.j, needed, pairs.start, pairs.slots)
    pairs.x_built[:] = p.x
    return True


@jit
def advance(p, pairs, walls, law, moduli, dyn, events, run, step, stop, obs):
    """Run whole steps from `step` to `stop` (forward if stop > step, else reversed).

    run = (dt, skin, first step of the stage, last step, observables interval). Observables
    are recorded into the rows of `obs` at every step where (step - first) % interval == 0
    and at the last step. Returns (status, step reached, rows recorded); status
    PAIR_OVERFLOW means the pair list must grow before stepping on (the state is then at a
    whole step).
    """
    dt, skin = run[0], run[1]
    first, last, every = int(run[2]), int(run[3]), int(run[4])
    direction = 1 if stop > step else -1
    rows = 0
    while step != stop:
        if largest_reach(p.x, pairs.x_built, p.v, p.f, p.inv_mass, dt, direction) > 0.5 * skin:
            if not rebuild_pairs(p, pairs, skin):
                return PAIR_OVERFLOW, step, rows
        wall_time = (step + direction - first) * dt
        if direction > 0:
            forward_step(p, pairs, walls, law, moduli, dyn, events, dt, step, wall_time)
        else:
            reverse_step(p, pairs, walls, law, moduli, dyn, events, dt, step, wall_time)
        step += direction
        if (step - first) % every == 0 or step == last:
            obs[rows, 0] = step
            observe(p, pairs, walls, dyn, obs[rows])
            rows += 1
    return OK, step, rows
