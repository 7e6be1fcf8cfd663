"""The pair loop: the force on i from j of every listed pair (Hanley 2020 Eq 4-10), each
computed once and written to its own slot, with the shear force it destroyed counted.

The pair loop works in blocks of BLOCK pairs, so that LLVM can vectorise the contact
physics (four pairs at a time in 256-bit vectors, which LLVM prefers on AVX-512 hosts
too). A block is ROWS x BLOCK doubles, a row per quantity and a column per pair, and goes
through three stages:
- gather: each pair's separation, radii, moduli, velocities and history into its column
  (scalar: the particles' rows are scattered in memory), then the separations' nearest
  periodic images in a vector loop of their own (`to_nearest_images`);
- contact stage: `contact.contact_force` and its geometry and kinematics, column by column,
  reading and writing the block only, so the loop is elementwise over contiguous rows (with
  the spin correction's cos and sin as their series; a block where some touching pair's
  angle is too large for that is done again with them in full; a pair apart has none);
- scatter: each column's force, history, moment (fixed point: normal) and overlap into the
  pair arrays, counting the shear force destroyed (scalar, branches), and each particle's
  sums (`sum_in_order`); the forces, moments and overlaps only at steps after which
  something reads them (`keep`, which `forces.compute_forces` decides) or of pairs whose
  particles the chunk does not sum (`Pairs.foreign`). Plain stores: non-temporal ones,
  which gained on an Intel host when the pair loop wrote every force, made the fixed-point
  pair loop 36-50 % slower on an AMD EPYC (Zen 4) at n = 24 and 32 fcc, whose pair results
  exceed its L3 cache at 32.
Every pair's numbers are those of the scalar formulas, in the same order. The pair list is
cut into as many chunks as the loop runs on threads, each particle's own pairs in one
(`chunk_of`), each chunk worked through with its own block of `Pairs.blocks` (one for each
thread of numba's pool), so the loop allocates nothing. Each chunk holds the share of the
pairs that its thread, at the pace it kept in the call before, finishes with the others
(`balanced`): a chunk's work a pair depends on where the particles summed apart lie, and its
thread's pace on its core (shared, busy, or a slower kind of core). Summing, a chunk sums
the particles all of whose pairs it holds; those with a partner in an earlier chunk are
summed after every chunk is done, from the pair arrays (`sum_foreign`, dealt out to the
threads `SHARE` at a time), so that every sum has the same terms in the same order on any
thread count. That costs: on one thread, the fcc pair loop cut into 16 chunks took 13-30 %
longer than in one (256 and 4 000 spheres), so one thread works through the list in one
chunk; the serial build knows it, a constant (`one_thread`).
"""

import math

import numba
import numpy as np

from revdem_cli.kernels import HEAVY, by_size, clock_ns, inline, one_thread, threads_for
from revdem_cli.kernels.arrays import ContactLaw
from revdem_cli.kernels.cell import affine_velocity, nearest_image, strain_rates
from revdem_cli.kernels.contact import (
    FORWARD,
    NO_ROLLING,
    NO_SHEAR,
    REVERSE,
    SETTLED,
    SMALL_ANGLE,
    STATIC,
    capped_away,
    contact_force,
    contact_velocity,
    earlier_shear,
    lever_arm,
    reduced,
    rolling_moment,
)
from revdem_cli.kernels.fixed import magnitude_bits, snapped_in_range
from revdem_cli.kernels.gather import weight_summed
from revdem_cli.kernels.information import grid_spread, ordered
from revdem_cli.kernels.vectors import ZERO, axpy, cross, dot, norm, put, row, scaled

APART = 1.0 + 1e-12
"""Pairs farther apart than (1 + 1e-12) (r_i + r_j) are certainly not touching, so their
distance needs no square root."""


@inline
def separation(x, i, j, image):
    """x_j - x_i, across periodic boundaries to the nearest image (`cell.nearest_image`)."""
    return nearest_image(axpy(-1.0, row(x, i), row(x, j)), image)


@inline
def pair_velocity(d, n, overlap, r_i, r_j, v_ij, w_i, w_j, strain, deforming):
    """(velocity of j relative to i at the contact, mean spin about n) of a pair with radii
    r_i, r_j, separation d, normal n, centres' relative velocity v_ij = v_j - v_i and spins
    w_i, w_j; in a deforming cell the relative velocity includes the cell's affine motion
    (`strain` from `cell.strain_rates`)."""
    vrel = contact_velocity(n, lever_arm(r_i, overlap), lever_arm(r_j, overlap), v_ij, w_i, w_j)
    if deforming:
        vrel = axpy(1.0, affine_velocity(d, strain), vrel)
    return vrel, 0.5 * (dot(w_i, n) + dot(w_j, n))


@inline
def pair_overlap(d, reach):
    """(overlap, distance) of a pair with separation d and reach r_i + r_j; pairs certainly
    apart (by more than APART) get overlap -1 and distance 0 without a square root."""
    dist2 = dot(d, d)
    if dist2 > (APART * reach) ** 2:
        return -1.0, 0.0
    dist = math.sqrt(dist2)
    return reach - dist, dist


