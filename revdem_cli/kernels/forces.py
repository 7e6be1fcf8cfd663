"""Contact forces and net forces on particles at the current positions: the one place the
force loops of a step are called, in order.

Three loops, each writing only its own slots: pairs (`pairs.py`: each pair's force computed
once), wall contacts (`wall_contacts.py`: each particle's, wall by wall), and the gather
(`gather.py`: each particle sums its weight, its pairs in the order of its partners'
indices, and its walls in order, then takes its half kick), so sums do not depend on the
thread count; in floating point the pair loop sums the pairs' terms itself, in the same
order. The pair and wall loops also count the contacts whose shear force was
destroyed (integer sums and maxima, which do not depend on the order either), so the event
log is scanned only when something happened.

The loops take plain arrays and do each item's work in the loop body, with helpers over
scalars and 3-tuples: a compiled call that receives array bundles pays an atomic
reference-count update per array, which would dominate the cost per item.
"""

from revdem_cli.kernels import fixed as fx
from revdem_cli.kernels import inline_arrays, jit
from revdem_cli.kernels.cell import deforms, holds_stress, images, servo_forces
from revdem_cli.kernels.contact import REVERSE
from revdem_cli.kernels.events import note_destroyed
from revdem_cli.kernels.gather import complete_sums, damp_and_kick, damp_and_kick_on_grids
from revdem_cli.kernels.pairs import contact_normals, pair_loop
from revdem_cli.kernels.stress import stress_of
from revdem_cli.kernels.wall_contacts import wall_loop


@jit
def loop_arguments(p, pairs, walls, cell, fixed, law, moduli, dyn, mode, dt, h):
    """The plain arrays and settings the loops take, in their order: (the particles' part of
    the pair loop's, the rest of it after the periodic images, the wall loop's,
    `gather.complete_sums`'s, `gather.damp_and_kick`'s, which `damp_and_kick_on_grids` takes
    followed by the integers and their grids). Damping (local, viscous) reads the
    velocities p.v, p.omega, or with a velocity predictor its predicted ones (Kolafa &
    Lisal 2011); the shear spring's increment always reads p.v, p.omega."""
    deforming = deforms(cell)
    of_normals = pairs.normal.shape[0] > 0  # fixed point with shear: no `Pairs.moment`
    kept = pairs.normal if of_normals else pairs.moment  # what the pairs keep for moments
    predicted = p.v_pred.shape[0] > 0  # damping reads the velocity predictor's velocities
    v_damp = p.v_pred if predicted else p.v
    w_damp = p.omega_pred if predicted else p.omega
    particle_args = (
        p.x, p.v, p.omega, v_damp, w_damp, predicted, p.radius, p.mass, p.material,
        moduli.estar, moduli.gstar,
    )  # fmt: skip
    pair_args = (
        cell.rate,
        cell.length,
        deforming,
        pairs.i,
        pairs.j,
        pairs.count[0],
        pairs.force,
        pairs.history,
        kept,
        pairs.overlap,
        pairs.destroyed,
        pairs.rolling,
        pairs.rolled,
        pairs.normal_new if mode == REVERSE else pairs.normal,  # the step's other end
        pairs.earlier,
        law,
        mode,
        dt,
        pairs.blocks,
        dyn.gravity,
        p.f,
        p.torque,
        pairs.first,
        pairs.start,
        pairs.slots,
        pairs.foreign,
        pairs.balance,
    )
    wall_args = (
        p.x,
        p.v,
        p.omega,
        v_damp,
        w_damp,
        predicted,
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
        walls.rolling,
        walls.rolled,
        walls.normal_new,
        law,
        mode,
        dt,
    )
    sum_args = (
        p.mass, dyn.gravity, pairs.first, pairs.start, pairs.slots, pairs.force,
        kept.shape[0] > 0, walls.force, walls.torque, p.f, p.torque, fixed.v.shape[0] > 0,
        fixed.grid,
    )  # fmt: skip
    end_args = (
        p.f, p.torque, p.v, p.omega, v_damp, w_damp, p.inv_mass, p.inv_inertia,
        dyn.local_damping, h, kept.shape[0] > 0,
    )  # fmt: skip
    return particle_args, pair_args, wall_args, sum_args, end_args


