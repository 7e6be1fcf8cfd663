"""The gather: each particle's force and moment, which the pair loop has summed from its
weight and its pairs in a fixed order (`pairs.sum_in_order`), completed by its walls in
order (`complete_sums`; in fixed-point arithmetic also judged and put on their grids);
then local damping and the half kick (`damp_and_kick`, on the velocity grids
`damp_and_kick_on_grids`)."""

import numba
import numpy as np

from revdem_cli.kernels import LIGHT, by_parts, by_size, inline, inline_arrays, jit
from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels.vectors import ZERO, axpy, cell_of, row, scaled, sign


@inline
def locally_damped(f, v, local):
    """A component f of a force or moment less local damping against the velocity's
    component v: f - gamma_l |f| sgn(v) (Hanley 2020 Eq 21)."""
    return f - local * abs(f) * sign(v)


@inline
def weight_of(m, gravity):
    """The weight m g of a particle of mass m."""
    return scaled(m, (gravity[0], gravity[1], gravity[2]))


@inline
def weight_summed(m, gravity, f_step):
    """Where each force sum of a particle of mass m starts: its weight, in fixed-point
    arithmetic (f_step, the force grid's step, not 0) rounded onto the force grid
    (`fixed.add_rounded`)."""
    weight = weight_of(m, gravity)
    if f_step == 0.0:
        return weight
    return fx.add_rounded(ZERO, weight, f_step, 1.0 / f_step)


@inline_arrays
def _largest_wall_term(q, wall_force, per_step):
    """The largest magnitude of a component of particle q's wall forces, in steps of the force
    grid, before rounding (as `fixed.add_on_grid` finds it)."""
    largest = 0.0
    for b in range(wall_force.shape[1]):
        largest = fx.largest_of(fx.in_range3(scaled(per_step, cell_of(wall_force, q, b))), largest)
    return largest


@inline
def _terms(q, first, start, walls):
    """The terms of particle q's force sum: its weight, its pairs and its walls."""
    at, after = np.uint64(q), np.uint64(q) + np.uint64(1)  # no wraparound (uint64 + 1 is a float)
    return 1 + start[after] - start[at] + first[after] - first[at] + walls


@inline
def _may_round(weight, largest_wall, largest_pair, terms, per_f):
    """Whether a particle's force sum in doubles may have rounded: not where its largest term
    (the pair loop's largest pair force, N, its weight, or its largest wall force,
    `largest_wall`, grid steps) times the number of terms stays below 2^53 grid steps
    (`fixed.sum_exact`)."""
    own = fx.largest_of(fx.in_range3(scaled(per_f, weight)), largest_wall)
    return not fx.sum_exact(max(largest_pair * per_f, own), terms)


@inline
def _pairs_as_integers(q, weight, first, start, slots, pair_force, per_f):
    """Particle q's weight and pairs summed as integers on the force grid (`fixed.add_on_grid`,
    `add_snapped`), in the pair loop's order: (the sum, its largest term in grid steps)."""
    total, largest = fx.add_on_grid((np.int64(0), np.int64(0), np.int64(0)), weight, 1.0, per_f,
                                    0.0)  # fmt: skip
    for s in range(start[q], start[q + 1]):  # partners p < q, the reaction -f
        k = np.uint32(slots[s])  # unsigned, as in `pairs.gather_pairs`
        total, largest = fx.add_snapped(total, row(pair_force, k), -1.0, per_f, largest)
    for kk in range(first[q], first[q + 1]):  # partners j > q
        total, largest = fx.add_snapped(total, row(pair_force, np.uint64(kk)), 1.0, per_f, largest)
    return total, largest


