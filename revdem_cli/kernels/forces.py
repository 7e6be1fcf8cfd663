"""Contact forces, net forces on particles, and the stress they carry.

Three loops, each writing only its own slots: pairs (each pair's force computed once), wall
contacts (each particle's, wall by wall), and the gather (each particle sums its weight,
its pairs in the order of its partners' indices, and its walls in order, then takes its
half kick), so sums do not depend on the thread count. The pair and wall loops also count
the contacts whose shear force was destroyed (integer sums and maxima, which do not depend
on the order either), so the event log is scanned only when something happened.

The loops take plain arrays and do each item's work in the loop body, with helpers over
scalars and 3-tuples: a compiled call that receives array bundles pays an atomic
reference-count update per array, which would dominate the cost per item. Each loop is
built serial and parallel; small systems step serially, without waking threads.

The pair loop works in blocks of BLOCK pairs, so that LLVM can vectorise the contact
physics (AVX-512: eight pairs at a time). A block is ROWS x BLOCK doubles, a row per
quantity and a column per pair, and goes through three stages:
- gather: each pair's separation, radii, moduli, velocities and history into its column
  (scalar: the particles' rows are scattered in memory);
- contact stage: `contact.contact_force` and its geometry and kinematics, column by column,
  reading and writing the block only, so the loop is elementwise over contiguous rows (with
  the spin correction's cos and sin as their series; a block where some angle is too large
  for that is done again with them in full);
- scatter: each column's force, history, moment and overlap into the pair arrays, counting
  the shear force destroyed (scalar, branches); in a long list, force, moment and overlap
  with non-temporal stores (STREAM_FROM).
Every pair's numbers are those of the scalar formulas, in the same order. The pair list is
cut into as many chunks as `Pairs.blocks` has blocks (the thread count), each chunk worked
through with its own block, so the loop allocates nothing.
"""

import math

import numba
import numpy as np

from revdem_cli.kernels import fence, inline, jit, prefetch, renamed, serial_and_parallel, stream
from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels.arrays import ContactLaw
from revdem_cli.kernels.cell import (
    affine_velocity,
    deforms,
    holds_stress,
    images,
    nearest_image,
    servo_forces,
    strain_rates,
    volume,
)
from revdem_cli.kernels.contact import (
    FORWARD,
    NO_SHEAR,
    SMALL_ANGLE,
    axpy,
    contact_force,
    contact_velocity,
    cross,
    dot,
    norm,
    relative_velocity,
    scaled,
    unwind_shear,
)
from revdem_cli.kernels.events import note_destroyed
from revdem_cli.kernels.sums import SPAN, blocks_of, span
from revdem_cli.kernels.walls import wall_overlap

ZERO = (0.0, 0.0, 0.0)

PARALLEL_FROM = 256
"""Systems of at least this many particles step with parallel loops; smaller ones serially.
Results are the same either way."""

AHEAD = 8
"""The gather asks for the reactions of the particle this many ahead of the one it sums:
they lie under earlier particles, far back in the pair arrays, and the hardware does not
see them coming (at 10^6 fcc spheres the gather takes 26-31 % less time; 8 ahead did best
overall: 16 was 6 % faster frictionless at 10^6 but 9-12 % slower with history, 4 slower)."""

STREAM_FROM = 200_000
"""Lists of at least this many pairs send the pair loop's results (force, n x f, overlap)
to memory with non-temporal stores: read back only by the gather, after the loop, they
would not stay in cache, and a store that first reads its cache line in costs twice the
traffic (the pair loop takes 9-20 % less time at n = 24 and 64 fcc). Smaller lists keep
them in cache (at n = 10 and 14 streaming made the gather 20-30 % slower, at n = 18 it
broke even)."""

APART = 1.0 + 1e-12
"""Pairs farther apart than (1 + 1e-12) (r_i + r_j) are certainly not touching, so their
distance needs no square root."""


@inline
def sign(a):
    """1, -1 or 0 (0 for NaN) without a branch: a branch on the sign of a velocity component
    is mispredicted half the time (local damping's sign(v) made the gather 1.6 times
    slower, n = 24 fcc)."""
    return np.float64(a > 0.0) - np.float64(a < 0.0)


@inline
def row(a, k):
    """Row k of an (n, 3) array as a 3-tuple."""
    return (a[k, 0], a[k, 1], a[k, 2])


