"""The periodic cell: an orthorhombic box [0, L) repeated in x, y and z, whose edges may move.

Each edge is fixed, moves at a prescribed strain rate, or holds a stress with a servo. In
a deforming cell the particles are carried affinely: their state is the cell coordinate
s = x / L, drifted with their own velocity (relative to the cell's affine motion) and mapped
back with the new edge lengths, x = s L. Across a contact the cell's affine motion adds
(dL/dt / L) d to the relative velocity of two particles d apart.

Servos, for an axis a holding the stress target s*_a:
- PROPORTIONAL (Hanley 2020 §3.2.3): dL_a/dt = gain (sigma_aa - s*_a) / s*_a L_a, from the
  stress at the start of the step. A reversed step moves the edge back with the rate its
  state holds, the exact inverse of the forward step that moved with it, and then takes the
  rate for the next one from the stress there, steering it towards its target (the exact
  time reverse of a relaxation diverges; `steer_back`): the reversed run follows the
  forward one only as closely as the servo tracks its target, closer the larger the gain
  (the paper's observation).
- INERTIAL: the edge is a degree of freedom of mass M driven by (sigma_aa - s*_a) A_a, A_a the
  area of the face normal to a (Andersen's barostat, J. Chem. Phys. 72, 2384 (1980), per
  axis, as Parrinello and Rahman's; the stress of Hanley 2020 Eq 23), integrated with the
  particles' velocity-Verlet half steps; its reversed step is the exact inverse of its
  forward step.
"""

import numpy as np

from revdem_cli.kernels import inline, jit
from revdem_cli.kernels.fixed import EDGE, EDGE_RATE, OF_CELL, moved_on_grid, note_overflow
from revdem_cli.kernels.gather import locally_damped

FIXED = 0
STRAIN_RATE = 1
STRESS = 2

PROPORTIONAL = 0
INERTIAL = 1


@jit
def edge_on_grid(fixed, n, increment, step):
    """n + round(increment / step): an edge or its rate on its grid; a value that would
    leave the grid stays, and is counted as an overflow of the cell."""
    moved, ok = moved_on_grid(n, increment / step)
    if not ok:
        note_overflow(fixed, OF_CELL, (1, -1))
    return moved


@jit
def images(cell):
    """The cell's edges and their inverses as a 6-tuple for `nearest_image`, the inverse 0
    on an axis that is not periodic."""
    inv = (
        1.0 / cell.length[0] if cell.periodic[0] else 0.0,
        1.0 / cell.length[1] if cell.periodic[1] else 0.0,
        1.0 / cell.length[2] if cell.periodic[2] else 0.0,
    )
    return (cell.length[0], cell.length[1], cell.length[2], inv[0], inv[1], inv[2])


@inline
def nearest_image(d, image):
    """The separation d (3-tuple) mapped to its nearest periodic image; `image` from
    `images`. (On an axis that is not periodic the inverse is 0 and d is returned unchanged,
    bit for bit: d - L floor(0.5) = d - 0.)"""
    return (  # np.floor stays a float (math.floor would round-trip through an integer)
        d[0] - image[0] * np.floor(d[0] * image[3] + 0.5),
        d[1] - image[1] * np.floor(d[1] * image[4] + 0.5),
        d[2] - image[2] * np.floor(d[2] * image[5] + 0.5),
    )


@inline
def strain_rates(rate, length):
    """(dL/dt / L) of each edge, a 3-tuple: what `affine_velocity` takes."""
    return (rate[0] / length[0], rate[1] / length[1], rate[2] / length[2])


@inline
def affine_velocity(d, strain):
    """Velocity of the cell's affine motion across a separation d: (dL/dt / L) d, with the
    strain rates of `strain_rates` (a tuple, not the arrays: a compiled call per pair that
    receives arrays pays an atomic reference-count update for each)."""
    return (strain[0] * d[0], strain[1] * d[1], strain[2] * d[2])


@jit
def deforms(cell):
    """Whether any edge of the cell moves in this run."""
    for a in range(3):
        if cell.control[a] != FIXED:
            return True
    return False


@jit
def holds_stress(cell):
    """Whether a servo holds the stress on some edge in this stage."""
    for a in range(3):
        if cell.control[a] == STRESS:
            return True
    return False


