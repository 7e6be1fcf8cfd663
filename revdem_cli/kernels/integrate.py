"""Velocity-Verlet stepping, forward and reversed, and the compiled loop of a stage.

Compile time, which a user meets on a first run and a fresh install:
- constants go to a compiled call with much code beneath it as np.int64 and np.True_ or
  np.False_, which numba types as plain int64 and bool: it compiles a function anew for each
  literal argument (a mode such as FORWARD, True or False), and `forces.compute_forces` had
  five builds (small leaves, `events.note` and `fixed.note_overflow`, take their kinds as
  literals: a build of one costs little);
- the steps (`forward_step`, `reverse_step`, `settle`, `record_step`) are inlined by numba
  into `advance` (`inline_arrays`): numba links the code of every compiled function a
  compiled function calls into its own and optimises and compiles all of it again, so that
  each step, one level above `compute_forces`, compiled the pair loop once more."""

import numba
import numpy as np

from revdem_cli.kernels import LIGHT, by_size, inline_arrays, jit
from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels import tape as tp
from revdem_cli.kernels.cell import kick_cell, move_cell, steer_back
from revdem_cli.kernels.contact import FORWARD, NO_SHEAR, REVERSE, SETTLED
from revdem_cli.kernels.events import (
    COLUMNS,
    KINDS,
    MOTION_LOST,
    note,
    note_fixed_points,
    note_local_damping,
)
from revdem_cli.kernels.forces import compute_forces, note_normals
from revdem_cli.kernels.gather import kick
from revdem_cli.kernels.health import HEALTHY, Finding, examine
from revdem_cli.kernels.neighbours import (
    build_pairs,
    carry_history,
    index_by_particle,
    largest_reach,
)
from revdem_cli.kernels.observables import observe
from revdem_cli.kernels.predictor import predict
from revdem_cli.kernels.unwind import unwind_shear_history
from revdem_cli.kernels.walls import place_walls

OK = 0
PAIR_OVERFLOW = 1
CELL_TOO_SMALL = 2
FIXED_OVERFLOW = 3
BLOWN_UP = 4
HALTED = 5
TAPE_FULL = 6
TAPE_EMPTY = 7
TAPE_MISMATCH = 8


def _scale(v, factor):
    """v *= factor: drag, factor gamma_d (Hanley 2020 Eq 25), undone with 1/gamma_d (Eq 28)."""
    for q in numba.prange(v.shape[0]):
        for d in range(3):
            v[q, d] *= factor


def _scale_fixed(n, v, change, step):
    """Drag on the velocity grid: n += round(n change), v = n step, `change` gamma_d - 1
    (Eq 25) or (1 - gamma_d) / gamma_d to undo it (Eq 28; `drag`). Not invertible, as drag is
    not, but rounding the small product n change, not n gamma_d, merges two velocities only
    where drag itself must (a fraction |change| of them, -log2 gamma_d bits a value): n
    gamma_d near n ~ 2^51, rounded to 53 bits first, merged about one in eight."""
    for q in numba.prange(n.shape[0]):
        for d in range(3):
            n[q, d] += fx.to_grid(n[q, d] * change)
            v[q, d] = n[q, d] * step


def _drift(x, v, h):
    """x += h v with the half-step velocity, h = +dt (Hanley 2020 Eq 3) or -dt (Eq 18).

    Returns (particles whose nonzero displacement was too small to change a position, the
    last of them)."""
    lost = 0
    last = -1
    for q in numba.prange(x.shape[0]):
        below = False
        for d in range(3):
            moved = x[q, d] + h * v[q, d]
            if moved == x[q, d] and v[q, d] != 0.0:
                below = True
            x[q, d] = moved
        if below:
            lost += 1
            last = max(last, q)
    return lost, last


def _drift_in_cell(x, s, v, h, mid, length):
    """s += h v / L_mid, x = s L: the drift of Hanley 2020 Eq 3 in the cell coordinates of a
    deforming cell, L_mid its edges halfway through the step. Returns as `_drift`."""
    lost = 0
    last = -1
    for q in numba.prange(x.shape[0]):
        below = False
        for d in range(3):
            moved = s[q, d] + h * v[q, d] / mid[d]
            if moved == s[q, d] and v[q, d] != 0.0:
                below = True
            s[q, d] = moved
            x[q, d] = moved * length[d]
        if below:
            lost += 1
            last = max(last, q)
    return lost, last