@inline
def pair_geometry(d, r_i, r_j):
    """(overlap, unit normal n from i to j, R* = r_i r_j / (r_i + r_j)) of a pair with
    separation d = x_j - x_i and radii r_i, r_j (Hanley 2020 Eq 6): the one place a loop
    over pairs finds them, so that the forces, their unwinding, the fixed-point normals and
    the observables agree to the bit. A pair apart (overlap <= 0; certainly apart, -1 without
    a distance, `pair_overlap`) gets a zero normal: its spin about n is zero, and the normal
    the fixed-point histories turn from and the unwinding keep is zero, as the pair loop
    keeps it."""
    reach = r_i + r_j
    overlap, dist = pair_overlap(d, reach)
    inverse = 1.0 / dist if overlap > 0.0 else 0.0
    return overlap, scaled(inverse, d), reduced(r_i, r_j)


BLOCK = 64
"""Pairs in a block of the pair loop; its ROWS x BLOCK values (17 KB) stay in the
first-level cache."""

# The rows of a block, BLOCK values each, one column per pair (see the module docstring)
SEPARATION = 0  # x_j - x_i to the nearest image: 3 rows
RADIUS_I = 3
RADIUS_J = 4
E_STAR = 5
G_STAR = 6
M_STAR = 7  # reduced mass, with viscous damping
VELOCITY = 8  # v_j - v_i: 3 rows
OMEGA_I = 11  # 3 rows
OMEGA_J = 14  # 3 rows
SHEAR = 17  # the shear history: 3 rows
NORMAL_THEN = 20  # the normal at the step's other end: reversed, the later positions' (the
# unwinding normal); forward in fixed point, the earlier positions' (`Pairs.normal`): 3 rows
FORCE = 23  # 3 rows
NEW_SHEAR = 26  # the new shear history: 3 rows
MOMENT = 29  # with shear, what a pair keeps for its moment: n x force, or where `turned` (fixed
# point) the contact normal n, which `sum_in_order` crosses with the force (zero apart): 3 rows
OVERLAP = 32
SLIPPED = 33  # shear force removed by the Coulomb cap
ROLLING = 34  # rolling laws: the rolling history: 3 rows
NEW_ROLLING = 37  # the new rolling history: 3 rows
ROLLED = 40  # rolling moment removed by its limit
DAMP_VELOCITY = 41  # with a velocity predictor, damped laws: the predicted v_j - v_i: 3 rows
DAMP_OMEGA_I = 44  # the predicted spins: 3 rows
DAMP_OMEGA_J = 47  # 3 rows
OVERLAP_THEN = 50  # recording a tape by prediction: the overlap at the earlier positions
EARLIER = 51  # and the shear history the reversed step would find there: 3 rows
SPACING_THEN = 54  # and the grid step of the pair's history there
ROWS = 55

MISSED = 0  # `Pairs.earlier`: the slot of a pair whose earlier history the reversal misses
AMOUNT = 1  # the tape's entry of each axis: the history it had at the earlier positions
# less the one the reversed step would find there, in doubles (`information.ordered`),
# int64 bits: 3 columns
SPREAD = 4  # how far apart on the history's grid there (`information.grid_spread`, whose
# bits `tape.predict` counts): 3 columns
MISSED_COLUMNS = 7
"""Columns of `Pairs.earlier`, each chunk of the list's pairs (`pair_loop`) listing from its
first slot on those whose history the reversed step would miss, in slot order, ended where
they are fewer than the chunk's pairs by a MISSED of -(the next chunk's first slot + 1), the
slot the reader goes on from (`next_listed`). What the tape records of them is found here, so
that a row holds only that: 56 B."""


@inline
def next_listed(missed):
    """The row of `Pairs.earlier` its reader goes on from after the MISSED entry `missed`
    (< 0: the end of a chunk's list, `MISSED_COLUMNS`)."""
    return np.int64(-missed) - 1


PART = 0  # `Pairs.balance`: each chunk's share of the list's pairs in the last call
TOOK = 1  # the nanoseconds its thread took over them (0: unknown)
FIRST = 2  # its first particle in the last call (`chunk_of`)
BALANCE_COLUMNS = 3

LEAST_PART = 0.2
"""The least share of the pairs a chunk takes, in even shares (1 / chunks), and 2 - LEAST_PART
the most (`balanced`): a thread whose core was taken from it for a call is not left idle for
the calls after."""


def empty_balance(chunks: int) -> np.ndarray:
    """`Pairs.balance` of a pair loop on at most `chunks` chunks: none timed yet."""
    return np.zeros((chunks, BALANCE_COLUMNS))


def empty_blocks(chunks: int) -> np.ndarray:
    """Working rows of the pair loop: a block for each of `chunks` parts of the pair list."""
    return np.zeros((chunks, ROWS * BLOCK))


@inline
def entry(block, r, k):
    """Row r of a block, column k."""
    return block[r * BLOCK + k]


@inline
def enter(block, r, k, value):
    block[r * BLOCK + k] = value


@inline
def entries(block, r, k):
    """Rows r to r + 2 of a block, column k, as a 3-tuple."""
    return (block[r * BLOCK + k], block[(r + 1) * BLOCK + k], block[(r + 2) * BLOCK + k])


@inline
def enter3(block, r, k, vector):
    block[r * BLOCK + k], block[(r + 1) * BLOCK + k], block[(r + 2) * BLOCK + k] = vector


