"""The information tape: what a reversal cannot recompute, recorded going forward and
given back going backward, so that any run in fixed-point arithmetic reverses to its own
starting integers, whatever destroyed information on the way (Hanley 2020 §4-5).

The rule is the one of reversible computing (Maclaurin, Duvenaud & Adams 2015, §2.3):
wherever the reversed step cannot recompute a value, the forward step records the
difference between the true value and what the reversed step predicts. Here the
prediction is the reversed step itself: after each forward step from state S_n to
S_{n+1}, a reversed step is taken from S_{n+1} (a shadow of the reversal, in place, then
undone by copying back the arrays a step changes), and what it arrives at, S'_n, is
compared with S_n array by array. Every difference becomes an entry (array, place,
amount), integers throughout:

- positions, velocities and angular velocities are the integers of fixed-point arithmetic,
  and the entry is their difference in grid steps;
- net forces and moments, the shear and rolling histories and the cell's own floating-point
  arrays are compared by their bits, read as integers in the order of the numbers
  (`ordered`), so the entry counts the doubles between the two values: floating point is
  its own grid, and the forward run is the same bit for bit with or without the tape.

A force entry changes the half kick the reversed step took with it: the velocity is
kicked again with the corrected force (`rekicked`) before velocities are compared, so a
velocity entry holds only what the kick does not explain (drag's remainder). The reversed
run applies the entries of step n right after its step to n, in the same order and by the
same function (`settle`), so it reaches S_n bit for bit; the shadow reversal is the real
one bit for bit because every per-contact value depends only on its own pair and every
sum is taken in a fixed order (a particle's pairs by partner index).

Where the reversal finds every array but the pairs' shear histories again (`predictable`:
no damping, drag, rolling resistance, moving cell or wall contact with history), the shadow
reversal is not taken: the forward pair loop works out, beside each new history, the one
the reversed step would find from it (`contact.earlier_shear`: unwound at the later
positions, turned back, capped and rounded at the earlier ones, with the functions the
reversed step calls and the overlap and normal the pair had there), and `predict` records
their differences alone, entry for entry what the shadow reversal records. A settled
history gives the force the forward step found from it (the reversal finds forces from
settled histories taking them as they are, `SETTLED`), so that no force or velocity entry
follows.

Entries of the pair arrays are keyed by the pair (i, j), not by its slot, since the
reversed run builds its own list at other steps. Each entry also counts as
log2(1 + 2|amount|) bits, the bits that tell an integer from the others of at most its
size, charged to the mechanism that made it (`MECHANISMS`); a history's amount counted in
steps of its contact's own grid (`contact.history_step`), not in doubles, since the forward
run holds it on that grid: a history a grid step off costs log2 3 bits, not the 12 or more
of the doubles between.
"""

from collections import namedtuple

import numpy as np

from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels import inline, inline_arrays, jit
from revdem_cli.kernels.cell import deforms
from revdem_cli.kernels.contact import NO_ROLLING, NO_SHEAR, history_step, normal_law, reduced
from revdem_cli.kernels.information import bits_of, grid_bits, ordered, unordered
from revdem_cli.kernels.pairs import AMOUNT, MISSED, SPREAD, next_listed

OFF, RECORD, REPLAY = range(3)