@inline
def put(a, k, vector):
    a[k, 0], a[k, 1], a[k, 2] = vector


@inline
def put_streaming(a, k, vector):
    """`put` with non-temporal stores (`kernels.stream`)."""
    stream(a, (k, 0), vector[0])
    stream(a, (k, 1), vector[1])
    stream(a, (k, 2), vector[2])


@jit
def cell_of(a, q, b):
    """Entry (q, b) of an (n, m, 3) array as a 3-tuple."""
    return (a[q, b, 0], a[q, b, 1], a[q, b, 2])


@jit
def place(a, q, b, vector):
    a[q, b, 0], a[q, b, 1], a[q, b, 2] = vector


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
    vrel = contact_velocity(n, r_i - 0.5 * overlap, r_j - 0.5 * overlap, v_ij, w_i, w_j)
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
NORMAL_NEW = 20  # reversed runs: the unwinding normal: 3 rows
FORCE = 23  # 3 rows
NEW_SHEAR = 26  # the new shear history: 3 rows
MOMENT = 29  # n x force: 3 rows
OVERLAP = 32
SLIPPED = 33  # shear force removed by the Coulomb cap
ROWS = 34


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
    block, first, size, x, v, w, radius, mass, material, estar, gstar, image, pi, pj, history,
    normal_new, law,
):  # fmt: skip
    """Columns 0 to size - 1 of the block: what the contact stage needs of pairs first to
    first + size - 1, from their particles and their history."""
    shear_law = law.tangential != NO_SHEAR
    moving = shear_law or law.beta_n > 0.0  # the force depends on the relative velocity
    damped = law.beta_n > 0.0 or law.beta_t > 0.0
    unwound = normal_new.shape[0] > 0
    for k in range(size):
        p = np.uint64(first + k)  # unsigned indices: numba skips the check for negative ones
        i = np.uint32(pi[p])
        j = np.uint32(pj[p])
        enter3(block, SEPARATION, k, separation(x, i, j, image))
        enter(block, RADIUS_I, k, radius[i])
        enter(block, RADIUS_J, k, radius[j])
        a, b = np.uint32(material[i]), np.uint32(material[j])
        enter(block, E_STAR, k, estar[a, b])
        enter(block, G_STAR, k, gstar[a, b])
        if damped:
            enter(block, M_STAR, k, mass[i] * mass[j] / (mass[i] + mass[j]))
        if moving:
            enter3(block, VELOCITY, k, axpy(-1.0, row(v, i), row(v, j)))
            enter3(block, OMEGA_I, k, row(w, i))
            enter3(block, OMEGA_J, k, row(w, j))
        if shear_law:
            enter3(block, SHEAR, k, row(history, p))
        if unwound:
            enter3(block, NORMAL_NEW, k, row(normal_new, p))


@inline
def contacts(block, size, law, mode, dt, strain, deforming, unwound, small):
    """Contact stage: the force on i from j of the block's pairs (Hanley 2020 Eq 4-10) and,
    with a tangential law, the new history, n x force, the overlap and the shear force the
    Coulomb cap removed, column by column, reading and writing the block only: one loop
    body, elementwise, which LLVM vectorises. Pairs apart get zeros (their overlap < 0).
    The rows read are left as they were, so that a block can be done again. `small`: the
    spin corrections take every angle to be below contact.SMALL_ANGLE (`contact.cos_sin`).
    Returns how many angles were not."""
    shear_law = law.tangential != NO_SHEAR
    moving = shear_law or law.beta_n > 0.0
    damped = law.beta_n > 0.0 or law.beta_t > 0.0
    large = 0
    for k in range(size):
        d = entries(block, SEPARATION, k)
        r_i = entry(block, RADIUS_I, k)
        r_j = entry(block, RADIUS_J, k)
        reach = r_i + r_j
        overlap, dist = pair_overlap(d, reach)
        n = scaled(1.0 / dist, d)
        vrel = ZERO
        spin = 0.0
        if moving:
            w_i = entries(block, OMEGA_I, k)
            w_j = entries(block, OMEGA_J, k)
            v_ij = entries(block, VELOCITY, k)
            vrel, spin = pair_velocity(d, n, overlap, r_i, r_j, v_ij, w_i, w_j, strain, deforming)
            large += abs(spin * dt) >= SMALL_ANGLE  # the angle of contact_force's Eq 9
        f, shear, slipped = contact_force(
            law,
            mode,
            dt,
            overlap,
            n,
            r_i * r_j / reach,
            entry(block, M_STAR, k) if damped else 0.0,
            entry(block, E_STAR, k),
            entry(block, G_STAR, k),
            vrel,
            spin,
            entries(block, SHEAR, k) if shear_law else ZERO,
            entries(block, NORMAL_NEW, k) if unwound else ZERO,
            small,
        )
        touching = overlap > 0.0
        enter3(block, FORCE, k, f if touching else ZERO)
        if shear_law:
            enter3(block, NEW_SHEAR, k, shear if touching else ZERO)
            enter3(block, MOMENT, k, cross(n, f) if touching else ZERO)
            enter(block, OVERLAP, k, overlap)
            enter(block, SLIPPED, k, slipped if touching else 0.0)
    return large