@inline
def gather_pairs(
    block, first, size, x, v, w, v_damp, w_damp, predicted, radius, mass, material, estar, gstar,
    pi, pj, history, rolling, normals_then, then, law, overlaps, predicting,
):  # fmt: skip
    """Columns 0 to size - 1 of the block: what the contact stage needs of pairs first to
    first + size - 1, from their particles and their history (and where `then`, the normals
    at the step's other end, `normals_then`; `predicting`, the overlaps of the step before,
    `overlaps`). The separations x_j - x_i go in as they are, their nearest images taken
    after (`to_nearest_images`)."""
    shear_law = law.tangential != NO_SHEAR
    moving = shear_law or law.beta_n > 0.0  # the force depends on the relative velocity
    damped = law.beta_n > 0.0 or law.beta_t > 0.0
    for k in range(size):
        p = np.uint64(first + k)  # unsigned indices: numba skips the check for negative ones
        i = np.uint32(pi[p])
        j = np.uint32(pj[p])
        enter3(block, SEPARATION, k, axpy(-1.0, row(x, i), row(x, j)))  # `to_nearest_images`
        enter(block, RADIUS_I, k, radius[i])
        enter(block, RADIUS_J, k, radius[j])
        if estar.shape[0] > 1:  # one material: the rows hold its moduli (`one_material`)
            a, b = np.uint32(material[i]), np.uint32(material[j])
            enter(block, E_STAR, k, estar[a, b])
            if shear_law:
                enter(block, G_STAR, k, gstar[a, b])
        if damped:
            enter(block, M_STAR, k, reduced(mass[i], mass[j]))
        if moving:
            enter3(block, VELOCITY, k, axpy(-1.0, row(v, i), row(v, j)))
            enter3(block, OMEGA_I, k, row(w, i))
            enter3(block, OMEGA_J, k, row(w, j))
        if damped and predicted:
            enter3(block, DAMP_VELOCITY, k, axpy(-1.0, row(v_damp, i), row(v_damp, j)))
            enter3(block, DAMP_OMEGA_I, k, row(w_damp, i))
            enter3(block, DAMP_OMEGA_J, k, row(w_damp, j))
        if shear_law:
            enter3(block, SHEAR, k, row(history, p))
        if law.rolling != NO_ROLLING:
            enter3(block, ROLLING, k, row(rolling, p))
        if then:
            enter3(block, NORMAL_THEN, k, row(normals_then, p))
        if predicting:
            enter(block, OVERLAP_THEN, k, overlaps[p])


@inline
def one_material(block, estar, gstar):
    """The block's E* and G* rows, every column, for a run of one material: filled once a
    call of the pair loop, not by the gather pair by pair (the fcc pair loop at n = 24, one
    thread: 5 % faster frictionless, 4 % with history)."""
    for k in range(BLOCK):
        enter(block, E_STAR, k, estar[0, 0])
        enter(block, G_STAR, k, gstar[0, 0])


@inline
def gather_stage(
    block, first, size, x, v, w, v_damp, w_damp, predicted, radius, mass, material, estar, gstar,
    pi, pj, history, rolling, normals_then, then, law, overlaps, predicting,
):  # fmt: skip
    """`gather_pairs`, compiled apart for a law without shear, viscous damping or rolling
    resistance (`undamped`), whose constants leave the scalar loop only the separations,
    radii and moduli: its branches cost it registers and loads (the frictionless fcc pair
    loop at n = 24, one thread: 75.5 ns a sphere against 85.0 with every branch). With
    shear the separate build gained nothing (204 against 206 ns)."""
    if is_plain(law) and law.tangential == NO_SHEAR:
        gather_pairs(
            block, first, size, x, v, w, v_damp, w_damp, False, radius, mass, material, estar,
            gstar, pi, pj, history, rolling, normals_then, then, undamped(law, NO_SHEAR, 0.0),
            overlaps, False,
        )  # fmt: skip
    else:
        gather_pairs(
            block, first, size, x, v, w, v_damp, w_damp, predicted, radius, mass, material,
            estar, gstar, pi, pj, history, rolling, normals_then, then, law, overlaps,
            predicting,
        )  # fmt: skip


@inline
def to_nearest_images(block, size, image):
    """The block's separations taken to their nearest periodic images (`cell.nearest_image`;
    none where no axis is periodic, every inverse edge 0), in a loop of their own,
    elementwise, which LLVM vectorises: in the scalar gather they cost about a tenth of the
    frictionless pair loop, and in the contact stage's loop the history stage ran slower."""
    if image[3] == 0.0 and image[4] == 0.0 and image[5] == 0.0:
        return
    for k in range(size):
        enter3(block, SEPARATION, k, nearest_image(entries(block, SEPARATION, k), image))


