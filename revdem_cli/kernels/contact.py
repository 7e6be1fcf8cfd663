"""One contact, sphere-sphere or sphere-wall: normal law (Hanley 2020 Eq 6), tangential
force with history (Eq 7-10) and its exact inverse, Coulomb limit, viscous damping.

Vectors are 3-tuples. Convention: n points from particle i to its partner j (or to the
wall); forces are those on i; the tangential history is the elastic shear force on i.
"""

import math

from revdem_cli.kernels import jit

HERTZ = 0
LINEAR = 1

NO_SHEAR = 0
LINEAR_SHEAR = 1
MINDLIN = 2

FORWARD = 0  # shear history advanced by the step (Eq 7-10)
REVERSE = 1  # shear history mapped back (the inverse of Eq 7-10)
STATIC = 2  # shear history used as it is: forces of a state that is not stepping

NO_EVENT = 0
CONTACT_LOST = 1
COULOMB_SLIP = 2


@jit
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jit
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@jit
def axpy(s, a, b):
    """s a + b."""
    return (s * a[0] + b[0], s * a[1] + b[1], s * a[2] + b[2])


@jit
def scaled(s, a):
    return (s * a[0], s * a[1], s * a[2])


@jit
def norm(a):
    return math.sqrt(dot(a, a))


@jit
def normal_law(law, overlap, rstar, estar):
    """(elastic normal force, its stiffness dF/dd, stored energy) of one contact."""
    if law.model == LINEAR:
        force = law.kn * overlap  # Hanley 2020 Eq 6, linear
        return force, law.kn, 0.5 * force * overlap
    # Hanley 2020 Eq 6, Hertz: F = H d^1.5 with H = 4/3 E* sqrt(R*) (= 4G/(3(1-nu)) sqrt(R*))
    h = 4.0 / 3.0 * estar * math.sqrt(rstar)
    root = math.sqrt(overlap)
    force = h * overlap * root
    return force, 1.5 * h * root, 0.4 * force * overlap  # U = 2/5 H d^2.5


@jit
def shear_stiffness(law, overlap, rstar, gstar):
    """k_s: constant, or Mindlin H^s = H^n sqrt(U^n) 3(1-nu)/(2-nu) = 8 G* sqrt(R* d) (Eq 10)."""
    if law.tangential == LINEAR_SHEAR:
        return law.ks
    return 8.0 * gstar * math.sqrt(rstar * overlap)


@jit
def rotate_about(b, n, angle):
    """Rotate b (in the plane normal to n) by `angle` about n: the spin correction R (Eq 9)."""
    c = math.cos(angle)
    s = math.sin(angle)
    return axpy(s, cross(n, b), scaled(c, b))


@jit
def remap(shear, n):
    """Project the old shear force onto the plane normal to n and restore its magnitude
    (Hanley 2020 Eq 7-8)."""
    size = norm(shear)
    if size == 0.0:
        return (0.0, 0.0, 0.0)
    projected = axpy(-dot(n, shear), n, shear)  # Eq 7
    length = norm(projected)
    if length == 0.0:
        return (0.0, 0.0, 0.0)
    return scaled(size / length, projected)  # Eq 8


@jit
def unmap(mapped, n_new, n_old):
    """Exact inverse of `remap`: the vector in the plane normal to n_old whose projection
    along n_new is parallel to `mapped`, with the magnitude of `mapped`."""
    size = norm(mapped)
    if size == 0.0:
        return (0.0, 0.0, 0.0)
    lifted = axpy(-dot(n_old, mapped) / dot(n_old, n_new), n_new, mapped)
    return scaled(size / norm(lifted), lifted)


@jit
def coulomb_cap(shear, limit):
    """Limit |f_s| to mu |f_n| (Hanley 2020 §2); returns (force, amount removed)."""
    size = norm(shear)
    if size <= limit:
        return shear, 0.0
    return scaled(limit / size, shear), size - limit


@jit
def relative_velocity(n, arm_i, arm_j, v_i, w_i, v_j, w_j):
    """Velocity of j relative to i at the contact point; branch vectors arm_i n and -arm_j n."""
    at_i = axpy(1.0, cross(w_i, scaled(arm_i, n)), v_i)
    at_j = axpy(1.0, cross(w_j, scaled(-arm_j, n)), v_j)
    return axpy(-1.0, at_i, at_j)


@jit
def contact_force(
    law, mode, dt, overlap, n, rstar, mstar, moduli, vrel, spin, history, pending, normal_new
):
    """Force on i at one contact in overlap > 0, and the new shear history.

    FORWARD: remap the history onto the new contact plane (Eq 7-8), correct for spin (Eq 9),
    add the increment -k_s dU_s with dU_s = -v_t dt, the displacement of i relative to j
    (Eq 10), cap at mu |f_n|. REVERSE: the history is the exact inverse of those steps,
    `unmap(pending)` (see `unwind_shear`), capped the same way. STATIC: the history as is.
    Returns (force on i, normal force, stored energy, slip amount, history).
    """
    elastic, stiffness, energy = normal_law(law, overlap, rstar, moduli[0])
    vn = dot(vrel, n)
    normal = elastic - 2.0 * law.beta_n * math.sqrt(mstar * stiffness) * vn  # viscous, normal
    force = scaled(-normal, n)
    if law.tangential == NO_SHEAR:
        return force, normal, energy, 0.0, history
    vt = axpy(-vn, n, vrel)
    ks = shear_stiffness(law, overlap, rstar, moduli[1])
    if mode == FORWARD:
        rotated = rotate_about(remap(history, n), n, spin * dt)  # Eq 7-9
        shear = axpy(ks * dt, vt, rotated)  # Eq 10
    elif mode == REVERSE:
        shear = unmap(pending, normal_new, n)
    else:
        shear = history
    shear, slip = coulomb_cap(shear, law.mu * max(normal, 0.0))
    energy += 0.5 * dot(shear, shear) / ks
    damping = 2.0 * law.beta_t * math.sqrt(mstar * ks)  # viscous, tangential
    return axpy(1.0, axpy(damping, vt, shear), force), normal, energy, slip, shear


@jit
def unwind_shear(law, dt, overlap, n, rstar, gstar, vrel, spin, history):
    """Reversed step, at the later positions: undo Eq 10 and Eq 9. The result is mapped back
    onto the earlier contact plane by `unmap` once the particles have moved back."""
    if overlap <= 0.0:
        return (0.0, 0.0, 0.0)
    vt = axpy(-dot(vrel, n), n, vrel)
    ks = shear_stiffness(law, overlap, rstar, gstar)
    return rotate_about(axpy(-ks * dt, vt, history), n, -spin * dt)