@inline
def undamped(law, tangential):
    """`law` without viscous damping and with the tangential law `tangential`."""
    return ContactLaw(law.model, law.kn, tangential, law.ks, law.mu, 0.0, 0.0)


@inline
def contact_stage(block, size, law, mode, dt, strain, deforming, unwound):
    """`contacts`, compiled apart for the common cases (stepping forward without viscous
    damping, with and without shear), where the law's constants remove the branches those
    cases never take from the vectorised loop: an elementwise loop computes both sides of
    every branch in it. With shear, the block is done with small spin corrections, and
    again with any where some angle is not small (rare: |spin dt| >= 1e-3)."""
    if mode == FORWARD and law.beta_n == 0.0 and law.beta_t == 0.0:
        if law.tangential == NO_SHEAR:
            frictionless = undamped(law, NO_SHEAR)
            contacts(block, size, frictionless, FORWARD, dt, strain, deforming, False, True)
        else:
            forward = undamped(law, law.tangential)
            if contacts(block, size, forward, FORWARD, dt, strain, deforming, False, True) > 0:
                contacts(block, size, forward, FORWARD, dt, strain, deforming, False, False)
    else:
        contacts(block, size, law, mode, dt, strain, deforming, unwound, False)


STREAMING = False
"""Whether `scatter_pairs` streams (see STREAM_FROM); its streaming build has it True. A
constant, not an argument: numba optimises the helper before inlining it, and LLVM merges
the two branches' stores into one plain store."""


def _scatter_pairs(block, first, size, force, history, moment, overlaps, destroyed, law, mode):
    """The block's results into the pair arrays; returns (slips, last pair that slipped,
    losses, last pair that lost its shear force) of the block. A pair apart loses its
    history (the shear force is counted lost when stepping forward)."""
    slips = 0
    last_slip = -1
    losses = 0
    last_loss = -1
    shear_law = law.tangential != NO_SHEAR
    for k in range(size):
        p = first + k
        u = np.uint64(p)  # unsigned, as in `gather_pairs`
        if STREAMING:
            put_streaming(force, u, entries(block, FORCE, k))
        else:
            put(force, u, entries(block, FORCE, k))
        if shear_law:
            overlap = entry(block, OVERLAP, k)
            lost = norm(row(history, u)) if overlap <= 0.0 and mode == FORWARD else 0.0
            put(history, u, entries(block, NEW_SHEAR, k))
            if STREAMING:
                put_streaming(moment, u, entries(block, MOMENT, k))
                stream(overlaps, u, overlap)
            else:
                put(moment, u, entries(block, MOMENT, k))
                overlaps[u] = overlap
            slipped = entry(block, SLIPPED, k)
            if slipped > 0.0:  # `destroyed` is read only where something was
                destroyed[p] = slipped
                slips += 1
                last_slip = p
            if lost > 0.0:
                destroyed[p] = lost
                losses += 1
                last_loss = p
    return slips, last_slip, losses, last_loss


scatter_pairs = inline(_scatter_pairs)
scatter_pairs_streaming = inline(renamed(_scatter_pairs, "_scatter_streaming", STREAMING=True))