@inline
def contacts(
    block, size, law, mode, dt, strain, deforming, then, small, predicted, turned, predicting
):
    """Contact stage: the force on i from j of the block's pairs (Hanley 2020 Eq 4-10) and,
    with a tangential law, the new history, n x force (where `turned`, the contact normal
    instead), the overlap and the shear force the Coulomb cap removed, with a rolling law
    the rolling moment and what its limit removed, column by column, reading and writing the
    block only: one loop body, elementwise, which LLVM vectorises. Pairs apart get zeros
    (their overlap < 0). The rows read are left as they were, so that a block can be done
    again. `small`: the spin corrections take every angle to be below contact.SMALL_ANGLE
    (`contact.cos_sin`); `predicted`: viscous damping reads the relative velocity of the
    predicted velocities; `then`: the NORMAL_THEN rows hold the normals at the step's other
    end; `turned` (fixed point): the histories are carried across the contact plane's
    rotation by `contact. turn_onto` from those normals; `predicting` (stepping forward with
    a tape, a constant): the history the reversed step would find at the earlier positions
    into the EARLIER rows and its grid step there into SPACING_THEN
    (`contact.earlier_shear`). Returns how many angles were not."""
    shear_law = law.tangential != NO_SHEAR
    moving = shear_law or law.beta_n > 0.0
    damped = law.beta_n > 0.0 or law.beta_t > 0.0
    large = 0
    for k in range(size):
        d = entries(block, SEPARATION, k)
        r_i = entry(block, RADIUS_I, k)
        r_j = entry(block, RADIUS_J, k)
        overlap, n, rstar = pair_geometry(d, r_i, r_j)
        vrel = ZERO
        vdamp = ZERO
        spin = 0.0
        w_i = w_j = ZERO
        if moving:
            w_i = entries(block, OMEGA_I, k)
            w_j = entries(block, OMEGA_J, k)
            v_ij = entries(block, VELOCITY, k)
            vrel, spin = pair_velocity(d, n, overlap, r_i, r_j, v_ij, w_i, w_j, strain, deforming)
            large += abs(spin * dt) >= SMALL_ANGLE  # the angle of contact_force's Eq 9
            vdamp = vrel
            if damped and predicted:
                vdamp = pair_velocity(
                    d, n, overlap, r_i, r_j, entries(block, DAMP_VELOCITY, k),
                    entries(block, DAMP_OMEGA_I, k), entries(block, DAMP_OMEGA_J, k), strain,
                    deforming,
                )[0]  # fmt: skip
        f, shear, slipped, normal, elastic = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            rstar,
            entry(block, M_STAR, k) if damped else 0.0,
            entry(block, E_STAR, k),
            entry(block, G_STAR, k),
            vrel,
            vdamp,
            spin,
            entries(block, SHEAR, k) if shear_law else ZERO,
            entries(block, NORMAL_THEN, k) if then else ZERO,
            small,
            turned,
        )
        touching = overlap > 0.0
        enter3(block, FORCE, k, f if touching else ZERO)
        if shear_law or damped:  # damped: its pairs touching counted (`count_touching`)
            enter(block, OVERLAP, k, overlap)
        if shear_law:
            enter3(block, NEW_SHEAR, k, shear if touching else ZERO)
            kept = n if turned else cross(n, f)  # for its moment (`Pairs.normal`, `.moment`)
            enter3(block, MOMENT, k, kept if touching else ZERO)
            enter(block, SLIPPED, k, slipped if touching else 0.0)
            if predicting:
                earlier, spacing = earlier_shear(
                    law, dt, overlap, n, rstar, entry(block, E_STAR, k),
                    entry(block, G_STAR, k), vrel, spin, shear if touching else ZERO,
                    entry(block, OVERLAP_THEN, k), entries(block, NORMAL_THEN, k), small,
                )  # fmt: skip
                enter3(block, EARLIER, k, earlier)
                enter(block, SPACING_THEN, k, spacing)
        if law.rolling != NO_ROLLING:
            old = entries(block, ROLLING, k)
            n_then = entries(block, NORMAL_THEN, k) if then else ZERO
            rolling, capped = rolling_moment(
                law, mode, dt, overlap, n, rstar, normal, elastic, w_i, w_j, spin, old, n_then,
                small, turned,
            )  # fmt: skip
            enter3(block, NEW_ROLLING, k, rolling if touching else ZERO)
            enter(block, ROLLED, k, capped if touching else 0.0)
    return large


@inline
def is_plain(law):
    """Whether `law` has neither viscous damping nor rolling resistance: the laws whose
    gather and contact stage are compiled apart (`gather_stage`, `plain_stage`)."""
    return law.beta_n == 0.0 and law.beta_t == 0.0 and law.rolling == NO_ROLLING


@inline
def undamped(law, tangential, grid):
    """`law` without viscous damping or rolling resistance, with the tangential law
    `tangential` and the histories' grid `grid`."""
    return ContactLaw(law.normal, tangential, NO_ROLLING, law.mu, 0.0, 0.0, grid, *law[7:])


@inline
def plain_stage(block, size, law, mode, dt, strain, deforming, then, turned, predicting):
    """`contacts` of a law without viscous damping or rolling resistance (`undamped`), built
    for each mode: reversed; forward without shear; forward with shear, the block done with
    small spin corrections, and again with any where some angle is not small (rare:
    |spin dt| >= 1e-3). `turned`, `predicting`: constants (see `contacts`)."""
    if mode == REVERSE:
        contacts(block, size, law, REVERSE, dt, strain, deforming, then, False, False, turned,
                 False)  # fmt: skip
    elif law.tangential == NO_SHEAR:
        frictionless = undamped(law, NO_SHEAR, 0.0)
        contacts(block, size, frictionless, FORWARD, dt, strain, deforming, False, True, False,
                 False, False)  # fmt: skip
    else:
        args = (block, size, law, FORWARD, dt, strain, deforming, then)
        if contacts(*args, True, False, turned, predicting) > 0:
            contacts(*args, False, False, turned, predicting)


