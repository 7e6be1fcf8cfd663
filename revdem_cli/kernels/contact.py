"""One contact, sphere-sphere or sphere-wall: its laws (`revdem_cli.laws`: the normal force
of Hanley 2020 Eq 6, the shear stiffness of Eq 10) put together with the tangential force
with history (Eq 7-10) and its exact inverse, the Coulomb limit and viscous damping.

Vectors are 3-tuples. Convention: n points from particle i to its partner j (or to the
wall); forces are those on i; the tangential history is the elastic shear force on i.
"""

import math

from revdem_cli.kernels import inline
from revdem_cli.kernels.vectors import axpy, cross, dot, scaled
from revdem_cli.laws import NONE, dispatch

NO_SHEAR = NONE  # ContactLaw.tangential of frictionless spheres

FORWARD = 0  # shear history advanced by the step (Eq 7-10)
REVERSE = 1  # shear history mapped back (the inverse of Eq 7-10)
STATIC = 2  # shear history used as it is: forces of a state that is not stepping

_normal_force = dispatch("normal", "force")
_shear_stiffness = dispatch("tangential", "stiffness")


@inline
def normal_law(law, overlap, rstar, estar):
    """(elastic normal force, its stiffness dF/dd, stored energy) of one contact in overlap,
    from its normal law."""
    return _normal_force(law.normal, law, overlap, rstar, estar)


@inline
def shear_stiffness(law, overlap, rstar, gstar):
    """k_s of one contact in overlap, from its tangential law."""
    return _shear_stiffness(law.tangential, law, overlap, rstar, gstar)


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
    a2 = angle * angle
    return 1.0 - a2 * (0.5 - a2 * (1.0 / 24.0)), angle * (1.0 - a2 * (1.0 / 6.0 - a2 / 120.0))


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
    along n_new is parallel to `mapped`, with the magnitude of `mapped`."""
    size2 = dot(mapped, mapped)
    if size2 == 0.0:
        return (0.0, 0.0, 0.0)
    lifted = axpy(-dot(n_old, mapped) / dot(n_old, n_new), n_new, mapped)
    return scaled(math.sqrt(size2 / dot(lifted, lifted)), lifted)


@inline
def coulomb_cap(shear, limit):
    """Limit |f_s| to mu |f_n| (Hanley 2020 §2); returns (force, amount removed)."""
    size2 = dot(shear, shear)
    if size2 <= limit * limit:
        return shear, 0.0
    size = math.sqrt(size2)
    return scaled(limit / size, shear), size - limit


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
def contact_force(
    law, mode, dt, overlap, n, rstar, mstar, estar, gstar, vrel, spin, history, n_new, small=False
):
    """Force on i at one contact in overlap > 0, and the new shear history.

    FORWARD: remap the history onto the new contact plane (Eq 7-8), correct for spin (Eq 9),
    add the increment -k_s dU_s with dU_s = -v_t dt, the displacement of i relative to j
    (Eq 10), cap at mu |f_n|. REVERSE: `history` is the shear force with Eq 10 and 9 undone
    across the contact normal `n_new` of the later positions (`unwind_shear`); mapping it
    onto this contact plane (`unmap`) inverts Eq 7-8; it is capped the same way. STATIC:
    the history as is. Returns (force on i, history, amount the Coulomb cap removed).
    `small`: |spin dt| < SMALL_ANGLE (see `cos_sin`).
    """
    elastic, stiffness, _ = normal_law(law, overlap, rstar, estar)
    vn = dot(vrel, n)
    normal = elastic
    if law.beta_n > 0.0:
        normal -= 2.0 * law.beta_n * math.sqrt(mstar * stiffness) * vn  # viscous, normal
    force = scaled(-normal, n)
    if law.tangential == NO_SHEAR:
        return force, history, 0.0
    vt = axpy(-vn, n, vrel)
    ks = shear_stiffness(law, overlap, rstar, gstar)
    if mode == FORWARD:
        rotated = rotate_about(remap(history, n), n, spin * dt, small)  # Eq 7-9
        shear = axpy(ks * dt, vt, rotated)  # Eq 10
    elif mode == REVERSE:
        shear = unmap(history, n_new, n)
    else:
        shear = history
    shear, slip = coulomb_cap(shear, law.mu * max(normal, 0.0))
    if law.beta_t > 0.0:
        shear_total = axpy(2.0 * law.beta_t * math.sqrt(mstar * ks), vt, shear)  # viscous
        return axpy(1.0, shear_total, force), shear, slip
    return axpy(1.0, shear, force), shear, slip


@inline
def contact_energy(law, overlap, rstar, estar, gstar, shear):
    """Elastic energy stored in a contact in overlap > 0: normal spring and shear spring."""
    energy = normal_law(law, overlap, rstar, estar)[2]
    if law.tangential == NO_SHEAR:
        return energy
    return energy + 0.5 * dot(shear, shear) / shear_stiffness(law, overlap, rstar, gstar)


@inline
def unwind_shear(law, dt, overlap, n, rstar, gstar, vrel, spin, history):
    """Reversed step, at the later positions: undo Eq 10 and Eq 9. The result is mapped back
    onto the earlier contact plane by `unmap` once the particles have moved back."""
    if overlap <= 0.0:
        return (0.0, 0.0, 0.0)
    vt = axpy(-dot(vrel, n), n, vrel)
    ks = shear_stiffness(law, overlap, rstar, gstar)
    return rotate_about(axpy(-ks * dt, vt, history), n, -spin * dt)