def _sums_in_full(
    mass, gravity, first, start, slots, pair_force, torques, wall_force, wall_torque, f_out,
    t_out, on_grid, grid, largest_pair, kept,
):  # fmt: skip
    """Net force and moment on each particle (Hanley 2020 Eq 4-5): f_out and t_out hold its
    weight and its pairs' terms, which the pair loop summed by partner index
    (`pairs.sum_in_order`); its walls are added in order. Without `torques` (a tangential
    law) the moments stay zero.

    In fixed-point arithmetic (`on_grid`) each force term is on the force grid and the sum
    is their integer sum, so that the pairs' forces cancel to the integer (momentum is
    conserved exactly): the pair loop has rounded each pair's force once for its two
    particles (`fixed.snapped_in_range`) and the weight onto the grid, and summed them in
    doubles; wall forces are rounded onto the grid as they are added. The pair loop finds
    the largest component of a pair's force (`largest_pair`, N); with the particle's own
    weight and wall forces it bounds each term of its sum: where that bound times the
    number of terms stays below 2^53 grid steps (`fixed.sum_exact`: every partial sum is
    then an integer a double holds) the sum in doubles is exact, in any order, and is kept;
    elsewhere the terms are summed again as integers from the pair arrays (`Pairs.force`,
    `_pairs_as_integers`), each term's size kept track of; the two give the same bits. Where
    the pair loop did not keep its forces there (`kept` false), such a particle is only
    counted: the caller runs the pair loop again, keeping them, and this again. A sum
    in doubles is in range; one of integers leaves its grid when its largest term times the
    number of terms would (`fixed.sum_in_range`). The moment, summed in doubles in the fixed
    order, is rounded onto the moment grid once (`fixed.snapped_in_range`; it leaves the
    grid when that does): a reversed run sums the same terms in the same order, its pairs
    by partner index whichever steps its lists were built at (a pair listed in one run and
    not in the other adds an exact zero). Returns (particles whose force or moment left its
    grid, the last of them, what left it there: fixed.OF_FORCE, or OF_MOMENT where the
    force did not, the particles whose sums need the pair forces not `kept`)."""
    f_step = grid[fx.FORCE] if on_grid else 1.0
    t_step = grid[fx.TORQUE] if on_grid else 1.0
    per_f, per_t = 1.0 / f_step, 1.0 / t_step
    out = 0
    worst = -1  # QUANTITIES x particle + quantity of the last particle off its grid
    unsummed = 0
    for q in numba.prange(f_out.shape[0]):
        f = row(f_out, q)
        t = row(t_out, q) if torques else ZERO
        f_int = (np.int64(0), np.int64(0), np.int64(0))
        integer = False  # summed as integers, not in doubles
        largest_f = 0.0  # summed as integers: its largest term, in grid steps
        terms = _terms(q, first, start, wall_force.shape[1])
        if on_grid:
            weight = weight_of(mass[q], gravity)
            largest_wall = _largest_wall_term(q, wall_force, per_f)
            integer = _may_round(weight, largest_wall, largest_pair, terms, per_f)
            if integer and not kept:  # no pair forces to sum
                unsummed += 1
            elif integer:  # the sum in doubles may have rounded
                f_int, largest_f = _pairs_as_integers(q, weight, first, start, slots,
                                                      pair_force, per_f)  # fmt: skip
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
        ok = True  # the force sum on its grid
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
            f_out[q, d] = f[d]
        if torques:
            for d in range(3):
                t_out[q, d] = t[d]
        if not (ok and turned):
            out += 1
            quantity = fx.OF_FORCE if not ok else fx.OF_MOMENT
            worst = max(worst, q * len(fx.QUANTITIES) + quantity)
    kinds = len(fx.QUANTITIES)
    return out, worst // kinds if out else -1, worst % kinds if out else 0, unsummed


sums_in_full = by_size(_sums_in_full, LIGHT)


def _rounding(begin, end, mass, gravity, first, start, largest_pair, per_f):
    """Particles `begin` to `end` - 1 of a system without walls whose force sum in doubles may
    have rounded (`_may_round`), elementwise, which LLVM vectorises: (how many, -1: which
    ones `complete_sums` does not ask)."""
    out = 0
    for k in range(begin, end):
        q = np.uint64(k)  # unsigned: no wraparound, which stops LLVM
        weight = weight_of(mass[q], gravity)
        out += _may_round(weight, 0.0, largest_pair, _terms(q, first, start, 0), per_f)
    return out, -1


def _moments_on_grid(begin, end, t, step):
    """Coordinates `begin` to `end` - 1 of the moments t (flat) rounded onto the grid of
    `step` (`fixed.snapped_value`), elementwise: (how many were out of its range, the last or
    -1)."""
    per = 1.0 / step
    out = 0
    last = -1
    for k in range(begin, end):
        c = np.uint64(k)  # as in `_rounding`
        fine = fx.within_range(t[c] * per)
        t[c] = fx.snapped_value(t[c], step)
        out += not fine
        last = max(last, -1 if fine else k)
    return out, last


