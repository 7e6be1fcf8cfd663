"""The gather: each particle sums the forces and moments on it in a fixed order (its
weight, its pairs by partner index, its walls in order), applies local damping, and takes
its half kick; in fixed-point arithmetic on integer grids. The pair loop in floating
point has summed the weight and the pairs already, in the same order (`pairs.sum_in_order`)."""

import numba
import numpy as np

from revdem_cli.kernels import by_parts, by_size, inline, inline_arrays, prefetch
from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels.vectors import ZERO, axpy, cell_of, cross, row, scaled, sign


@inline
def locally_damped(f, v, local):
    """A component f of a force or moment less local damping against the velocity's
    component v: f - gamma_l |f| sgn(v) (Hanley 2020 Eq 21)."""
    return f - local * abs(f) * sign(v)


@inline
def weight_of(m, gravity):
    """The weight m g of a particle of mass m, where each of its force sums starts."""
    return scaled(m, (gravity[0], gravity[1], gravity[2]))


AHEAD = 8
"""The gather asks for the reactions of the particle this many ahead of the one it sums:
they lie under earlier particles, far back in the pair arrays, and the hardware does not
see them coming (at 10^6 fcc spheres the gather takes 26-31 % less time; 8 ahead did best
overall: 16 was 6 % faster frictionless at 10^6 but 9-12 % slower with history, 4 slower)."""


@inline_arrays
def _largest_own_term(q, weight, wall_force, per_step):
    """The largest magnitude of a component of particle q's weight and wall forces, in steps
    of the force grid, before rounding (as `fixed.add_on_grid` finds it)."""
    largest = fx.largest_of(fx.in_range3(scaled(per_step, weight)), 0.0)
    for b in range(wall_force.shape[1]):
        largest = fx.largest_of(fx.in_range3(scaled(per_step, cell_of(wall_force, q, b))), largest)
    return largest