COMPARED = (
    "cell_edges",  # fixed.length, the cell's edges on their grid
    "cell_edge_rates",  # fixed.rate
    "cell_length",  # cell.length, m (bits)
    "cell_rate",  # cell.rate, m/s (bits)
    "position",  # fixed.x
    "shear_history",  # pairs.history, N (bits), keyed by pair
    "rolling_history",  # pairs.rolling, N m (bits), keyed by pair
    "wall_shear_history",  # walls.history (bits)
    "wall_rolling_history",  # walls.rolling (bits)
    "cell_force",  # cell.force, the inertial servo's force on each edge, N (bits)
    "cell_stress",  # cell.stress, which the next step's servo reads, Pa (bits)
    "force",  # particles' net forces, N (bits)
    "moment",  # particles' net moments, N m (bits)
    "velocity",  # fixed.v, grid steps
    "angular_velocity",  # fixed.omega
)
"""The arrays compared: every array a reversed step reads from the state it starts from. They
are settled in two passes: first what forces are found from (the cell before the positions
its coordinates scale, then the histories), then, once the forces have been found again
from those, what comes of the forces (forces before the velocities they kick)."""
(
    CELL_EDGES,
    CELL_EDGE_RATES,
    CELL_LENGTH,
    CELL_RATE,
    POSITION,
    SHEAR,
    ROLLING,
    WALL_SHEAR,
    WALL_ROLLING,
    CELL_FORCE,
    CELL_STRESS,
    FORCE,
    MOMENT,
    VELOCITY,
    ANGULAR_VELOCITY,
) = range(len(COMPARED))
SECOND = CELL_FORCE
"""The first array of the second pass."""

MECHANISMS = (
    "coulomb_slip",  # a shear history capped at mu |f_n| (§5.1)
    "contact_lost_with_shear_force",  # a shear history zeroed at separation (§4)
    "rolling_limit",  # a rolling history capped at its law's limit (§5.3)
    "contact_lost_with_rolling_moment",  # a rolling history zeroed at separation
    "round_off",  # what the reversed remap and turn of a history (Eq 7-9) miss by round-off
    "damping",  # forces that read velocities: local (Eq 21) and viscous damping (§5.2)
    "drag",  # the velocity drag's rounding leaves (Eq 25, 28; §5.2)
    "cell_servo",  # the cell's edges and what they move: a servo reads the stress (Eq 23)
)
"""What an entry is charged to: a history's by what its contact did in the forward step,
the rest by the array."""
SLIP, LOST, LIMIT, ROLLED_OFF, ROUND_OFF, DAMPING, DRAG, SERVO = range(len(MECHANISMS))

Tape = namedtuple(
    "Tape",
    [
        "mode",  # OFF, RECORD or REPLAY
        "live",  # the arrays a step changes, as int64 views (each holds 8-byte numbers), a
        # fixed number of them
        "kept",  # their copies while the shadow reversal runs
        "state",  # the arrays of COMPARED as int64 views (the doubles' bits), in that order
        "before",  # their copies at the start of the step
        "causes",  # per pair slot: what its shear (2k) and rolling (2k + 1) history did
        "wall_causes",  # per wall contact q W + b, the same
        "what",  # entries: the array (index in COMPARED), int64 (E,)
        "where",  # the place: flat index, or for pair arrays (i N + j) 3 + axis, int64 (E,)
        "amount",  # true value minus the reversal's, int64 (E,)
        "counts",  # entries of each step of the block, int64 (S,)
        "bits",  # bits of each step of the block by mechanism, (S, len(MECHANISMS))
        "contacts",  # contacts (or particles, or edges) with entries, same shape, int64
        "offsets",  # first entry of each step of the block, int64 (S + 1,)
        "span",  # [first step of the block, steps in it, entries in it, the most entries a
        # step has made, 1 where the step before the block is to be recorded again], int64 (5,)
        "predicting",  # 1 where the forward pair loop predicts the reversal's histories
        # (`predictable`), with no shadow reversal
    ],
)
"""Entries are labelled by the step whose state they restore: a forward step from n records
label n, and the reversed step to n applies it. The helpers of one entry take no bundle, and
those that take arrays are inlined by numba (`inline_arrays`): a compiled call pays a
reference-count update for each array it receives, which would cost more than the entry."""


@inline
def contact_grid(law, rolling, overlap, rstar, modulus):
    """The grid step of a contact's shear history (or with `rolling` its rolling one) from its
    overlap, R* and E*: scalars, so that one entry's work takes no array (see `Tape`)."""
    elastic = normal_law(law, overlap, rstar, modulus)[0] if overlap > 0.0 else 0.0
    return history_step(law, elastic * (rstar if rolling else 1.0))