def _pair_loop(
    x,
    v,
    w,
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
    normal_new,
    law,
    mode,
    dt,
    blocks,
):
    """Force on i from j for every listed pair (Hanley 2020 Eq 4-10) and, with a tangential
    law, n x force, the overlap and the shear force destroyed: by the Coulomb cap, or at
    separation, where the history is zeroed. The list is cut into as many chunks as there
    are `blocks`, each done block by block in its own: gather, contact stage, scatter.
    Returns (slips, last pair that slipped, losses, last pair that lost its shear force)."""
    strain = strain_rates(rate, length)
    unwound = normal_new.shape[0] > 0
    streaming = n_pairs >= STREAM_FROM
    chunks = blocks.shape[0]
    slips = 0
    last_slip = -1
    losses = 0
    last_loss = -1
    for c in numba.prange(chunks):
        block = blocks[c]
        end = (c + 1) * n_pairs // chunks
        for first in range(c * n_pairs // chunks, end, BLOCK):
            size = min(BLOCK, end - first)
            gather_pairs(
                block, first, size, x, v, w, radius, mass, material, estar, gstar, image, pi,
                pj, history, normal_new, law,
            )  # fmt: skip
            contact_stage(block, size, law, mode, dt, strain, deforming, unwound)
            results = (force, history, moment, overlaps, destroyed, law, mode)
            if streaming:
                scattered = scatter_pairs_streaming(block, first, size, *results)
            else:
                scattered = scatter_pairs(block, first, size, *results)
            s, s_last, lost, lost_last = scattered
            slips += s
            last_slip = max(last_slip, s_last)
            losses += lost
            last_loss = max(last_loss, lost_last)
        fence()  # any streamed results, before the gather reads them on other threads
    return slips, last_slip, losses, last_loss


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
    force,
    torque,
    overlaps,
    history,
    destroyed,
    normal_new,
    law,
    mode,
    dt,
):
    """Force and moment on each particle from each wall (Hanley 2020 Eq 4-10, R* = r).
    Returns (slips, last contact q W + b that slipped, losses, last that lost its shear)."""
    shear_law = law.tangential != NO_SHEAR
    walls = kind.shape[0]
    slips = 0
    last_slip = -1
    losses = 0
    last_loss = -1
    for q in numba.prange(x.shape[0]):
        for b in range(walls):
            overlap, n, arm, vrel, spin = wall_kinematics(
                q, b, x, v, w, radius, kind, point, axis, wall_radius, wall_velocity
            )
            overlaps[q, b] = overlap
            shear = cell_of(history, q, b)
            if overlap > 0.0:
                m = wall_material[b]
                n_new = cell_of(normal_new, q, b) if normal_new.shape[0] > 0 else ZERO
                f, shear, slipped = contact_force(
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
                    spin,
                    shear,
                    n_new,
                )
                t = cross(scaled(arm, n), f) if shear_law else ZERO
                dropped = 0.0
            else:
                f = ZERO
                t = ZERO
                slipped = 0.0
                dropped = norm(shear) if mode == FORWARD else 0.0
                shear = ZERO
            place(history, q, b, shear)
            place(force, q, b, f)
            place(torque, q, b, t)
            destroyed[q, b] = slipped + dropped
            if slipped > 0.0:
                slips += 1
                last_slip = max(last_slip, q * walls + b)
            if dropped > 0.0:
                losses += 1
                last_loss = max(last_loss, q * walls + b)
    return slips, last_slip, losses, last_loss


@jit
def add_on_grid(total, value, factor, per_step):
    """total + factor value on a grid of 1 / per_step: total a 3-tuple of integers, factor
    value rounded to the grid first (`fixed.rounded`; the steps are powers of two, so
    multiplying by per_step divides by the step exactly). Returns (sum, whether it stayed in
    range)."""
    n0 = fx.rounded(factor * value[0] * per_step)
    n1 = fx.rounded(factor * value[1] * per_step)
    n2 = fx.rounded(factor * value[2] * per_step)
    if max(abs(n0), abs(n1), abs(n2)) > fx.RANGE:
        return total, False
    result = (total[0] + np.int64(n0), total[1] + np.int64(n1), total[2] + np.int64(n2))
    return result, max(abs(result[0]), abs(result[1]), abs(result[2])) <= fx.RANGE