def _gather_loop(
    mass,
    inv_mass,
    inv_inertia,
    radius,
    v,
    w,
    v_damp,
    w_damp,
    gravity,
    local,
    first,
    start,
    slots,
    pair_force,
    moment,
    of_normals,
    overlaps,
    rolling,
    wall_force,
    wall_torque,
    f_out,
    t_out,
    h,
    fixed_v,
    fixed_w,
    grid,
    largest_pair,
    summed,
):
    """Net force and moment on each particle: weight, pairs by partner index, walls in order
    (Hanley 2020 Eq 4-5), local damping of each component, f - gamma_l |f| sgn(v) (Eq 21; v
    from `v_damp`, `w_damp`: the half-step velocities or the predictor's); then the half
    kick v += h f / m, w += h t / I (Eq 11-12; h = 0: none). A pair's moment on each of its
    particles is its lever arm r - overlap / 2 times n x f (Eq 5): the rows of `moment`, or
    where `of_normals` (fixed point, `Pairs.normal`) its rows are the pairs' contact normals
    n, crossed with their forces f on the grid; without a tangential law (no `moment`) every
    moment is zero; with a rolling law (`rolling`, the rolling moment on the pair's first
    particle) each pair adds its rolling moment, on i, and its opposite, on j. Where
    `summed`, f_out and t_out hold the weight and the pairs' terms already, added in this
    order and by this arithmetic by the pair loop (`pairs.sum_in_order`), and the pair
    arrays are not read.

    In fixed-point arithmetic (fixed_v not empty) each force term is on the force grid and
    the sum is their integer sum, so that the pairs' forces cancel to the integer (momentum
    is conserved exactly): the pair loop has rounded each pair's force once for its two
    particles (`fixed.snapped_in_range`), and the weight and wall forces are rounded onto
    the grid as they are added. The pair loop finds the largest component of a pair's
    force (`largest_pair`, N); with the particle's own weight and wall forces it bounds each
    term of its sum: where that bound times the number of terms stays below 2^53 grid steps
    (`fixed.sum_exact`: every partial sum is then an integer a double holds) the terms are
    summed in doubles, exactly and in any order, else as integers, each term's size kept
    track of; the two give the same bits. A sum in doubles is in range; one of integers
    leaves its grid when its largest term times the number of terms would
    (`fixed.sum_in_range`). The moment is summed in doubles in the same fixed order and the
    sum rounded onto the moment grid once (`fixed.snapped_in_range`; it leaves the grid when
    that does): a reversed run sums the same terms in the same order, its pairs by partner
    index whichever steps its lists were built at (a pair listed in one run and not in the
    other adds an exact zero). The kick lands on the velocity grids. Returns (particles
    whose sum or velocity left its grid, the last of them, what left it there:
    fixed.OF_FORCE, OF_MOMENT, OF_VELOCITY or OF_ANGULAR_VELOCITY, the first of these in
    that order)."""
    torques = moment.shape[0] > 0
    rolls = rolling.shape[0] > 0
    on_grid = fixed_v.shape[0] > 0
    f_step = grid[fx.FORCE] if on_grid else 1.0
    t_step = grid[fx.TORQUE] if on_grid else 1.0
    per_f, per_t = 1.0 / f_step, 1.0 / t_step
    out = 0
    worst = -1  # QUANTITIES x particle + quantity of the last particle off its grid
    n = f_out.shape[0]
    for q in numba.prange(n):
        if q + AHEAD < n and not summed:
            for s in range(start[q + AHEAD], start[q + AHEAD + 1]):
                k = np.uint32(slots[s])
                prefetch(pair_force, k)
                if torques:
                    prefetch(moment, k)
                    prefetch(overlaps, k)
        weight = weight_of(mass[q], gravity)
        f_int = (np.int64(0), np.int64(0), np.int64(0))
        f = ZERO if on_grid else weight
        t = ZERO
        pairs_from, own_from = start[q], first[q]  # the first of its partners to add
        if summed:  # weight and pairs, summed in this order by the pair loop
            f = row(f_out, q)
            t = row(t_out, q) if torques else ZERO
            pairs_from, own_from = start[q + 1], first[q + 1]  # none left
        ok = True  # the force sum on its grid
        integer = False  # summed as integers, not in doubles
        largest_f = 0.0  # summed as integers: its largest term so far, in grid steps
        terms = 1 + start[q + 1] - start[q] + first[q + 1] - first[q] + wall_force.shape[1]
        if on_grid:
            bound = max(largest_pair * per_f, _largest_own_term(q, weight, wall_force, per_f))
            integer = not fx.sum_exact(bound, terms)
            if integer:
                f_int, largest_f = fx.add_on_grid(f_int, weight, 1.0, per_f, largest_f)
            else:
                f = fx.add_rounded(f, weight, f_step, per_f)
        # the two partner loops are written out: one helper for both, returning the four
        # sums, made this loop 1.4 to 2.6 times slower (n = 24 fcc, float and fixed point)
        for s in range(pairs_from, start[q + 1]):  # partners p < q, the reaction -f
            k = np.uint32(slots[s])  # unsigned, as in `gather_pairs`
            if integer:
                f_int, largest_f = fx.add_snapped(f_int, row(pair_force, k), -1.0, per_f, largest_f)
            else:
                f = axpy(-1.0, row(pair_force, k), f)
            if torques:  # Hanley 2020 Eq 5: the lever arm r - overlap / 2 times n x f
                n_x_f = row(moment, k)
                if of_normals:
                    n_x_f = cross(n_x_f, row(pair_force, k))
                t = axpy(radius[q] - 0.5 * overlaps[k], n_x_f, t)
            if rolls:  # the opposite of the rolling moment on p
                t = axpy(-1.0, row(rolling, k), t)
        for kk in range(own_from, first[q + 1]):  # partners j > q
            k = np.uint64(kk)
            if integer:
                f_int, largest_f = fx.add_snapped(f_int, row(pair_force, k), 1.0, per_f, largest_f)
            else:
                f = axpy(1.0, row(pair_force, k), f)
            if torques:
                n_x_f = row(moment, k)
                if of_normals:
                    n_x_f = cross(n_x_f, row(pair_force, k))
                t = axpy(radius[q] - 0.5 * overlaps[k], n_x_f, t)
            if rolls:
                t = axpy(1.0, row(rolling, k), t)
        for b in range(wall_force.shape[1]):
            if integer:
                f_int, largest_f = fx.add_on_grid(
                    f_int, cell_of(wall_force, q, b), 1.0, per_f, largest_f
                )
            elif on_grid:
                f = fx.add_rounded(f, cell_of(wall_force, q, b), f_step, per_f)
            else:
                f = axpy(1.0, cell_of(wall_force, q, b), f)
            t = axpy(1.0, cell_of(wall_torque, q, b), t)
        turned = True  # the moment sum
        if on_grid:
            if integer:
                ok = fx.sum_in_range(largest_f, terms)
                f = (f_int[0] * f_step, f_int[1] * f_step, f_int[2] * f_step)
            else:
                f = (f[0] + 0.0, f[1] + 0.0, f[2] + 0.0)  # a sum of zeros is +0, as f_int's
            turned = fx.in_grid_range(t[0] * per_t, t[1] * per_t, t[2] * per_t)
            t = fx.snapped_in_range(t, t_step)
        for d in range(3):
            f_out[q, d] = locally_damped(f[d], v_damp[q, d], local)
        if torques:  # else the moments stay zero
            for d in range(3):
                t_out[q, d] = locally_damped(t[d], w_damp[q, d], local)
        kicked = True
        spun = True
        if on_grid:
            kicked = fx.kick_row(fixed_v, v, f_out, inv_mass, q, h, grid[fx.VELOCITY])
            if torques:
                step = grid[fx.ANGULAR_VELOCITY]
                spun = fx.kick_row(fixed_w, w, t_out, inv_inertia, q, h, step)
        else:
            for d in range(3):
                v[q, d] += h * f_out[q, d] * inv_mass[q]  # `_kick`
                if torques:
                    w[q, d] += h * t_out[q, d] * inv_inertia[q]
        if not (ok and turned and kicked and spun):
            out += 1
            if not ok:
                quantity = fx.OF_FORCE
            elif not turned:
                quantity = fx.OF_MOMENT
            elif not kicked:
                quantity = fx.OF_VELOCITY
            else:
                quantity = fx.OF_ANGULAR_VELOCITY
            worst = max(worst, q * len(fx.QUANTITIES) + quantity)
    kinds = len(fx.QUANTITIES)
    return out, worst // kinds if out else -1, worst % kinds if out else 0