scale = by_size(_scale, LIGHT)
scale_on_grid = by_size(_scale_fixed, LIGHT)
drift_free = by_size(_drift, LIGHT)
drift_in_cell = by_size(_drift_in_cell, LIGHT)


@jit
def kick_particles(p, fixed, law, h):
    """The half kick of the velocities and, where there are moments (a tangential law), of
    the angular velocities: on their grids in fixed-point arithmetic."""
    moments = law.tangential != NO_SHEAR  # without shear forces the moments are zero
    n = p.v.shape[0]
    if fixed.v.shape[0] > 0:
        grid = fixed.grid
        moved = fx.kick(n, fixed.v, p.v, p.f, p.inv_mass, h, grid[fx.VELOCITY])
        fx.note_overflow(fixed, fx.OF_VELOCITY, moved)
        if moments:
            step = grid[fx.ANGULAR_VELOCITY]
            moved = fx.kick(n, fixed.omega, p.omega, p.torque, p.inv_inertia, h, step)
            fx.note_overflow(fixed, fx.OF_ANGULAR_VELOCITY, moved)
        return
    kick(n, p.v, p.omega, p.f, p.torque, p.inv_mass, p.inv_inertia, h, moments)


@jit
def drag(p, fixed, gamma, undo):
    """v *= gamma (Hanley 2020 Eq 25), or `undo`: v /= gamma (Eq 28); on the velocity grid in
    fixed-point arithmetic, each velocity changed by its rounded product with gamma - 1, or
    with (1 - gamma) / gamma (both exact to an ulp, where 1 / gamma - 1 loses the digits
    the grid needs; `_scale_fixed`)."""
    if fixed.v.shape[0] > 0:
        change = (1.0 - gamma) / gamma if undo else gamma - 1.0
        scale_on_grid(p.v.shape[0], fixed.v, p.v, change, fixed.grid[fx.VELOCITY])
    else:
        scale(p.v.shape[0], p.v, 1.0 / gamma if undo else gamma)


@jit
def drift_on_grid(p, cell, fixed, h):
    """The drift in fixed-point arithmetic, then the positions the integers give. Motion
    below the grid is not lost information: the reversed drift rounds the same increment."""
    in_cell = p.s.shape[0] > 0  # positions are the coordinates of a deforming cell
    step = fixed.grid[fx.X : fx.Z + 1]
    n = p.x.shape[0]
    if not in_cell and step[0] == step[1] and step[1] == step[2]:  # as `state.fixed_grid` makes
        flat = (fixed.x.reshape(-1), p.x.reshape(-1), p.v.reshape(-1))
        fx.note_overflow(fixed, fx.OF_POSITION, fx.drift_uniform(n, *flat, h, step[0]))
        return
    moved = fx.drift(n, fixed.x, p.v, h, step, cell.mid, in_cell)
    fx.note_overflow(fixed, fx.OF_POSITION, moved)
    fx.mirror(n, fixed.x, p.x, p.s, step, cell.length)


@jit
def drift(p, cell, fixed, h, events, step):
    """The drift of every particle; in floating point a nonzero displacement too small to
    change a position (or a cell coordinate) is lost to round-off, and logged with the
    largest such displacement of the last particle it happened to."""
    if fixed.v.shape[0] > 0:
        drift_on_grid(p, cell, fixed, h)
        return
    n = p.x.shape[0]
    in_cell = p.s.shape[0] > 0
    if in_cell:
        pos = p.s
        lost, last = drift_in_cell(n, p.x, p.s, p.v, h, cell.mid, cell.length)
    else:
        pos = p.x
        lost, last = drift_free(n, p.x, p.v, h)
    if lost > 0:
        amount = 0.0
        for d in range(3):
            increment = h * p.v[last, d] / cell.mid[d] if in_cell else h * p.v[last, d]
            if p.v[last, d] != 0.0 and pos[last, d] + increment == pos[last, d]:
                amount = max(amount, abs(h * p.v[last, d]))
        note(events, MOTION_LOST, step, last, -1, amount, lost)