@inline_arrays
def rekicked(f, inv, q, h, step):
    """The increment, in grid steps, of the reversed step's half kick h f / m of one
    component, as `fixed.kick_coordinates` takes it."""
    return fx.to_grid(fx.kick_steps(h, f, inv[q], step))


@jit
def _copy(into, arrays):
    """into[k][:] = arrays[k] for each array, element by element (a slice assignment would
    first look for overlap, and copy through a temporary)."""
    for k in range(len(arrays)):
        source, target = arrays[k], into[k]
        for e in range(source.shape[0]):
            target[e] = source[e]


@jit
def keep(tape):
    """`before` <- the compared arrays now (S_n) (none where predicting)."""
    _copy(tape.before, tape.state)


@jit
def hold(tape):
    """`kept` <- the arrays a step changes (S_{n+1}), before the shadow reversal."""
    _copy(tape.kept, tape.live)


@jit
def restore(tape, p, cell, fixed):
    """The arrays a step changes back to `kept`: the shadow reversal undone; the positions'
    and velocities' images, which are not kept, made again from their integers."""
    _copy(tape.live, tape.kept)
    fx.mirror(p.x.shape[0], fixed.x, p.x, p.s, fixed.grid[fx.X : fx.Z + 1], cell.length)
    v_step = fixed.grid[fx.VELOCITY]
    w_step = fixed.grid[fx.ANGULAR_VELOCITY]
    for q in range(p.v.shape[0]):
        for d in range(3):
            p.v[q, d] = fixed.v[q, d] * v_step
            p.omega[q, d] = fixed.omega[q, d] * w_step


@inline
def _cause(destroyed, apart, capped, lost):
    """What a contact's history did in the forward step: `capped` (SLIP, LIMIT) or `lost` at
    separation where some of it was destroyed, ROUND_OFF otherwise."""
    if destroyed > 0.0:
        return lost if apart else capped
    return ROUND_OFF


@jit
def classify(tape, pairs, walls):
    """What each contact's histories did in the forward step just taken (S_n to S_{n+1}):
    capped (slip, rolling limit) or lost at separation; round-off otherwise (`_cause`)."""
    n = pairs.count[0]
    for k in range(min(n, pairs.destroyed.shape[0])):
        apart = pairs.overlap[k] <= 0.0
        tape.causes[2 * k] = _cause(pairs.destroyed[k], apart, SLIP, LOST)
        if pairs.rolled.shape[0] > 0:
            tape.causes[2 * k + 1] = _cause(pairs.rolled[k], apart, LIMIT, ROLLED_OFF)
    if walls.history.shape[0] == 0:
        return
    count = walls.overlap.shape[1]
    for q in range(walls.overlap.shape[0]):
        for b in range(count):
            c = q * count + b
            apart = walls.overlap[q, b] <= 0.0
            tape.wall_causes[2 * c] = _cause(walls.destroyed[q, b], apart, SLIP, LOST)
            if walls.rolled.shape[0] > 0:
                tape.wall_causes[2 * c + 1] = _cause(walls.rolled[q, b], apart, LIMIT,
                                                     ROLLED_OFF)  # fmt: skip


@inline
def _charged(what, damped):
    """The mechanism every entry of array `what` is charged to, or -1 for a history's, which
    its contact's cause says (`classify`). `damped`: forces read velocities."""
    if what <= POSITION or what == CELL_FORCE or what == CELL_STRESS:
        return SERVO
    if what == FORCE or what == MOMENT:
        return DAMPING if damped else ROUND_OFF
    if what == VELOCITY or what == ANGULAR_VELOCITY:
        return DRAG
    return -1


@inline
def _in_order(what):
    """Whether array `what` holds doubles, compared and changed in their order."""
    integers = what == CELL_EDGES or what == CELL_EDGE_RATES or what == POSITION
    return not (integers or what == VELOCITY or what == ANGULAR_VELOCITY)


