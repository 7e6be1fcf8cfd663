"""The linearised stiffness of each contact of a state, from its laws: what
`revdem_cli.timestep.packing` assembles into the stiffness matrix of a whole packing."""

from revdem_cli.kernels import inline, jit
from revdem_cli.kernels.contact import (
    NO_ROLLING,
    NO_SHEAR,
    normal_law,
    rolling_stiffness,
    shear_stiffness,
)
from revdem_cli.kernels.vectors import axpy, cross, dot, row, scaled


@jit
def contact_stiffnesses(law, overlap, rstar, estar, gstar, kn, ks, kr):
    """Fill kn, ks and kr of each contact in overlap > 0: the normal law's tangent stiffness
    dF/dd (Hanley 2020 Eq 6), k_s of the tangential law (Eq 10; 0 without one) and k_r of
    the rolling law (0 without one)."""
    for c in range(overlap.shape[0]):
        kn[c] = normal_law(law, overlap[c], rstar[c], estar[c])[1]
        ks[c] = 0.0
        if law.tangential != NO_SHEAR:
            ks[c] = shear_stiffness(law, overlap[c], rstar[c], gstar[c])
        kr[c] = 0.0
        if law.rolling != NO_ROLLING:
            kr[c] = rolling_stiffness(law, overlap[c], rstar[c])


@inline
def _add(a, k, s, vector):
    """a[k] += s vector."""
    a[k, 0] += s * vector[0]
    a[k, 1] += s * vector[1]
    a[k, 2] += s * vector[2]


@jit
def apply_stiffness(a, b, n, arm_a, arm_b, normal, shear, rolling, u, theta, out_u, out_theta):
    """out = K q for displacements u and rotations theta, (N + 1, 3) each, row N a wall that
    does not move: at each contact, in order, Δ = u_b - u_a - (l_a θ_a + l_b θ_b) × n, the
    force g = [k_n nnᵀ + k_s (I - nnᵀ)] Δ on b and -g on a, their moments l (g × n) on both,
    and the rolling moment k_r P_t (θ_b - θ_a) on b and its opposite on a (the Hessian of
    the contact energy of `timestep.packing`)."""
    out_u[:] = 0.0
    out_theta[:] = 0.0
    for c in range(a.shape[0]):
        i, j, nc = a[c], b[c], row(n, c)
        ta, tb = row(theta, i), row(theta, j)
        spin = axpy(arm_a[c], ta, scaled(arm_b[c], tb))
        delta = axpy(-1.0, cross(spin, nc), axpy(-1.0, row(u, i), row(u, j)))
        g = axpy((normal[c] - shear[c]) * dot(delta, nc), nc, scaled(shear[c], delta))
        lever = cross(g, nc)
        _add(out_u, j, 1.0, g)
        _add(out_u, i, -1.0, g)
        _add(out_theta, i, arm_a[c], lever)
        _add(out_theta, j, arm_b[c], lever)
        if rolling[c] != 0.0:
            turn = axpy(-1.0, ta, tb)
            moment = scaled(rolling[c], axpy(-dot(turn, nc), nc, turn))
            _add(out_theta, j, 1.0, moment)
            _add(out_theta, i, -1.0, moment)