@inline
def contact_stage(block, size, law, mode, dt, strain, deforming, then, predicted, predicting):
    """`contacts`, compiled apart for the common cases (stepping forward or reversed without
    viscous damping or rolling resistance, `plain_stage`), where the law's constants and the
    mode remove the branches those cases never take from the vectorised loop: an elementwise
    loop computes both sides of every branch in it. Floating point gets a build of its own,
    whose histories' grid is the constant 0, so that it does not pay for their rounding, and
    fixed point stepping forward with a tape one of its own that `predicting`."""
    plain = is_plain(law)
    if not plain or mode == STATIC or mode == SETTLED:
        turned = law.history_grid != 0.0
        contacts(block, size, law, mode, dt, strain, deforming, then, False, predicted, turned,
                 False)  # fmt: skip
    elif law.history_grid == 0.0:
        floating = undamped(law, law.tangential, 0.0)
        plain_stage(block, size, floating, mode, dt, strain, deforming, then, False, False)
    else:
        gridded = undamped(law, law.tangential, law.history_grid)
        if predicting:
            plain_stage(block, size, gridded, mode, dt, strain, deforming, then, True, True)
        else:
            plain_stage(block, size, gridded, mode, dt, strain, deforming, then, True, False)


@inline
def snap_forces(block, size, step):
    """Fixed-point arithmetic: the block's forces on the force grid of `step`
    (`fixed.snapped_in_range`), once a pair, so that each particle's sum adds it exactly for
    both its particles. Returns the largest magnitude of a component of them (N), found from
    their bits (a double's magnitude orders as its bits do, and integers LLVM vectorises)."""
    largest = np.int64(0)
    for k in range(size):
        f = snapped_in_range(entries(block, FORCE, k), step)
        enter3(block, FORCE, k, f)
        largest = max(largest, max(magnitude_bits(f[0]), max(magnitude_bits(f[1]),
                                                             magnitude_bits(f[2]))))  # fmt: skip
    return np.int64(largest).view(np.float64)


@inline
def list_missed(earlier, listed, slot, was, found, spacing):
    """Row `listed` of `Pairs.earlier` <- pair `slot`, where the history the reversed step
    would find, `found`, is not bit for bit the one it had, `was`: each axis's entry and how
    far apart the two lie on the grid of step `spacing` (0 where the axis is found; no
    logarithm here, which would put a call in the pair loop); returns the next row."""
    for d in range(3):
        if np.float64(was[d]).view(np.int64) != np.float64(found[d]).view(np.int64):
            earlier[listed, MISSED] = slot
            for axis in range(3):
                had = np.float64(was[axis]).view(np.int64)
                now = np.float64(found[axis]).view(np.int64)
                amount = ordered(had) - ordered(now)
                earlier[listed, AMOUNT + axis] = np.int64(amount).view(np.float64)
                spread = grid_spread(had, now, spacing) if amount != 0 else 0.0
                earlier[listed, SPREAD + axis] = spread
            return listed + 1
    return listed


@inline
def scatter_pairs(
    block, first, size, force, history, moment, overlaps, destroyed, rolling, rolled, earlier,
    predicting, listed, law, mode, write,
):  # fmt: skip
    """The block's results into the pair arrays (where `write`, its forces, overlaps and into
    `moment` what each pair keeps for its moment, `Pairs.moment` or in fixed point
    `Pairs.normal`; its histories and what was destroyed always; `predicting`, each pair whose
    history the reversed step would miss listed in `earlier` from row `listed` on,
    `list_missed`); returns the block's counts (`Destroyed`: slips, last pair that slipped,
    losses, last pair that lost its shear force, and the same for the rolling moment) and
    the next row of `earlier`. A pair apart loses its histories (counted lost when stepping
    forward)."""
    slips = 0
    last_slip = -1
    losses = 0
    last_loss = -1
    caps = 0
    last_cap = -1
    drops = 0
    last_drop = -1
    shear_law = law.tangential != NO_SHEAR
    for k in range(size):
        p = first + k
        u = np.uint64(p)  # unsigned, as in `gather_pairs`
        if write:
            put(force, u, entries(block, FORCE, k))
        if shear_law:
            overlap = entry(block, OVERLAP, k)
            lost = norm(row(history, u)) if overlap <= 0.0 and mode == FORWARD else 0.0
            put(history, u, entries(block, NEW_SHEAR, k))
            if predicting:
                was, found = entries(block, SHEAR, k), entries(block, EARLIER, k)
                spacing = entry(block, SPACING_THEN, k)
                listed = list_missed(earlier, listed, p, was, found, spacing)
            if write:
                put(moment, u, entries(block, MOMENT, k))
                overlaps[u] = overlap
            slipped = entry(block, SLIPPED, k)
            destroyed[p] = slipped  # this step's, 0 where nothing was: the sliding flag
            if slipped > 0.0:
                slips += 1
                last_slip = p
            if lost > 0.0:
                destroyed[p] = lost
                losses += 1
                last_loss = p
        if law.rolling != NO_ROLLING:
            apart = entry(block, OVERLAP, k) <= 0.0 and mode == FORWARD
            dropped = norm(row(rolling, u)) if apart else 0.0
            put(rolling, u, entries(block, NEW_ROLLING, k))
            capped = entry(block, ROLLED, k)
            if capped > 0.0:
                rolled[p] = capped
                caps += 1
                last_cap = p
            if dropped > 0.0:
                rolled[p] = dropped
                drops += 1
                last_drop = p
    return slips, last_slip, losses, last_loss, caps, last_cap, drops, last_drop, listed


@inline
def slips_destroying(block, first, size, law):
    """(how many of the block's slips destroyed information, the last pair that slipped so;
    -1 where none): with mu = 0 only those of pairs that carried a history in
    (`contact.capped_away`), counted in a loop of their own, run for mu = 0 alone, in place
    of `scatter_pairs`' count of every slip."""
    count = 0
    last = -1
    for k in range(size):
        if entry(block, SLIPPED, k) > 0.0 and not capped_away(law, entries(block, SHEAR, k)):
            count += 1
            last = max(last, first + k)
    return count, last