@inline
def _targets(what, p, fixed):
    """What an entry of array `what` acts on besides it: the forces, inverse masses,
    velocity integers and their images, and the velocity grid step of its particles (the
    angular ones for moments and angular velocities)."""
    if what == MOMENT or what == ANGULAR_VELOCITY:
        return p.torque, p.inv_inertia, fixed.omega, p.omega, fixed.grid[fx.ANGULAR_VELOCITY]
    return p.f, p.inv_mass, fixed.v, p.v, fixed.grid[fx.VELOCITY]


@inline_arrays
def _apply(values, what, index, amount, h, forces, inverse, ints, images, step, x, s, length,
           grid):  # fmt: skip
    """Add `amount` to `values` (array `what`, flat) at `index` (doubles: in their order), with
    what follows from it: a force or moment kicks its velocity again (`_targets`), a
    velocity, angular velocity or position refreshes its image (positions: x, and in a
    deforming cell s, with the cell's `length` and the position `grid`). Plain arrays: one
    entry's work takes no bundle. `values` is a view of `forces` (or of `ints`) where the
    entry is one of theirs: every value is carried from where it is made, never read back
    through the other view, so that no reordering of loads and stores can matter."""
    q, axis = index // 3, index % 3
    if what == FORCE or what == MOMENT:
        wrong = forces[q, axis]
        bits = unordered(ordered(values[index]) + amount)
        values[index] = bits
        right = np.int64(bits).view(np.float64)
        moved = (
            ints[q, axis]
            + rekicked(right, inverse, q, h, step)
            - rekicked(wrong, inverse, q, h, step)
        )
        ints[q, axis] = moved
        images[q, axis] = moved * step
    elif _in_order(what):
        values[index] = unordered(ordered(values[index]) + amount)
    else:
        moved = values[index] + amount
        values[index] = moved
        if what == VELOCITY or what == ANGULAR_VELOCITY:
            images[q, axis] = moved * step
        elif what == POSITION and s.shape[0] > 0:
            s[q, axis] = moved * grid[axis]
            x[q, axis] = s[q, axis] * length[axis]
        elif what == POSITION:
            x[q, axis] = moved * grid[axis]


@inline_arrays
def _slot(first, partners, i, j):
    """The slot of pair (i, j) in the list, -1 if it is not listed."""
    for k in range(first[i], first[i + 1]):
        if partners[k] == j:
            return k
    return -1


@inline
def _keyed(i, j, n):
    """The place of pair (i, j)'s first component in a pair array's entries, (i N + j) 3:
    the same whichever list the pair is in."""
    return (np.int64(i) * n + j) * 3


@inline_arrays
def _entry(whats, wheres, amounts, used, what, where, amount):
    """Entry `used` of the block <- (what, where, amount), where it has room (counted either
    way: `overflowed`); returns the entries counted."""
    if used < whats.shape[0]:
        whats[used] = what
        wheres[used] = where
        amounts[used] = amount
    return used + 1