@inline_arrays
def pairs_now(n, cell, particle_args, pair_args, keep):
    """`pairs.pair_loop` over the list, across the periodic images of `cell` (in an open
    system none: `pairs.to_nearest_images` skips them); the pair arrays get each pair's
    results where `keep`. One build for both: one of its own for open systems (`image` None)
    cost a cold start 30 s of compiling and gained nothing measurable (README, *Compile
    time*)."""
    return pair_loop(n, *particle_args, images(cell), *pair_args, keep)


@jit
def compute_forces(p, pairs, walls, cell, fixed, law, moduli, dyn, mode, dt, h, events, step, keep):
    """Forces at the current positions (Hanley 2020 Eq 4-10 and 21 forward, Eq 19 reversed),
    the half kick h that follows them, and the stress a servo needs; the shear force and
    rolling moment the step destroyed go into the event log at `step`. The pair arrays
    (`Pairs.force`, `.moment`, `.overlap`) get each pair's where `keep` (something reads
    them before the next step), where a servo's stress is found from them, and in fixed
    point where the pairs carry histories (the next step turns them from the normals). In
    fixed point without histories, where a sum in doubles may have rounded
    (`gather.complete_sums`), the pair loop runs again, keeping its forces, which the
    gather sums as integers: a loop that changes nothing but the sums and the pair arrays
    gives the same bits twice, and a step where no sum rounds writes no pair forces (the
    forces of the n = 24 fcc benchmark without friction, one core: 96 -> 87 ns a sphere)."""
    particle_args, pair_args, wall_args, sum_args, end_args = loop_arguments(
        p, pairs, walls, cell, fixed, law, moduli, dyn, mode, dt, h
    )
    n = p.x.shape[0]
    on_grid = fixed.v.shape[0] > 0
    stressed = holds_stress(cell)  # a servo's stress, which `stress_of` finds from the pairs'
    carries = pairs.history.shape[0] > 0 or pairs.rolling.shape[0] > 0  # shear, rolling
    keep = keep or stressed or (on_grid and carries)
    pair_events, largest = pairs_now(n, cell, particle_args, pair_args, keep)
    wall_events = wall_loop(n, *wall_args)
    if stressed:
        stress_of(p, pairs, cell, cell.stress)
    if walls.force.shape[1] > 0 or on_grid:  # walls to add, or sums to judge on their grid
        out, last, quantity, unsummed = complete_sums(n, *sum_args, largest, keep)
        if unsummed > 0:  # fixed point without histories: the pair forces were not kept
            pair_events, largest = pairs_now(n, cell, particle_args, pair_args, True)
            out, last, quantity, unsummed = complete_sums(n, *sum_args, largest, True)
        fx.note_overflow(fixed, quantity, (out, last))
    if on_grid:
        out, last = damp_and_kick_on_grids(n, *end_args, fixed.v, fixed.omega, fixed.grid)
        quantity = fx.OF_VELOCITY if last % 2 else fx.OF_ANGULAR_VELOCITY
        fx.note_overflow(fixed, quantity, (out, last // 2))
    else:
        damp_and_kick(n, *end_args)
    servo_forces(cell, dyn.local_damping)
    note_destroyed(events, step, pairs, walls, pair_events, wall_events, law)


@jit
def note_normals(p, pairs, cell):
    """Fixed point with shear: `Pairs.normal` and `Pairs.overlap` found from the current
    positions, as the pair loop leaves them (the periodic images as `compute_forces` takes
    them), wherever the list or the state may have changed without a pair loop (a rebuild,
    a restart)."""
    if pairs.normal.shape[0] == 0:
        return
    args = (p.x, p.radius)
    listed = (pairs.i, pairs.j, pairs.count[0], pairs.normal, pairs.overlap)
    contact_normals(p.x.shape[0], *args, images(cell), *listed)