@inline_arrays
def forward_step(p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, elapsed, keep):
    """One forward step from `step` (Hanley 2020 Eq 1-12, with drag Eq 25-26); `elapsed`
    is the stage's time at its end. The damping forces at the new positions read the
    half-step velocity (velocity Verlet) or, with a velocity predictor, its prediction of
    the velocity there (`predictor.predict`). `keep`: the pair arrays keep the step's
    forces (`forces.compute_forces`)."""
    h = 0.5 * dt
    kick_particles(p, fixed, law, h)
    kick_cell(cell, fixed, h)
    if dyn.drag != 1.0:
        drag(p, fixed, dyn.drag, np.False_)
        note_fixed_points(p.v, p.v_drift, step + 1, events)
    move_cell(cell, fixed, dt, elapsed)
    drift(p, cell, fixed, dt, events, step + 1)
    place_walls(walls, elapsed)
    predict(p)  # v_P(t + dt) from v(t + dt/2) and the k before (Kolafa & Lisal 2011)
    compute_forces(p, pairs, walls, cell, fixed, law, moduli, dyn, np.int64(FORWARD), dt, h,
                   events, step + 1, keep)  # fmt: skip
    note_local_damping(events, step + 1, dyn)
    kick_cell(cell, fixed, h)


@inline_arrays
def reverse_step(p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, elapsed, keep):
    """One reversed step from `step`: the forward step's operations undone in reverse order.

    Kick back with the stored force (Eq 17, 27); undo the shear increment and spin
    correction at the later positions (inverse of Eq 10, 9); move the cell and drift back
    with the velocities the forward step moved with (Eq 18); undo drag (Eq 28); forces at
    the earlier positions, the shear history mapped back onto their contact planes (Eq 19,
    inverse of Eq 7-8), and the kick back (Eq 20); a velocity predictor predicts from the
    half-step velocities of the later steps, as going forward from the earlier ones, so
    the reversed step is the forward one with dt -> -dt. Mechanisms that destroy information
    (Coulomb cap, local and viscous damping, shear force lost at separation) run mirrored
    and are logged. `keep` as in `forward_step`.
    """
    h = -0.5 * dt
    kick_particles(p, fixed, law, h)
    kick_cell(cell, fixed, h)
    unwind_shear_history(p, pairs, walls, cell, law, moduli, dt)
    move_cell(cell, fixed, -dt, elapsed)
    drift(p, cell, fixed, -dt, events, step - 1)
    place_walls(walls, elapsed)
    if dyn.drag != 1.0:
        note_fixed_points(p.v, p.v_drift, step - 1, events)
        drag(p, fixed, dyn.drag, np.True_)
    predict(p)  # the same predictor on the reversed run's own history: dt -> -dt
    compute_forces(p, pairs, walls, cell, fixed, law, moduli, dyn, np.int64(REVERSE), dt, h,
                   events, step - 1, keep)  # fmt: skip
    note_local_damping(events, step - 1, dyn)
    kick_cell(cell, fixed, h)
    steer_back(cell)


@inline_arrays
def settle(tape, p, pairs, walls, cell, fixed, law, moduli, dyn, dt, step, recording):
    """Bring the reversed step's state at `step` to the forward run's with the information
    tape (`kernels.tape`), recording the entries (going forward, in the reversed step's
    shadow) or replaying them (going backward), in two passes: first the cell, positions
    and histories; where one changed, the forces are found again from them (the positions'
    images refreshed, the half kick taken back and given again, the histories taken as
    settled, neither capped nor rounded again: SETTLED), so that a force entry holds only
    what reads velocities; then the forces and velocities. Returns -1, or replaying, the
    pair i N + j of an entry that is not in the list."""
    h = -0.5 * dt
    damped = dyn.local_damping > 0.0 or law.beta_n > 0.0 or law.beta_t > 0.0
    if recording:
        touched = tp.record(
            tape, p, pairs, walls, cell, fixed, law, moduli.estar, h, np.True_, damped
        )
    else:
        touched, missing = tp.replay(tape, p, pairs, cell, fixed, step, h, np.True_)
        if missing >= 0:
            return missing
    if touched > 0:
        if p.s.shape[0] > 0:  # the cell's edges may have moved under the cell coordinates
            fx.mirror(p.x.shape[0], fixed.x, p.x, p.s, fixed.grid[fx.X : fx.Z + 1], cell.length)
        tp.unkick(p, fixed, h)
        scratch = np.zeros((len(KINDS), len(COLUMNS)))  # logged once, by the step itself
        compute_forces(p, pairs, walls, cell, fixed, law, moduli, dyn, np.int64(SETTLED), dt, h,
                       scratch, step, np.True_)  # fmt: skip
    if recording:
        tp.record(tape, p, pairs, walls, cell, fixed, law, moduli.estar, h, np.False_, damped)
        tp.close_step(tape)
    else:
        tp.replay(tape, p, pairs, cell, fixed, step, h, np.False_)
    return -1


