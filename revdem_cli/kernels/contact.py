"""One contact, sphere-sphere or sphere-wall: its laws (`revdem_cli.laws`: the normal force
of Hanley 2020 Eq 6, the shear stiffness of Eq 10, a rolling spring and its limit) put
together with the tangential force with history (Eq 7-10) and its exact inverse, the Coulomb
limit, viscous damping, and the rolling moment with history, carried as the shear history
is and capped by its law as the shear force is by Coulomb's (§5.3).

Vectors are 3-tuples. Convention: n points from particle i to its partner j (or to the
wall); forces and moments are those on i (j takes the opposite rolling moment); the
tangential history is the elastic shear force on i, the rolling history the rolling
moment on i.
"""

import math

import numpy as np

from revdem_cli.kernels import inline
from revdem_cli.kernels.fixed import binade, snapped
from revdem_cli.kernels.vectors import axpy, cross, dot, scaled
from revdem_cli.laws import NONE, dispatch

NO_SHEAR = NONE  # ContactLaw.tangential of frictionless spheres
NO_ROLLING = NONE  # ContactLaw.rolling without rolling resistance

FORWARD = 0  # shear history advanced by the step (Eq 7-10)
REVERSE = 1  # shear history mapped back (the inverse of Eq 7-10)
STATIC = 2  # shear history used as it is: forces of a state that is not stepping
SETTLED = 3  # STATIC, the history neither capped nor rounded again: the forces of histories
# the information tape settled, as the forward step found them from those very histories

_normal_force = dispatch("normal", "force")
_shear_stiffness = dispatch("tangential", "stiffness")
_rolling_stiffness = dispatch("rolling", "stiffness")
_rolling_limit = dispatch("rolling", "limit")


@inline
def normal_law(law, overlap, rstar, estar):
    """(elastic normal force, its stiffness dF/dd, stored energy) of one contact in overlap,
    from its normal law."""
    return _normal_force(law.normal, law, overlap, rstar, estar)


@inline
def shear_stiffness(law, overlap, rstar, gstar):
    """k_s of one contact in overlap, from its tangential law."""
    return _shear_stiffness(law.tangential, law, overlap, rstar, gstar)


@inline
def rolling_stiffness(law, overlap, rstar):
    """k_r of one contact in overlap, from its rolling law."""
    return _rolling_stiffness(law.rolling, law, overlap, rstar)


@inline
def reduced(a, b):
    """a b / (a + b): the effective radius R* of two radii (Hanley 2020 Eq 6) or the reduced
    mass m* of two masses (the viscous damping's), scalars or arrays alike."""
    return a * b / (a + b)


@inline
def lever_arm(radius, overlap):
    """r - overlap / 2: the distance from a sphere's centre to the contact point, the length
    of its branch vector (Hanley 2020 Eq 5, 22), by which n x f is the contact's moment on
    it; scalars or arrays alike."""
    return radius - 0.5 * overlap


@inline
def viscous_coefficient(beta, mstar, stiffness):
    """c = 2 beta sqrt(m* k): the dashpot of a contact of stiffness k between bodies of
    reduced mass m*, damped at beta, the fraction of the critical 2 sqrt(k / A) of two bodies
    apart, A = 1/m* (Peng 2020 Eq 29, 37); scalars or arrays alike."""
    return 2.0 * beta * np.sqrt(mstar * stiffness)


SMALL_ANGLE = 1e-3
"""Below this (rad) cos and sin are their Taylor series to the 6th order, exact to well under
an ulp (the first term left out, a^6/720 or a^7/5040, is below 2e-21), and cheaper."""


@inline
def cos_sin(angle, small=False):
    """(cos angle, sin angle); even and odd in the angle exactly, so a rotation by -angle
    uses the same numbers as one by +angle. `small`: the angle is known to be below
    SMALL_ANGLE, and the branch to math.cos and math.sin is left out (in a vectorised loop
    it costs as much as the rest of the rotation, even where it is never taken)."""
    if not small and abs(angle) >= SMALL_ANGLE:
        return math.cos(angle), math.sin(angle)
    a2 = angle * angle  # the coefficients' reciprocals folded: no division in the series
    sine = angle * (1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0)))
    return 1.0 - a2 * (0.5 - a2 * (1.0 / 24.0)), sine


@inline
def rotate_about(b, n, angle, small=False):
    """Rotate b (in the plane normal to n) by `angle` about n: the spin correction R (Eq 9);
    `small`: |angle| < SMALL_ANGLE (see `cos_sin`)."""
    c, s = cos_sin(angle, small)
    return axpy(s, cross(n, b), scaled(c, b))