def _gather_loop(
    mass,
    inv_mass,
    inv_inertia,
    radius,
    v,
    w,
    gravity,
    local,
    first,
    start,
    slots,
    pair_force,
    moment,
    overlaps,
    wall_force,
    wall_torque,
    f_out,
    t_out,
    h,
    fixed_v,
    fixed_w,
    grid,
):
    """Net force and moment on each particle: weight, pairs by partner index, walls in order
    (Hanley 2020 Eq 4-5), local damping of each component, f - gamma_l |f| sgn(v) (Eq 21);
    then the half kick v += h f / m, w += h t / I (Eq 11-12; h = 0: none). Without a
    tangential law (no `moment`) every moment is zero.

    In fixed-point arithmetic (fixed_v not empty) each term is rounded to the force or moment
    grid and summed as an integer, so the sum does not depend on the order of its terms,
    and the kick lands on the velocity grids. Returns (particles whose sum or velocity left
    its grid, the last of them)."""
    torques = moment.shape[0] > 0
    on_grid = fixed_v.shape[0] > 0
    f_step = grid[fx.FORCE] if on_grid else 1.0
    t_step = grid[fx.TORQUE] if on_grid else 1.0
    per_f, per_t = 1.0 / f_step, 1.0 / t_step
    out = 0
    last = -1
    n = f_out.shape[0]
    for q in numba.prange(n):
        if q + AHEAD < n:
            for s in range(start[q + AHEAD], start[q + AHEAD + 1]):
                k = np.uint32(slots[s])
                prefetch(pair_force, k)
                if torques:
                    prefetch(moment, k)
                    prefetch(overlaps, k)
        weight = scaled(mass[q], (gravity[0], gravity[1], gravity[2]))
        f_int = (np.int64(0), np.int64(0), np.int64(0))
        t_int = (np.int64(0), np.int64(0), np.int64(0))
        f = ZERO if on_grid else weight
        t = ZERO
        ok = True
        if on_grid:
            f_int, ok = add_on_grid(f_int, weight, 1.0, per_f)
        # the two partner loops are written out: one helper for both, returning the four
        # sums, made this loop 1.4 to 2.6 times slower (n = 24 fcc, float and fixed point)
        for s in range(start[q], start[q + 1]):  # partners p < q, the reaction -f
            k = np.uint32(slots[s])  # unsigned, as in `gather_pairs`
            if on_grid:
                f_int, fine = add_on_grid(f_int, row(pair_force, k), -1.0, per_f)
                ok = ok and fine
            else:
                f = axpy(-1.0, row(pair_force, k), f)
            if torques:  # Hanley 2020 Eq 5: the lever arm r - overlap / 2 times n x f
                arm = radius[q] - 0.5 * overlaps[k]
                if on_grid:
                    t_int, fine = add_on_grid(t_int, row(moment, k), arm, per_t)
                    ok = ok and fine
                else:
                    t = axpy(arm, row(moment, k), t)
        for kk in range(first[q], first[q + 1]):  # partners j > q
            k = np.uint64(kk)
            if on_grid:
                f_int, fine = add_on_grid(f_int, row(pair_force, k), 1.0, per_f)
                ok = ok and fine
            else:
                f = axpy(1.0, row(pair_force, k), f)
            if torques:
                arm = radius[q] - 0.5 * overlaps[k]
                if on_grid:
                    t_int, fine = add_on_grid(t_int, row(moment, k), arm, per_t)
                    ok = ok and fine
                else:
                    t = axpy(arm, row(moment, k), t)
        for b in range(wall_force.shape[1]):
            if on_grid:
                f_int, fine = add_on_grid(f_int, cell_of(wall_force, q, b), 1.0, per_f)
                t_int, turned = add_on_grid(t_int, cell_of(wall_torque, q, b), 1.0, per_t)
                ok = ok and fine and turned
            else:
                f = axpy(1.0, cell_of(wall_force, q, b), f)
                t = axpy(1.0, cell_of(wall_torque, q, b), t)
        if on_grid:
            f = (f_int[0] * f_step, f_int[1] * f_step, f_int[2] * f_step)
            t = (t_int[0] * t_step, t_int[1] * t_step, t_int[2] * t_step)
        for d in range(3):
            f_out[q, d] = f[d] - local * abs(f[d]) * sign(v[q, d])  # Hanley 2020 Eq 21
        if torques:  # else the moments stay zero
            for d in range(3):
                t_out[q, d] = t[d] - local * abs(t[d]) * sign(w[q, d])
        if on_grid:
            ok = ok and kick_on_grid(fixed_v, v, f_out, inv_mass, q, h, grid[fx.VELOCITY])
            if torques:
                step = grid[fx.ANGULAR_VELOCITY]
                ok = ok and kick_on_grid(fixed_w, w, t_out, inv_inertia, q, h, step)
        else:
            for d in range(3):
                v[q, d] += h * f_out[q, d] * inv_mass[q]
                if torques:
                    w[q, d] += h * t_out[q, d] * inv_inertia[q]
        if not ok:
            out += 1
            last = max(last, q)
    return out, last