rounding = by_parts(_rounding, LIGHT)
moments_on_grid = by_parts(_moments_on_grid, LIGHT)


@jit
def complete_sums(
    n, mass, gravity, first, start, slots, pair_force, torques, wall_force, wall_torque, f_out,
    t_out, on_grid, grid, largest_pair, kept,
):  # fmt: skip
    """`sums_in_full`, which returns what it does, or in fixed-point arithmetic without walls,
    where no particle's force sum in doubles may have rounded (`rounding`), its two
    elementwise passes: the forces stay as the pair loop summed them (from +0, never -0:
    the + 0.0 of `sums_in_full` changes nothing there) and the moments are rounded onto
    their grid (`moments_on_grid`). The fcc benchmark without friction at n = 24, one core:
    10.9 ns a sphere in full, 1.2-1.9 judged elementwise (`rounding`)."""
    if on_grid and wall_force.shape[1] == 0:
        per_f = 1.0 / grid[fx.FORCE]
        if rounding(n, mass, gravity, first, start, largest_pair, per_f)[0] == 0:
            out, last = 0, -1
            if torques:
                out, last = moments_on_grid(n, t_out.reshape(-1), grid[fx.TORQUE])
            return out, last // 3 if out else -1, fx.OF_MOMENT if out else 0, 0
    return sums_in_full(
        n, mass, gravity, first, start, slots, pair_force, torques, wall_force, wall_torque,
        f_out, t_out, on_grid, grid, largest_pair, kept,
    )  # fmt: skip


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
    to `end` - 1; none without it (gamma_l = 0 leaves every finite f as it is: a pass over
    f and v saved, about 3 ns a sphere, n = 24 fcc, one core)."""
    if local == 0.0:
        return
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


def _damp_and_kick_on_grids(begin, end, f, t, v, w, v_damp, w_damp, inv_mass, inv_inertia,
                            local, h, torques, fixed_v, fixed_w, grid):  # fmt: skip
    """`damp_and_kick_on_grids` of particles `begin` to `end` - 1 (`by_parts`). Returns
    (velocities and angular velocities that left their grids, 2 q + 1 for the last particle
    q whose velocity did, else 2 q for the last whose angular velocity did, -1 for none)."""
    damp_rows(begin, end, f, v_damp, local)
    out, last = fx.kick_part(begin, end, fixed_v, v, f, inv_mass, h, grid[fx.VELOCITY])
    last = 2 * last + 1 if out else -1
    if torques:
        damp_rows(begin, end, t, w_damp, local)
        step = grid[fx.ANGULAR_VELOCITY]
        spun, at = fx.kick_part(begin, end, fixed_w, w, t, inv_inertia, h, step)
        if spun and not out:
            last = 2 * at
        out += spun
    return out, last


kick = by_parts(_kick, LIGHT)
damp_and_kick = by_parts(_damp_and_kick, LIGHT)
"""The gather's end, once each particle's force and moment sum is complete (the pair loop's,
`pairs.sum_in_order`, and where walls add to them `complete_sums`), called as f(n, f, t,
v, w, ...): local damping of each component, f - gamma_l |f| sgn(v) (Hanley 2020 Eq 21; v
from `v_damp`, `w_damp`: the half-step velocities or the predictor's), and the half kick v
+= h f / m, w += h t / I (Eq 11-12; h = 0: none), one array at a time in loops of their
own, which LLVM vectorises (damping's velocities v_damp may be v itself, and a loop that
read the one and wrote the other would not be); the moments likewise where there are
(`torques`: a tangential law). One parallel region, each thread's part of the particles
through all four loops (`by_parts`), not one region a loop: at 4 000 spheres on two
threads a region costs about what the loop inside it does."""
damp_and_kick_on_grids = by_parts(_damp_and_kick_on_grids, LIGHT)
"""`damp_and_kick` in fixed-point arithmetic, after `complete_sums`, called as f(n, f, t, v,
w, ..., torques, fixed_v, fixed_w, grid): the half kick lands on the velocity grids
(`fixed.kick`, the velocities the integers give)."""