@jit
def _settled(tape, what, values, was, used, p, pairs, walls, cell, fixed, law, estar, h, damped):
    """Record the differences of the array `what` of the reversal's state, `values`, from
    `was`, the forward run's, as `record` does, a pair's history on the grid of its contact
    at the reversal's overlap, and apply them (`values` then is `was`); returns the entries
    counted, `used` with them."""
    label = tape.span[1]
    n = p.x.shape[0]
    radius, material = p.radius, p.material
    walls_each = walls.overlap.shape[1]
    forces, inverse, ints, mirrors, step = _targets(what, p, fixed)
    keyed = what == SHEAR or what == ROLLING
    size = min(3 * pairs.count[0], values.shape[0]) if keyed else values.shape[0]
    charged = _charged(what, damped)
    causes = tape.wall_causes if what >= WALL_SHEAR else tape.causes
    rolling = 1 if what == ROLLING or what == WALL_ROLLING else 0
    in_order = _in_order(what)
    counted = -1  # the last contact (or particle, or edge) charged with an entry
    spacing = 0.0  # its history's grid step (the components of one contact come together)
    for index in range(size):
        if values[index] == was[index]:
            continue
        if in_order:
            amount = ordered(was[index]) - ordered(values[index])
        else:
            amount = was[index] - values[index]
        where = index
        if keyed:
            k = index // 3
            where = _keyed(pairs.i[k], pairs.j[k], n) + index % 3
        used = _entry(tape.what, tape.where, tape.amount, used, what, where, amount)
        mechanism = charged if charged >= 0 else causes[2 * (index // 3) + rolling]
        if index // 3 != counted:
            tape.contacts[label, mechanism] += 1
            counted = index // 3
            if charged < 0 and what <= ROLLING:  # a history, on its contact's grid
                c = index // 3
                i, j = pairs.i[c], pairs.j[c]
                rstar = reduced(radius[i], radius[j])
                modulus = estar[material[i], material[j]]
                spacing = contact_grid(law, rolling == 1, pairs.overlap[c], rstar, modulus)
            elif charged < 0:
                q, b = index // 3 // walls_each, index // 3 % walls_each
                modulus = estar[material[q], walls.material[b]]
                spacing = contact_grid(law, rolling == 1, walls.overlap[q, b], radius[q], modulus)
        if charged < 0:
            tape.bits[label, mechanism] += grid_bits(was[index], values[index], spacing)
        else:
            tape.bits[label, mechanism] += bits_of(amount)
        _apply(
            values,
            what,
            index,
            amount,
            h,
            forces,
            inverse,
            ints,
            mirrors,
            step,
            p.x,
            p.s,
            cell.length,
            fixed.grid,
        )
    return used


@jit
def record(tape, p, pairs, walls, cell, fixed, law, estar, h, first, damped):
    """Settle the shadow reversal's state S'_n onto `before` (S_n): the arrays of the `first`
    pass, or of the second, each in the order of COMPARED, appending each difference as an
    entry of the block's step being recorded and charging its bits; `h` is the reversed
    step's half kick, -dt/2; `damped`: forces read velocities, so that a force entry is
    charged to damping rather than to round-off; `law` and `estar` (moduli.estar): what a
    history's grid is found from (at the reversal's overlaps). Entries past the block's room
    are counted and applied but not written: the step is then taken again once the block has
    room (`overflowed`). Returns the entries counted."""
    used = tape.span[2]
    for what in range(0 if first else SECOND, SECOND if first else len(COMPARED)):
        used = _settled(tape, what, tape.state[what], tape.before[what], used, p, pairs, walls,
                        cell, fixed, law, estar, h, damped)  # fmt: skip
    recorded = used - tape.span[2]
    tape.span[2] = used
    return recorded


@jit
def predictable(p, pairs, walls, cell, law, dyn):
    """Whether the reversal of a forward step finds every array but the pairs' shear
    histories again, so that those are all the tape holds and the forward pair loop can
    predict them itself (`predict`): fixed-point positions and velocities (the tape's
    arithmetic), no velocity read by a force (local or viscous damping) nor drag, no rolling
    resistance, a cell that does not move, no wall contact with a history, and the room for
    the prediction (`Pairs.earlier`, a run with a tape and shear)."""
    quiet = dyn.local_damping == 0.0 and law.beta_n == 0.0 and law.beta_t == 0.0
    walled = walls.kind.shape[0] > 0 and law.tangential != NO_SHEAR
    plain = quiet and law.rolling == NO_ROLLING and dyn.drag == 1.0
    room = pairs.earlier.shape[0] > 0 or law.tangential == NO_SHEAR
    return plain and room and not deforms(cell) and not walled


@jit
def predict(tape, p, pairs, law):
    """Record the entries of the forward step just taken (S_n to S_{n+1}) of a run whose
    reversal finds all but the pairs' shear histories again (`predictable`), with no shadow
    reversal: of each pair the forward pair loop listed in `Pairs.earlier`
    (`pairs.list_missed`), the history it had at S_n less the one the reversed step would
    find there (`contact.earlier_shear`) and its bits (`information.grid_bits`, from the
    spread the list holds), the list left as it is, so that a step can
    be recorded again. What it records is what the shadow reversal would, entry for entry
    and bit for bit."""
    if law.tangential == NO_SHEAR:
        return
    label = tape.span[1]
    used = tape.span[2]
    n = p.x.shape[0]
    count = pairs.count[0]
    listed = pairs.earlier
    row = 0
    while row < count:  # each chunk's list, in slot order (`pairs.MISSED_COLUMNS`)
        missed = listed[row, MISSED]
        if missed < 0.0:  # the end of a chunk's list
            row = next_listed(missed)
            continue
        k = np.int64(missed)
        cause = _cause(pairs.destroyed[k], pairs.overlap[k] <= 0.0, SLIP, LOST)
        tape.contacts[label, cause] += 1
        key = _keyed(pairs.i[k], pairs.j[k], n)
        for axis in range(3):
            amount = np.float64(listed[row, AMOUNT + axis]).view(np.int64)
            if amount == 0:
                continue
            used = _entry(tape.what, tape.where, tape.amount, used, SHEAR, key + axis, amount)
            tape.bits[label, cause] += np.log2(1.0 + listed[row, SPREAD + axis])
        row += 1
    tape.span[2] = used


@jit
def close_step(tape):
    """End the step being recorded: its entries counted, the next step's begun."""
    label = tape.span[1]
    tape.counts[label] = tape.span[2] - tape.offsets[label]
    tape.span[3] = max(tape.span[3], tape.counts[label])
    tape.offsets[label + 1] = tape.span[2]
    tape.span[1] = label + 1


@jit
def replay(tape, p, pairs, cell, fixed, step, h, first):
    """Apply the entries of `step` (the reversed run has just stepped to it) as `record`
    settled them: those of the `first` pass, or of the second. Returns (the entries
    applied, -1), or where an entry's pair is not in the list (-1, the pair i N + j)."""
    label = step - tape.span[0]
    n = p.x.shape[0]
    applied = 0
    last = -1
    values = tape.state[0]
    forces, inverse, ints, images, grid_step = _targets(0, p, fixed)
    for e in range(tape.offsets[label], tape.offsets[label + 1]):
        what = tape.what[e]
        if (what < SECOND) != first:
            continue
        if what != last:  # a step's entries come array by array
            values = tape.state[what]
            forces, inverse, ints, images, grid_step = _targets(what, p, fixed)
            last = what
        index = tape.where[e]
        if what == SHEAR or what == ROLLING:
            key = index // 3
            k = _slot(pairs.first, pairs.j, key // n, key % n)
            if k < 0:
                return -1, key
            index = 3 * k + index % 3
        amount = tape.amount[e]
        _apply(values, what, index, amount, h, forces, inverse, ints, images, grid_step, p.x,
               p.s, cell.length, fixed.grid)  # fmt: skip
        applied += 1
    return applied, -1


@jit
def unkick(p, fixed, h):
    """Take back the half kick h f / m (and h t / I) the reversed step's gather gave with the
    forces it found, before they are found again (`fixed.kick_coordinates` undone)."""
    v_step = fixed.grid[fx.VELOCITY]
    w_step = fixed.grid[fx.ANGULAR_VELOCITY]
    for q in range(p.f.shape[0]):
        for d in range(3):
            fixed.v[q, d] -= rekicked(p.f[q, d], p.inv_mass, q, h, v_step)
            p.v[q, d] = fixed.v[q, d] * v_step
            fixed.omega[q, d] -= rekicked(p.torque[q, d], p.inv_inertia, q, h, w_step)
            p.omega[q, d] = fixed.omega[q, d] * w_step


@jit
def has_room(tape):
    """Whether the record block has room for one more step: for its label, and for as many
    entries as the most a step has made so far."""
    return tape.span[1] < tape.counts.shape[0] and tape.span[2] + tape.span[3] <= tape.what.shape[0]


@jit
def overflowed(tape):
    """Whether the step just recorded made more entries than the block had room for."""
    return tape.span[2] > tape.what.shape[0]


@jit
def holds(tape, step):
    """Whether the replay block holds the entries of `step`."""
    return 0 <= step - tape.span[0] < tape.span[1]