@jit
def kick_on_grid(n, v, f, inv_m, q, h, step):
    """The half kick of particle q on its grid, n += round(h f / m / step), v = n step
    (`fixed._kick`); whether it stayed in range."""
    ok = True
    per_step = 1.0 / step  # a power of two: multiplying by it divides exactly
    for d in range(3):
        increment = fx.rounded(h * f[q, d] * inv_m[q] * per_step)
        if abs(increment) > fx.RANGE or abs(n[q, d] + np.int64(increment)) > fx.RANGE:
            ok = False
        else:
            n[q, d] += np.int64(increment)
        v[q, d] = n[q, d] * step
    return ok


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
    normal_new,
    law,
    dt,
):
    """Reversed step, before drifting back: undo Eq 10 and 9 for every pair, in place."""
    strain = strain_rates(rate, length)
    for k in numba.prange(n_pairs):
        i = pi[k]
        j = pj[k]
        d = separation(x, i, j, image)
        dist = norm(d)
        overlap = radius[i] + radius[j] - dist
        n = scaled(1.0 / dist, d)
        w_i = row(w, i)
        w_j = row(w, j)
        v_ij = axpy(-1.0, row(v, i), row(v, j))
        vrel, spin = pair_velocity(
            d, n, overlap, radius[i], radius[j], v_ij, w_i, w_j, strain, deforming
        )
        rstar = radius[i] * radius[j] / (radius[i] + radius[j])
        gs = gstar[material[i], material[j]]
        put(history, k, unwind_shear(law, dt, overlap, n, rstar, gs, vrel, spin, row(history, k)))
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
                law, dt, overlap, n, radius[q], gs, vrel, spin, cell_of(history, q, b)
            )
            place(history, q, b, shear)
            place(normal_new, q, b, n)


pair_loop, pair_loop_parallel = serial_and_parallel(_pair_loop)
wall_loop, wall_loop_parallel = serial_and_parallel(_wall_loop)
gather_loop, gather_loop_parallel = serial_and_parallel(_gather_loop)
unwind_pair_loop, unwind_pair_loop_parallel = serial_and_parallel(_unwind_pair_loop)
unwind_wall_loop, unwind_wall_loop_parallel = serial_and_parallel(_unwind_wall_loop)


@jit
def compute_forces(p, pairs, walls, cell, fixed, law, moduli, dyn, mode, dt, h, events, step):
    """Forces at the current positions (Hanley 2020 Eq 4-10 and 21 forward, Eq 19 reversed),
    the half kick h that follows them, and the stress a servo needs; the shear force the
    step destroyed goes into the event log at `step`."""
    deforming = deforms(cell)
    particle_args = (p.x, p.v, p.omega, p.radius, p.mass, p.material, moduli.estar, moduli.gstar)
    pair_args = (
        cell.rate,
        cell.length,
        deforming,
        pairs.i,
        pairs.j,
        pairs.count[0],
        pairs.force,
        pairs.history,
        pairs.moment,
        pairs.overlap,
        pairs.destroyed,
        pairs.normal_new,
        law,
        mode,
        dt,
        pairs.blocks,
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
        walls.force,
        walls.torque,
        walls.overlap,
        walls.history,
        walls.destroyed,
        walls.normal_new,
        law,
        mode,
        dt,
    )
    gather_args = (
        p.mass,
        p.inv_mass,
        p.inv_inertia,
        p.radius,
        p.v,
        p.omega,
        dyn.gravity,
        dyn.local_damping,
        pairs.first,
        pairs.start,
        pairs.slots,
        pairs.force,
        pairs.moment,
        pairs.overlap,
        walls.force,
        walls.torque,
        p.f,
        p.torque,
        h,
        fixed.v,
        fixed.omega,
        fixed.grid,
    )
    periodic = cell.periodic[0] or cell.periodic[1] or cell.periodic[2]
    if p.x.shape[0] >= PARALLEL_FROM:
        if periodic:  # an open system's pairs skip the nearest image: a build of its own
            pair_events = pair_loop_parallel(*particle_args, images(cell), *pair_args)
        else:
            pair_events = pair_loop_parallel(*particle_args, None, *pair_args)
        wall_events = wall_loop_parallel(*wall_args)
        if holds_stress(cell):
            stress_of(p, pairs, cell)
        gathered = gather_loop_parallel(*gather_args)
    else:
        if periodic:
            pair_events = pair_loop(*particle_args, images(cell), *pair_args)
        else:
            pair_events = pair_loop(*particle_args, None, *pair_args)
        wall_events = wall_loop(*wall_args)
        if holds_stress(cell):
            stress_of(p, pairs, cell)
        gathered = gather_loop(*gather_args)
    fx.note_overflow(fixed, fx.OF_FORCE, gathered)
    servo_forces(cell, dyn.local_damping)
    note_destroyed(events, step, pairs, walls, pair_events, wall_events)