@inline
def count_touching(block, first, size):
    """(how many of the block's pairs touch, the last that does; -1 where none): where
    viscous damping acts, which `events.note_destroyed` logs, in a loop of its own, which
    LLVM vectorises, run only for a damped law."""
    count = 0
    last = -1
    for k in range(size):
        if entry(block, OVERLAP, k) > 0.0:
            count += 1
            last = max(last, first + k)
    return count, last


@inline
def sum_in_order(
    block, first, size, pi, pj, radius, f_sum, t_sum, torques, rolls, beyond, foreign,
    foreign_end, force, moment, overlaps, turned,
):  # fmt: skip
    """The block's pairs, first to first + size - 1, added to their particles' sums in the
    list's order: the force f on i and -f on j; with moments (`torques`), on each the lever
    arm r - overlap / 2 times n x f (Hanley 2020 Eq 5; where `turned`, fixed point, the
    MOMENT rows hold the normal n, crossed here with the force on its grid) and, with a
    rolling law (`rolls`), the rolling moment on i and its opposite on j. The list is sorted
    by (i, j), so each particle gets its terms in one order on any thread count: its
    partners p < q by index, then its own pairs (q, j) by index. Each particle's
    own pairs are consecutive: its sums stay in registers while they last. A particle with
    a partner in an earlier chunk (`foreign`, or `beyond` and above: a later chunk's) is
    summed after (`sum_foreign`): its pairs' forces, moments and overlaps go to the pair
    arrays, and a later chunk's particle is left alone. No particle from `foreign_end` on
    is foreign, so most pairs are judged without reading a flag (the fcc pair loop at n =
    24, one thread: 6 % faster frictionless, 4 % with history)."""
    current = np.uint32(pi[np.uint64(first)])
    f_i = row(f_sum, current)
    t_i = row(t_sum, current) if torques else ZERO
    for k in range(size):
        p = np.uint64(first + k)
        i = np.uint32(pi[p])
        j = np.uint32(pj[p])
        if i != current:
            put(f_sum, current, f_i)
            f_i = row(f_sum, i)
            if torques:
                put(t_sum, current, t_i)
                t_i = row(t_sum, i)
            current = i
        f = entries(block, FORCE, k)
        mine = j < beyond  # this chunk's particle; a later chunk's is foreign there, but
        # that chunk marks it concurrently, so its flag is not read here
        # for `sum_foreign` (j > i: no particle from foreign_end on is foreign)
        if not mine or (i < foreign_end and (foreign[i] or (j < foreign_end and foreign[j]))):
            put(force, p, f)
            if torques:
                put(moment, p, entries(block, MOMENT, k))
                overlaps[p] = entry(block, OVERLAP, k)
        f_i = axpy(1.0, f, f_i)
        if mine:
            put(f_sum, j, axpy(-1.0, f, row(f_sum, j)))
        if torques:
            n_x_f = entries(block, MOMENT, k)
            if turned:
                n_x_f = cross(n_x_f, f)
            overlap = entry(block, OVERLAP, k)
            t_i = axpy(lever_arm(radius[i], overlap), n_x_f, t_i)
            t_j = axpy(lever_arm(radius[j], overlap), n_x_f, row(t_sum, j)) if mine else ZERO
            if rolls:
                t_i = axpy(1.0, entries(block, NEW_ROLLING, k), t_i)
                t_j = axpy(-1.0, entries(block, NEW_ROLLING, k), t_j)
            if mine:
                put(t_sum, j, t_j)
    put(f_sum, current, f_i)
    if torques:
        put(t_sum, current, t_i)


@inline
def mark_foreign(foreign, lo, hi, pi, start, slots):
    """foreign[q] of particles lo to hi - 1, a chunk's: whether q has a partner p < lo, in
    an earlier chunk (its partners are ascending: the first is the least). Returns the
    last such particle + 1 (lo where there is none)."""
    end = lo
    for q in range(lo, hi):
        marked = start[q] < start[q + 1] and pi[np.uint32(slots[start[q]])] < lo
        foreign[q] = marked
        if marked:
            end = q + 1
    return end


@inline
def n_cross_f(moment, force, k, turned):
    """n x f of pair k from what it keeps for its moment: `Pairs.moment`, or where `turned`
    (fixed point) its normal, `Pairs.normal`, crossed with its force."""
    return cross(row(moment, k), row(force, k)) if turned else row(moment, k)


@inline
def sum_foreign(q, mass, gravity, radius, pi, first_pair, start, slots, force, moment,
                overlaps, rolling, f_sum, t_sum, torques, rolls, f_step, turned):  # fmt: skip
    """Particle q's weight, forces and moments, summed from the pair arrays in the order and
    by the arithmetic of `sum_in_order`: its partners p < q ascending (the reaction -f, the
    lever arm r - overlap / 2 times n x f, Hanley 2020 Eq 5, the opposite of the rolling
    moment on p), then its own pairs (q, j) (f, the lever-arm term, the rolling moment);
    where `turned` (fixed point) n x f from the pair's normal and force (`n_cross_f`)."""
    f = weight_summed(mass[q], gravity, f_step)
    t = ZERO
    for s in range(start[q], start[q + 1]):
        k = np.uint32(slots[s])
        f = axpy(-1.0, row(force, k), f)
        if torques:
            t = axpy(lever_arm(radius[q], overlaps[k]), n_cross_f(moment, force, k, turned), t)
            if rolls:
                t = axpy(-1.0, row(rolling, k), t)
    for kk in range(first_pair[q], first_pair[q + 1]):
        k = np.uint64(kk)
        f = axpy(1.0, row(force, k), f)
        if torques:
            t = axpy(lever_arm(radius[q], overlaps[k]), n_cross_f(moment, force, k, turned), t)
            if rolls:
                t = axpy(1.0, row(rolling, k), t)
    put(f_sum, q, f)
    if torques:
        put(t_sum, q, t)


