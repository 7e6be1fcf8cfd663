"""Velocity-Verlet stepping, forward and reversed, and the compiled loop of a stage."""

from revdem_cli.kernels import jit
from revdem_cli.kernels.forces import compute_forces
from revdem_cli.kernels.neighbours import (
    build_pairs,
    carry_history,
    index_by_particle,
    largest_reach,
)
from revdem_cli.kernels.observables import observe

OK = 0
PAIR_OVERFLOW = 1


@jit
def kick(v, f, inv_m, h):
    """v += h f / m: a half kick with h = +dt/2 (Hanley 2020 Eq 1, 11) or -dt/2 (Eq 17, 20)."""
    for q in range(v.shape[0]):
        for d in range(3):
            v[q, d] += h * f[q, d] * inv_m[q]


@jit
def drift(x, v, h):
    """x += h v with the half-step velocity, h = +dt (Hanley 2020 Eq 3) or -dt (Eq 18)."""
    for q in range(x.shape[0]):
        for d in range(3):
            x[q, d] += h * v[q, d]


@jit
def verlet_step(p, pairs, law, gravity, h):
    """One velocity-Verlet step of signed length h.

    h = +dt is the forward step (Hanley 2020 Eq 1-3, 4-6, 11-12). For this conservative
    system the reversed step (Eq 17-20) is its exact algebraic inverse with the same
    operations and h = -dt: kick back with the stored force, drift back, recompute the force
    at the earlier positions, kick back again. Each increment has the same magnitude in both
    directions, so the two differ only by round-off.
    """
    kick(p.v, p.f, p.inv_mass, 0.5 * h)
    kick(p.omega, p.torque, p.inv_inertia, 0.5 * h)
    drift(p.x, p.v, h)
    compute_forces(p, pairs, law, gravity)
    kick(p.v, p.f, p.inv_mass, 0.5 * h)
    kick(p.omega, p.torque, p.inv_inertia, 0.5 * h)


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
def advance(p, pairs, law, gravity, skin, dt, direction, step, stop, stage, obs_every, obs):
    """Run whole steps from `step` to `stop` in `direction` (+1 forward, -1 reversed).

    stage = (first step, last step) of the stage; observables are recorded into the rows of
    `obs` at every step where (step - first) % obs_every == 0 and at the last step.
    Returns (status, step reached, rows recorded). Status PAIR_OVERFLOW means the pair list
    must grow before stepping on; the state is then at a whole step.
    """
    rows = 0
    while step != stop:
        if largest_reach(p.x, pairs.x_built, p.v, p.f, p.inv_mass, dt, direction) > 0.5 * skin:
            if not rebuild_pairs(p, pairs, skin):
                return PAIR_OVERFLOW, step, rows
        verlet_step(p, pairs, law, gravity, direction * dt)
        step += direction
        if (step - stage[0]) % obs_every == 0 or step == stage[1]:
            obs[rows, 0] = step
            observe(p, pairs, gravity, obs[rows])
            rows += 1
    return OK, step, rows