@inline_arrays
def record_step(tape, p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, first):
    """Record the tape entries of the forward step just taken from `step`: the reversed step
    from step + 1 taken in place, its state settled onto the state before the forward
    step, then undone (the shadow reversal); or, where that reversal would find all but the
    pairs' histories again (`tape.predictable`), those predicted (`tape.predict`)."""
    if tape.predicting:
        tp.predict(tape, p, pairs, law)
        tp.close_step(tape)
        return
    tp.classify(tape, pairs, walls)
    tp.hold(tape)
    elapsed = (step - first) * dt
    reverse_step(
        p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step + 1, elapsed, np.True_
    )
    settle(tape, p, pairs, walls, cell, fixed, law, moduli, dyn, dt, step, np.True_)
    tp.restore(tape, p, cell, fixed)


@jit
def rebuild_pairs(p, pairs, cell, skin):
    """Rebuild the pair list at the current positions, carrying contact history.

    Returns PAIR_OVERFLOW, leaving the list as it was, when the new list does not fit (the
    number needed is then in pairs.count[1]), and CELL_TOO_SMALL when a periodic edge is no
    longer twice the contact reach, so that a pair could touch through two images.
    """
    cutoff = 2.0 * p.radius.max() + skin
    for d in range(3):
        if cell.periodic[d] and cell.length[d] <= 2.0 * cutoff:
            return CELL_TOO_SMALL
    new_i = np.empty(pairs.i.shape[0], dtype=np.int32)  # the new list, while it is built:
    new_j = np.empty(pairs.j.shape[0], dtype=np.int32)  # not kept from one build to the next
    needed = build_pairs(p.x, p.radius, skin, cell.periodic, cell.length, new_i, new_j)
    pairs.count[1] = needed
    if needed > pairs.i.shape[0]:
        return PAIR_OVERFLOW
    old = pairs.count[0]
    for history in (pairs.history, pairs.rolling):  # those of the laws a run has
        if history.shape[0] > 0:
            carry_history(pairs.i, pairs.j, old, new_i, new_j, needed, history)
    pairs.i[:needed] = new_i[:needed]
    pairs.j[:needed] = new_j[:needed]
    pairs.count[0] = needed
    index_by_particle(pairs.i, pairs.j, needed, pairs.first, pairs.start, pairs.slots)
    note_normals(p, pairs, cell)
    pairs.x_built[:] = p.x
    cell.built[:] = cell.length
    return OK


@jit
def needs_rebuild(p, pairs, cell, dt, skin, direction):
    """Whether some pair could close half the skin in the next step: twice the largest
    reach of a particle from its place at the last build, plus the relative change of the
    cell's edges times the largest contact reach, exceeds the skin. The largest radius is
    looked for only in a cell that has changed or is changing (a serial pass, 1.2 ns a
    sphere: in the fcc benchmark 1.5 % of a step without friction)."""
    reach = largest_reach(
        p.x.shape[0], p.x, pairs.x_built, p.v, p.f, p.inv_mass, dt, direction, cell.length,
        cell.built,
    )  # fmt: skip
    strain = 0.0
    for d in range(3):
        ahead = dt * abs(cell.rate[d]) / cell.length[d]
        strain = max(strain, abs(cell.length[d] / cell.built[d] - 1.0) + ahead)
    closing = 0.0  # how much the cell's change can close a pair's gap
    if strain > 0.0:
        closing = strain * (2.0 * p.radius.max() + skin)
    return 2.0 * reach + closing > skin