SHARE = 16
"""Consecutive particles a thread takes at a time of those summed after the chunks
(`sum_foreign`). A chunk's lie together, at its start (and in a periodic packing at its
end too, whose last particles touch the first): dealt out SHARE at a time, they fall to
every thread alike, and the rows of the sums each thread writes (16 x 24 B) share few
cache lines with another's."""


def _pair_loop(
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
    image,
    rate,
    length,
    deforming,
    pi,
    pj,
    n_pairs,
    force,
    history,
    moment,
    overlaps,
    destroyed,
    rolling,
    rolled,
    normals_then,
    earlier,
    law,
    mode,
    dt,
    blocks,
    gravity,
    f_sum,
    t_sum,
    first_pair,
    start,
    slots,
    foreign,
    balance,
    keep,
):
    """Force on i from j for every listed pair (Hanley 2020 Eq 4-10) and, with a tangential
    law, what it keeps for its moment (`moment`: n x force, in fixed point its normal), the
    overlap and the shear force destroyed (viscous damping reading `v_damp`, `w_damp` where
    `predicted`, else v, w): by the Coulomb cap, or at separation, where the history is
    zeroed; with a rolling law the rolling moment on i and what its limit or a separation
    destroyed; in fixed point, the histories turned from `normals_then`, the normals at the
    step's other end (`contacts`); stepping forward without damping or rolling resistance
    with an `earlier` array (`Pairs.earlier`), the pairs whose history the reversed step
    would miss listed in it (`list_missed`, each chunk from its first slot on). The list is
    cut into as many chunks as there are `blocks` (`chunk_of`: each particle's own pairs in
    one), each done block by block in its own: gather, contact stage, scatter. It also sums
    each particle's weight, forces and moments into f_sum and t_sum, in one fixed order
    (`sum_in_order`; a particle with a partner in an earlier chunk, marked in `foreign`,
    once every chunk is done, `sum_foreign`), the same bits on any thread count; in fixed
    point the weight rounded onto the force grid and the forces summed in doubles, which
    `gather.complete_sums` keeps where that is exact. It writes the pair arrays' forces,
    moments (in fixed point normals) and overlaps only where `keep` (something reads them
    before the next step: `forces.compute_forces` says when) or `sum_foreign` reads them;
    the histories and what was destroyed always. The chunks are as many as the threads the
    loop runs on (`threads_for`, as `by_size` chooses the build; at most the blocks), each
    the share of the pairs `balance` gives it (`balanced`), where its time is kept too.
    Returns (the counts of `events.note_destroyed`, in fixed point the largest magnitude of
    a component of a pair's force, N, which the gather judges the sums by)."""
    strain = strain_rates(rate, length)
    then = normals_then.shape[0] > 0 and (mode == FORWARD or mode == REVERSE)
    plain = is_plain(law)
    predicting = mode == FORWARD and earlier.shape[0] > 0 and plain
    damped = law.beta_n > 0.0 or law.beta_t > 0.0  # its pairs touching counted (`count_touching`)
    chunks = min(threads_for(first_pair.shape[0] - 1, HEAVY), blocks.shape[0])
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
    largest = 0.0  # fixed point: the largest component of a pair's force, N
    f_step = law.force_grid  # fixed point: the force grid's step; 0 in floating point
    turned = law.history_grid != 0.0  # fixed point: `moment` holds the pairs' normals
    torques = moment.shape[0] > 0
    rolls = rolling.shape[0] > 0
    if chunks > 1:
        balanced(balance, chunks, first_pair, n_pairs)
    for c in numba.prange(chunks):
        began = clock_ns() if chunks > 1 else 0
        block = blocks[c]
        lo, start_pair = chunk_of(c, chunks, first_pair, n_pairs, balance)
        beyond, end = chunk_of(c + 1, chunks, first_pair, n_pairs, balance)
        for q in range(lo, beyond):  # each of the chunk's particles' sums starts at its weight
            put(f_sum, q, weight_summed(mass[q], gravity, f_step))
            if torques:
                put(t_sum, q, ZERO)
        foreign_end = lo  # the chunk's particles from here on have no partner in an earlier one
        if chunks > 1:  # one chunk: none, and `foreign`, which an earlier call on more
            # chunks may have marked, is not read (foreign_end = 0)
            foreign_end = mark_foreign(foreign, lo, beyond, pi, start, slots)
        listed = start_pair  # the chunk's next row of `earlier`
        if estar.shape[0] == 1:
            one_material(block, estar, gstar)
        for first in range(start_pair, end, BLOCK):
            size = min(BLOCK, end - first)
            gather_stage(
                block, first, size, x, v, w, v_damp, w_damp, predicted, radius, mass, material,
                estar, gstar, pi, pj, history, rolling, normals_then, then, law, overlaps,
                predicting,
            )  # fmt: skip
            to_nearest_images(block, size, image)
            contact_stage(
                block, size, law, mode, dt, strain, deforming, then, predicted, predicting
            )
            if f_step != 0.0:
                largest = max(largest, snap_forces(block, size, f_step))
            results = (
                force, history, moment, overlaps, destroyed, rolling, rolled, earlier,
                predicting, listed, law, mode, keep,
            )  # fmt: skip
            scattered = scatter_pairs(block, first, size, *results)
            slipped = scattered[:2]
            if law.mu == 0.0 and law.tangential != NO_SHEAR:
                slipped = slips_destroying(block, first, size, law)
            slips += slipped[0]
            last_slip = max(last_slip, slipped[1])
            losses += scattered[2]
            last_loss = max(last_loss, scattered[3])
            caps += scattered[4]
            last_cap = max(last_cap, scattered[5])
            drops += scattered[6]
            last_drop = max(last_drop, scattered[7])
            listed = scattered[8]
            if damped:
                count, last = count_touching(block, first, size)
                dashpots += count
                last_dashpot = max(last_dashpot, last)
            sum_in_order(
                block, first, size, pi, pj, radius, f_sum, t_sum, torques, rolls, beyond,
                foreign, foreign_end, force, moment, overlaps, turned,
            )  # fmt: skip
        if predicting and listed < end:
            earlier[listed, MISSED] = -(end + 1)  # `next_listed`
        if chunks > 1:
            balance[c, TOOK] = max(clock_ns() - began, 1)
    if chunks > 1:  # the particles with partners in an earlier chunk, dealt out to the
        # threads SHARE at a time, so that each thread gets its part wherever they lie
        for t in numba.prange(chunks):
            for c in range(1, chunks):
                lo = chunk_of(c, chunks, first_pair, n_pairs, balance)[0]
                hi = chunk_of(c + 1, chunks, first_pair, n_pairs, balance)[0]
                for share in range(lo + SHARE * t, hi, SHARE * chunks):
                    for q in range(share, min(share + SHARE, hi)):
                        if foreign[q]:
                            sum_foreign(
                                q, mass, gravity, radius, pi, first_pair, start, slots, force,
                                moment, overlaps, rolling, f_sum, t_sum, torques, rolls, f_step,
                                turned,
                            )  # fmt: skip
    counts = (slips, last_slip, losses, last_loss, caps, last_cap, drops, last_drop)
    return counts + (dashpots, last_dashpot), largest