def _stress_sums(x, image, pi, pj, first, force, partials):
    """sum of -d (x) f over the pairs listed under each block of particles (`kernels.sums`),
    in list order, partials[b, 3 a + c]."""
    n = x.shape[0]
    for b in numba.prange(blocks_of(n)):
        partials[b, :9] = 0.0
        lo, hi = span(b, n)
        for k in range(first[lo], first[hi]):
            f = row(force, k)
            if f[0] != 0.0 or f[1] != 0.0 or f[2] != 0.0:
                d = separation(x, pi[k], pj[k], image)
                for a in range(3):
                    for c in range(3):
                        partials[b, 3 * a + c] -= d[a] * f[c]


stress_sums, stress_sums_parallel = serial_and_parallel(_stress_sums)


@jit
def stress_of(p, pairs, cell):
    """Average stress in the cell, -1/V sum over contacts of d (x) f with d the branch vector
    from i to j and f the force on i (Hanley 2020 Eq 22-23 summed over the particles;
    compression positive), summed over the pair list by blocks (`kernels.sums`)."""
    n = p.x.shape[0]
    parts = pairs.partials
    args = (p.x, images(cell), pairs.i, pairs.j, pairs.first, pairs.force, parts)
    if n > SPAN:
        stress_sums_parallel(*args)
    else:
        stress_sums(*args)
    sigma = cell.stress
    sigma[:, :] = 0.0
    for b in range(blocks_of(n)):
        for a in range(3):
            for c in range(3):
                sigma[a, c] += parts[b, 3 * a + c]
    scale = 1.0 / volume(cell)
    for a in range(3):
        for c in range(3):
            sigma[a, c] *= scale


@jit
def wall_normal(p, walls, q, b):
    """Unit normal from particle q towards wall b (for observables, not per step)."""
    point, axis = row(walls.point, b), row(walls.axis, b)
    return wall_overlap(walls.kind[b], point, axis, walls.radius[b], row(p.x, q), p.radius[q])[1]


@jit
def particle_stress(p, pairs, walls, cell, out):
    """Stress of each particle, -1/V_p sum over its contacts of x_c (x) f_c with x_c from its
    centre to the contact point (Hanley 2020 Eq 22; compression positive), Pa, (N, 3, 3).

    A pair's force f on i acts on j as -f at -arm_j n: both particles get arm n (x) f."""
    out[:] = 0.0
    image = images(cell)
    for k in range(pairs.count[0]):
        f = row(pairs.force, k)
        if f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0:
            continue
        i, j = pairs.i[k], pairs.j[k]
        d = separation(p.x, i, j, image)
        dist = norm(d)
        overlap = p.radius[i] + p.radius[j] - dist
        for q in (i, j):
            arm = p.radius[q] - 0.5 * overlap
            for a in range(3):
                for b in range(3):
                    out[q, a, b] -= arm * d[a] / dist * f[b]
    for q in range(p.x.shape[0]):
        for b in range(walls.force.shape[1]):
            if walls.overlap[q, b] > 0.0:
                n = wall_normal(p, walls, q, b)
                arm = p.radius[q] - 0.5 * walls.overlap[q, b]
                for a in range(3):
                    for c in range(3):
                        out[q, a, c] -= arm * n[a] * walls.force[q, b, c]
        out[q] *= 3.0 / (4.0 * math.pi * p.radius[q] ** 3)


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