gather_loop = by_size(_gather_loop)


@inline_arrays
def kick_rows(begin, end, v, f, inv_m, h):
    """v += h f / m of particles `begin` to `end` - 1: a half kick, h = +dt/2 (Hanley 2020
    Eq 1-2, 11-12) or -dt/2 (Eq 17, 20); elementwise, which LLVM vectorises."""
    for k in range(begin, end):
        q = np.uint64(k)  # unsigned: no wraparound, which stops LLVM
        for d in range(3):
            v[q, d] += h * f[q, d] * inv_m[q]


@inline_arrays
def damp_rows(begin, end, f, v, local):
    """Local damping of each component of f against v (`locally_damped`), particles `begin`
    to `end` - 1."""
    for k in range(begin, end):
        q = np.uint64(k)  # as in `kick_rows`
        for d in range(3):
            f[q, d] = locally_damped(f[q, d], v[q, d], local)


def _kick(begin, end, v, w, f, t, inv_mass, inv_inertia, h, moments):
    """The half kick of particles `begin` to `end` - 1 (`by_parts`): their velocities and,
    where there are `moments` (a tangential law), their angular velocities, each array in a
    loop of its own (`kick_rows`). Nothing leaves a grid: returns (0, -1)."""
    kick_rows(begin, end, v, f, inv_mass, h)
    if moments:
        kick_rows(begin, end, w, t, inv_inertia, h)
    return 0, -1


def _damp_and_kick(begin, end, f, t, v, w, v_damp, w_damp, inv_mass, inv_inertia, local, h,
                   torques):  # fmt: skip
    """`damp_and_kick` of particles `begin` to `end` - 1 (`by_parts`); returns (0, -1)."""
    damp_rows(begin, end, f, v_damp, local)
    kick_rows(begin, end, v, f, inv_mass, h)
    if torques:
        damp_rows(begin, end, t, w_damp, local)
        kick_rows(begin, end, w, t, inv_inertia, h)
    return 0, -1


kick = by_parts(_kick)
damp_and_kick = by_parts(_damp_and_kick)
"""The gather's end where the pair loop has summed every term of each particle's force and
moment (`pairs.sum_in_order`) and no walls add to them, called as f(n, f, t, v, w, ...):
local damping and the half kick as `_gather_loop` applies them, the same bits, one array at a
time in loops of their own, which LLVM vectorises (damping's velocities v_damp may be v
itself, and a loop that read the one and wrote the other would not be); the moments likewise
where there are (`torques`: a tangential law). One parallel region, each thread's part of
the particles through all four loops (`by_parts`), not one region a loop: at 4 000 spheres
on two threads a region costs about what the loop inside it does."""