@inline
def chunk_of(c, chunks, first_pair, n_pairs, balance):
    """(first particle, first pair) of chunk c of the `chunks` the pair loop cuts the list
    into this call (c = chunks: the ends), as `balanced` cut it (`Pairs.balance`): at a
    particle's first pair, so that each particle's own pairs lie in one chunk
    (`Pairs.first`: each particle's first pair, ascending)."""
    n = first_pair.shape[0] - 1
    if c == 0:
        return np.int64(0), np.int64(0)
    if c >= chunks:
        return np.int64(n), np.int64(n_pairs)
    q = np.int64(balance[c, FIRST])
    return q, np.int64(first_pair[q])


@inline
def balanced(balance, chunks, first_pair, n_pairs):
    """Cut the list into `chunks` chunks for this call (`Pairs.balance`): each chunk's share
    of the pairs moves from the last call's halfway to the share that its thread, at the
    pace it kept then (its pairs a nanosecond), finishes with the others, within LEAST_PART
    and 2 - LEAST_PART even shares; even shares where the last call cut the list into
    another number of chunks. Each chunk starts at the particle whose first pair its share
    reaches (FIRST, `chunk_of`). No sum depends on the cut (`sum_in_order`). The fcc
    benchmark on two threads, whole steps in turns with even shares in one process (AMD
    EPYC, 2 cores): 1-5 % more particle-steps a second (best and upper quartile; n = 10
    and 24, frictionless and with history); beside a busy loop neither wins, the other
    core's time changing faster than a call."""
    known = True
    for c in range(balance.shape[0]):
        known = known and (balance[c, TOOK] > 0.0) == (c < chunks)
    pace = 0.0
    if known:
        for c in range(chunks):
            pace += balance[c, PART] / balance[c, TOOK]
    total = 0.0
    for c in range(chunks):
        part = 1.0 / chunks
        if known:
            finishing = balance[c, PART] / balance[c, TOOK] / pace
            part = 0.5 * (balance[c, PART] + finishing)
            part = min(max(part, LEAST_PART / chunks), (2.0 - LEAST_PART) / chunks)
        balance[c, PART] = part
        total += part
    reached = 0.0
    for c in range(chunks):
        balance[c, PART] /= total
        balance[c, FIRST] = np.searchsorted(first_pair, np.int64(reached * n_pairs))
        reached += balance[c, PART]
    balance[:, TOOK] = 0.0  # until this call's chunks have taken it


pair_loop = by_size(_pair_loop, threads_for=one_thread)
"""The serial build works through the list in one chunk, a constant (`one_thread`), so its
code for more (`mark_foreign`, the flags, `sum_foreign`) folds away."""


def _contact_normals(x, radius, image, pi, pj, n_pairs, normals, overlaps):
    """Each pair's contact normal at the positions x (zero where it is apart,
    `pair_geometry`) and its overlap, as the pair loop finds them (`contacts`): what the next
    forward step turns its histories from, and predicts what the reversed step finds with."""
    for k in numba.prange(n_pairs):
        i = pi[k]
        j = pj[k]
        d = separation(x, i, j, image)
        overlap, n, _ = pair_geometry(d, radius[i], radius[j])
        put(normals, k, n)
        overlaps[k] = overlap


contact_normals = by_size(_contact_normals)