@inline
def remap(shear, n):
    """Project the old shear force onto the plane normal to n and restore its magnitude
    (Hanley 2020 Eq 7-8)."""
    size2 = dot(shear, shear)
    if size2 == 0.0:
        return (0.0, 0.0, 0.0)
    projected = axpy(-dot(n, shear), n, shear)  # Eq 7
    length2 = dot(projected, projected)
    if length2 == 0.0:
        return (0.0, 0.0, 0.0)
    return scaled(math.sqrt(size2 / length2), projected)  # Eq 8


@inline
def unmap(mapped, n_new, n_old):
    """Exact inverse of `remap`: the vector in the plane normal to n_old whose projection
    along n_new is parallel to `mapped`, with the magnitude of `mapped`; zero where there is
    none (`mapped` along n_new, as a history a few grid steps long can be)."""
    size2 = dot(mapped, mapped)
    if size2 == 0.0:
        return (0.0, 0.0, 0.0)
    lifted = axpy(-dot(n_old, mapped) / dot(n_old, n_new), n_new, mapped)
    length2 = dot(lifted, lifted)
    if length2 == 0.0:
        return (0.0, 0.0, 0.0)
    return scaled(math.sqrt(size2 / length2), lifted)


@inline
def coulomb_cap(shear, limit):
    """Limit |f_s| to mu |f_n| (Hanley 2020 §2); returns (force, amount removed)."""
    size2 = dot(shear, shear)
    if size2 <= limit * limit:
        return shear, 0.0
    size = math.sqrt(size2)
    return scaled(limit / size, shear), size - limit


@inline
def capped_away(law, carried):
    """Whether a shear force the Coulomb cap removed destroyed no information: with mu = 0
    the cap leaves no history, so one that carried none in is found again, zero, by the
    reversed step (its history unwound, capped the same way); what it removed was the
    step's increment, found from the positions and velocities alone."""
    return law.mu == 0.0 and dot(carried, carried) == 0.0


@inline
def relative_velocity(n, arm_i, arm_j, v_i, w_i, v_j, w_j):
    """Velocity of j relative to i at the contact point, branch vectors arm_i n and -arm_j n:
    (v_j + w_j x (-arm_j n)) - (v_i + w_i x arm_i n) = v_j - v_i - (arm_i w_i + arm_j w_j) x n."""
    return contact_velocity(n, arm_i, arm_j, axpy(-1.0, v_i, v_j), w_i, w_j)


@inline
def contact_velocity(n, arm_i, arm_j, v_ij, w_i, w_j):
    """`relative_velocity` from the centres' relative velocity v_ij = v_j - v_i."""
    spin = axpy(arm_i, w_i, scaled(arm_j, w_j))
    return axpy(-1.0, cross(spin, n), v_ij)


@inline
def turn_onto(history, a, b):
    """`history` turned by the rotation that takes the unit normal a onto b, about a x b
    (Rodrigues' formula with the axis's length sin(angle)): c h + (a x b) x h +
    (a x b)((a x b) . h) / (1 + c), c = a . b. Its inverse is the turn from b onto a, so a
    history carried across the contact plane's rotation this way keeps what rounding put
    across the plane, which the remap of Eq 7-8 projects out; the two agree to the square
    of the angle. Zero where a is (a contact apart before, whose history is zero)."""
    axis = cross(a, b)
    c = dot(a, b)
    return axpy(
        dot(axis, history) / (1.0 + c), axis, axpy(1.0, cross(axis, history), scaled(c, history))
    )


@inline
def spring_forward(history, n, n_then, spin, dt, k, rate, small=False, turned=False):
    """A spring with history, shear or rolling, one step on: remapped onto the new contact
    plane (Hanley 2020 Eq 7-8; `turned`: turned onto it from the normal `n_then` of the
    earlier positions, `turn_onto`), turned with the contact's spin (Eq 9), then k dt
    `rate` added (Eq 10: `rate` the tangential velocity, or angular velocity, of j relative
    to i). `small`: |spin dt| < SMALL_ANGLE (see `cos_sin`)."""
    carried = turn_onto(history, n_then, n) if turned else remap(history, n)  # Eq 7-8
    rotated = rotate_about(carried, n, spin * dt, small)  # Eq 9
    return axpy(k * dt, rate, rotated)  # Eq 10


@inline
def spring_unwound(history, n, spin, dt, k, rate, small=False):
    """`spring_forward` undone, but for its remap: the reversed step at the later positions
    undoes the increment of Eq 10 and the turn of Eq 9; `unmap` (or `turn_onto`) undoes Eq
    7-8 once the particles have moved back. `small`: as `spring_forward`'s."""
    return rotate_about(axpy(-k * dt, rate, history), n, -spin * dt, small)