@jit
def advance(
    p, pairs, walls, cell, fixed, law, moduli, dyn, events, tape, stepping, step, stop, until,
    obs, obs_steps,
):  # fmt: skip
    """Run whole steps from `step` towards `stop` (forward if stop > step, else reversed),
    returning at `until` (`stop`, or a step before it: the caller's pause, which changes
    nothing of the stepping), with the settings `stepping` (arrays.Stepping).

    Observables are recorded into the rows of `obs` (their steps into `obs_steps`, int64)
    at every step where (step - first step)
    % every == 0 and at the stage's last step, each after the state there passed
    `health.examine`, which is also asked at `stop` and before each rebuild of the pair
    list. Returns (status, step reached, rows recorded, the last `health.Finding`); status
    PAIR_OVERFLOW means the pair list must grow before stepping on, CELL_TOO_SMALL that the
    cell has shrunk too far (the state is then at a whole step), FIXED_OVERFLOW that a
    value left its fixed-point grid in the step just taken (fixed.overflow says which),
    BLOWN_UP that the state at the step reached is not physical (the finding says why; the
    rows recorded are of the steps before), HALTED that `stepping.halt` asked for a stop
    (the state is at the whole step reached; one step after the signal where the step it
    came in did not write the pair arrays, which the checkpoint holds). With an information
    tape (`kernels.tape`) recording, each forward step records its entries, and TAPE_FULL
    says that the block must be written out before the next (where the step just taken made
    more entries than the block had room for, `io.tape.Recorder.flush` leaves it out and
    asks for it again: the loop then takes its `record_step` again first, even where `step`
    is `until`); replaying, each reversed step applies them, and TAPE_EMPTY says that the
    block holds no more, TAPE_MISMATCH that an entry's pair is not in the list (the
    finding's particle and partner).
    """
    dt, skin, limit = stepping.dt, stepping.skin, stepping.overlap_limit
    first, last, every = stepping.first_step, stepping.last_step, stepping.every
    direction = 1 if stop > step else -1
    rows = 0
    finding = Finding(HEALTHY, -1, -1, 0.0)
    if tape.mode == tp.RECORD and tape.span[4] != 0:  # the step before, recorded again
        tape.span[4] = 0
        record_step(
            tape, p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step - 1, first
        )
    # the bundles go to each call as they are: a tuple of them built at each step would take
    # and give back a reference to each of their arrays, an atomic update each (with two
    # spheres, 360 of the 1 390 updates a step; ARCHITECTURE.md, per-step calls)
    kept = False  # the pair arrays hold the forces of the step reached (unknown on entry)
    while step != until:
        if stepping.halt[0] != 0 and kept:  # else one more step first, which keeps them
            return HALTED, step, rows, finding
        if tape.mode == tp.RECORD and not tp.has_room(tape):
            return TAPE_FULL, step, rows, finding
        if tape.mode == tp.REPLAY and not tp.holds(tape, step - 1):
            return TAPE_EMPTY, step, rows, finding
        if needs_rebuild(p, pairs, cell, dt, skin, direction):
            finding = examine(p, pairs, walls, cell, limit)
            if finding.what != HEALTHY:  # not worth a search
                return BLOWN_UP, step, rows, finding
            status = rebuild_pairs(p, pairs, cell, skin)
            if status != OK:
                return status, step, rows, finding
        elapsed = (step + direction - first) * dt
        after = step + direction
        kept = (  # whatever reads the pair arrays before the next step: the tape, an
            # observation, the caller (at `until`, `stop` or a halt)
            tape.mode != tp.OFF
            or (after - first) % every == 0
            or after == last
            or after == until
            or after == stop
            or stepping.halt[0] != 0
        )
        if direction > 0:
            if tape.mode == tp.RECORD:
                tp.keep(tape)
            forward_step(
                p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, elapsed, kept
            )
            if tape.mode == tp.RECORD:
                record_step(
                    tape, p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, first
                )
        else:
            reverse_step(
                p, pairs, walls, cell, fixed, law, moduli, dyn, events, dt, step, elapsed, kept
            )
            if tape.mode == tp.REPLAY:
                missing = settle(
                    tape, p, pairs, walls, cell, fixed, law, moduli, dyn, dt, step - 1, np.False_
                )
                if missing >= 0:
                    n = p.x.shape[0]
                    return TAPE_MISMATCH, step - 1, rows, Finding(HEALTHY, missing // n,
                                                                  missing % n, 0.0)  # fmt: skip
        step += direction
        if fixed.overflow[0] != 0:
            return FIXED_OVERFLOW, step, rows, finding
        recorded = (step - first) % every == 0 or step == last
        if recorded or step == stop:
            finding = examine(p, pairs, walls, cell, limit)
            if finding.what != HEALTHY:
                return BLOWN_UP, step, rows, finding
        if recorded:
            obs_steps[rows] = step
            observe(p, pairs, walls, cell, law, moduli, dyn, obs[rows])
            rows += 1
        if tape.mode == tp.RECORD and tp.overflowed(tape):
            return TAPE_FULL, step, rows, finding
    return OK, step, rows, finding