@jit
def volume(cell):
    return cell.length[0] * cell.length[1] * cell.length[2]


@jit
def servo_forces(cell, local_damping):
    """Inertial servo: the force on each stress-controlled edge at the current step,
    (sigma_aa - s*_a) A_a, less local damping (Hanley 2020 Eq 21) as on a particle."""
    if cell.servo != INERTIAL:
        return
    for a in range(3):
        if cell.control[a] == STRESS:
            force = (cell.stress[a, a] - cell.target[a]) * volume(cell) / cell.length[a]
            cell.force[a] = locally_damped(force, cell.rate[a], local_damping)


@jit
def kick_cell(cell, fixed, h):
    """Inertial servo: dL/dt += h F / M, h = +-dt/2, as the particles' half kicks; on its
    grid in fixed-point arithmetic."""
    if cell.servo != INERTIAL:
        return
    on_grid = fixed.v.shape[0] > 0
    step = fixed.grid[EDGE_RATE] if on_grid else 0.0
    for a in range(3):
        if cell.control[a] == STRESS:
            if on_grid:
                kick = h * cell.force[a] / cell.mass
                fixed.rate[a] = edge_on_grid(fixed, fixed.rate[a], kick, step)
                cell.rate[a] = fixed.rate[a] * step
            else:
                cell.rate[a] += h * cell.force[a] / cell.mass


@inline
def proportional_rate(cell, a, gain):
    """dL_a/dt = gain (sigma_aa - s*_a) / s*_a L_a (Hanley 2020 §3.2.3), from the stress now."""
    error = (cell.stress[a, a] - cell.target[a]) / cell.target[a]
    return gain * error * cell.length[a]


@jit
def steer_back(cell):
    """Proportional servo, reversed: the rate the next reversed step moves an edge back with,
    dL/dt of forward time, which the forward step before took from a stress the reversal has
    not reached yet. It takes the one that steers the stress towards its target in reversed
    time, -gain (sigma - s*) / s* L from the stress now (the exact time reverse of a
    relaxation diverges): the reversed run follows the forward one only as closely as the
    servo tracks its target, closer the larger the gain (the paper's observation), and the
    information tape records the difference (`tape`, the cell's rate)."""
    if cell.servo != PROPORTIONAL:
        return
    for a in range(3):
        if cell.control[a] == STRESS:
            cell.rate[a] = proportional_rate(cell, a, -cell.gain)


@jit
def move_cell(cell, fixed, dt, elapsed):
    """The edges after a step of dt (< 0 reversed), `elapsed` seconds into the stage at its
    end; cell.mid gets the edges at the middle of the step, the ones a drift divides by.

    Strain-rate edges: L = L_start + rate elapsed, a function of the step as walls are.
    Proportional servo: forward, the rate from the stress now, then L += dt rate; reversed,
    L += dt rate with the rate the cell holds, the forward step's (`steer_back` the rest of
    the way). Inertial: L += dt rate.
    In fixed-point arithmetic every edge lies on its grid, whatever moves it: the integer
    state then holds the whole cell, and a stage that starts (`stage.set_cell_motion`, which
    puts the edges on their grid) starts from the edges the last one ended with, bit for bit.
    """
    on_grid = fixed.v.shape[0] > 0
    step = fixed.grid[EDGE] if on_grid else 0.0
    for a in range(3):
        before = cell.length[a]
        if cell.control[a] == STRAIN_RATE:
            length = cell.start[a] + cell.rate[a] * elapsed
            if on_grid:
                fixed.length[a] = edge_on_grid(fixed, np.int64(0), length, step)
                length = fixed.length[a] * step
            cell.length[a] = length
        elif cell.control[a] == STRESS:
            if cell.servo == PROPORTIONAL and dt > 0.0:  # reversed: the rate it moved with
                cell.rate[a] = proportional_rate(cell, a, cell.gain)
            if on_grid:
                fixed.length[a] = edge_on_grid(fixed, fixed.length[a], dt * cell.rate[a], step)
                cell.length[a] = fixed.length[a] * step
            else:
                cell.length[a] = before + dt * cell.rate[a]
        cell.mid[a] = 0.5 * (before + cell.length[a])