@inline
def spring(mode, history, n, n_then, spin, dt, k, rate, small=False, turned=False):
    """A spring's new history: FORWARD `spring_forward` (`n_then`, the normal of the earlier
    positions, read where `turned`); REVERSE, `history` unwound across the normal `n_then`
    of the later positions (`spring_unwound`) and mapped onto this contact plane (`unmap`,
    the inverse of Eq 7-8, or where `turned` the turn back, `turn_onto`); STATIC and
    SETTLED, the history as is."""
    if mode == FORWARD:
        return spring_forward(history, n, n_then, spin, dt, k, rate, small, turned)
    if mode == REVERSE:
        return turn_onto(history, n_then, n) if turned else unmap(history, n_then, n)
    return history


@inline
def tangential(a, n):
    """The part of a in the plane normal to n."""
    return axpy(-dot(a, n), n, a)


@inline
def normal_force(law, overlap, rstar, mstar, estar, vrel, n):
    """(normal force magnitude, compression positive, with viscous damping; its elastic part)
    of one contact in overlap > 0, j moving at vrel relative to i (the velocity the damping
    reads)."""
    elastic, stiffness, _ = normal_law(law, overlap, rstar, estar)
    normal = elastic
    if law.beta_n > 0.0:
        normal -= viscous_coefficient(law.beta_n, mstar, stiffness) * dot(vrel, n)
    return normal, elastic


@inline
def history_step(law, scale):
    """The grid step of a history in fixed-point arithmetic (`fixed.HISTORY_BITS`): of the
    binade of `scale`, the contact's elastic normal force for its shear history, that times
    R* for its rolling one; 0 in floating point."""
    return law.history_grid * binade(scale)


@inline
def contact_force(
    law, mode, dt, overlap, n, rstar, mstar, estar, gstar, vrel, vdamp, spin, history, n_then,
    small=False, turned=False,
):  # fmt: skip
    """Force on i at one contact in overlap > 0, and the new shear history.

    FORWARD: remap the history onto the new contact plane (Eq 7-8; `turned`: turn it there
    from the normal `n_then` of the earlier positions, `turn_onto`), correct for spin (Eq
    9), add the increment -k_s dU_s with dU_s = -v_t dt, the displacement of i relative to
    j (Eq 10), cap at mu |f_n|. REVERSE: `history` is the shear force with Eq 10 and 9
    undone across the contact normal `n_then` of the later positions (`unwind_shear`);
    mapping it onto this contact plane (`unmap`, or turning it back) inverts Eq 7-8; it is
    capped the same way. STATIC:
    the history as is, capped (and rounded) again; SETTLED: the history as is, neither.
    Returns (force on i, history, amount the Coulomb cap removed, normal force magnitude,
    which `rolling_moment` limits by, and its elastic part). `small`: |spin dt| <
    SMALL_ANGLE (see `cos_sin`). The shear increment reads the relative velocity
    `vrel`, the viscous damping `vdamp` (the same, or from the velocity predictor's
    velocities). In fixed-point arithmetic the history is rounded onto its grid
    (`fixed.HISTORY_BITS`, from the binade of the elastic normal force, which the positions
    alone give) before the force is taken from it: the reversed step, undoing the step in
    floating point, rounds back onto the history it started from unless the remap or turn
    carries its round-off across half a grid step.
    """
    normal, elastic = normal_force(law, overlap, rstar, mstar, estar, vdamp, n)
    force = scaled(-normal, n)
    if law.tangential == NO_SHEAR:
        return force, history, 0.0, normal, elastic
    vt = tangential(vrel, n)
    ks = shear_stiffness(law, overlap, rstar, gstar)
    shear = spring(mode, history, n, n_then, spin, dt, ks, vt, small, turned)
    slip = 0.0
    if mode != SETTLED:
        shear, slip = coulomb_cap(shear, law.mu * max(normal, 0.0))
        if law.history_grid != 0.0:  # fixed point (a constant in a build for floating point)
            shear = snapped(shear, history_step(law, elastic))
    if law.beta_t > 0.0:
        damped = tangential(vdamp, n)
        shear_total = axpy(viscous_coefficient(law.beta_t, mstar, ks), damped, shear)
        return axpy(1.0, shear_total, force), shear, slip, normal, elastic
    return axpy(1.0, shear, force), shear, slip, normal, elastic


@inline
def rolling_moment(
    law, mode, dt, overlap, n, rstar, normal, elastic, w_i, w_j, spin, history, n_then,
    small=False, turned=False,
):  # fmt: skip
    """Rolling resistance moment on i at one contact in overlap > 0 whose normal force is
    `normal` and its elastic part `elastic` (`contact_force`'s), and its new history:
    the rolling spring of the contact's rolling law, wound by the rotation of j relative to
    i in the contact plane, (w_j - w_i)_t dt, and carried across steps as the shear history
    is (`spring`), then capped at the law's limit (Hanley 2020 §5.3: a limit destroys
    information as the Coulomb cap does) and, in fixed-point arithmetic, rounded onto its grid
    as the shear history is, from the binade of the elastic normal force times R*. Returns
    (the moment on i, which is the new history, and the amount the cap removed); j takes the
    opposite moment."""
    kr = rolling_stiffness(law, overlap, rstar)
    rate = tangential(axpy(-1.0, w_i, w_j), n)
    moment = spring(mode, history, n, n_then, spin, dt, kr, rate, small, turned)
    if mode == SETTLED:
        return moment, 0.0
    moment, capped = coulomb_cap(moment, _rolling_limit(law.rolling, law, normal, rstar))
    if law.history_grid != 0.0:
        moment = snapped(moment, history_step(law, elastic * rstar))
    return moment, capped


@inline
def contact_energy(law, overlap, rstar, estar, gstar, shear, rolling):
    """Elastic energy stored in a contact in overlap > 0: normal (the law's, `normal_law`),
    shear |f_s|^2 / 2 k_s and rolling |M_r|^2 / 2 k_r (`rolling`, the rolling moment; ignored
    without a rolling law), the energy of a linear spring at its present stiffness (Hanley
    2020 Eq 10 and §5.3's springs). Exact for a constant k_s; with Mindlin's, which stiffens
    with the overlap, an estimate: the spring was loaded at other stiffnesses."""
    energy = normal_law(law, overlap, rstar, estar)[2]
    if law.tangential == NO_SHEAR:
        return energy
    energy += 0.5 * dot(shear, shear) / shear_stiffness(law, overlap, rstar, gstar)
    if law.rolling == NO_ROLLING:
        return energy
    return energy + 0.5 * dot(rolling, rolling) / rolling_stiffness(law, overlap, rstar)


@inline
def unwind_shear(law, dt, overlap, n, rstar, gstar, vrel, spin, history, small=False):
    """Reversed step, at the later positions: undo Eq 10 and Eq 9 of the shear history.
    `small`: |spin dt| < SMALL_ANGLE (see `cos_sin`)."""
    if overlap <= 0.0:
        return (0.0, 0.0, 0.0)
    ks = shear_stiffness(law, overlap, rstar, gstar)
    return spring_unwound(history, n, spin, dt, ks, tangential(vrel, n), small)


@inline
def unwind_rolling(law, dt, overlap, n, rstar, w_i, w_j, spin, history):
    """Reversed step, at the later positions: undo the rolling spring's increment and turn."""
    if overlap <= 0.0:
        return (0.0, 0.0, 0.0)
    kr = rolling_stiffness(law, overlap, rstar)
    return spring_unwound(history, n, spin, dt, kr, tangential(axpy(-1.0, w_i, w_j), n))


@inline
def earlier_shear(law, dt, overlap, n, rstar, estar, gstar, vrel, spin, shear, overlap_then,
                  n_then, small=False):  # fmt: skip
    """The shear history the reversed step finds at the earlier positions of a forward step
    just taken, from the new history `shear` at the later ones (overlap, normal n, relative
    velocity vrel, spin) and the overlap and normal the pair had at the earlier ones
    (`overlap_then`, `n_then`): unwound at the later positions (`unwind_shear`), turned
    back, capped and rounded at the earlier ones as `contact_force` does reversed (fixed
    point, no viscous damping); zero where the pair was apart at either. Returns (that
    history, the grid step of the pair's history at the earlier positions: 0 apart)."""
    if overlap_then <= 0.0:
        return (0.0, 0.0, 0.0), 0.0
    normal, elastic = normal_force(law, overlap_then, rstar, 0.0, estar, (0.0, 0.0, 0.0), n_then)
    spacing = history_step(law, elastic)
    if overlap <= 0.0:  # apart now: nothing to unwind
        return (0.0, 0.0, 0.0), spacing
    unwound = unwind_shear(law, dt, overlap, n, rstar, gstar, vrel, spin, shear, small)
    back = turn_onto(unwound, n, n_then)
    back = coulomb_cap(back, law.mu * max(normal, 0.0))[0]
    return snapped(back, spacing), spacing
