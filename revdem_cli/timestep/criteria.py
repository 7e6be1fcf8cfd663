"""Critical time steps of two convex, centrally symmetric particles in one contact.

Peng, Burns & Hanley (2020), doi:10.1002/nme.6568. SI units; `inverse_mass` is the
paper's A_max (1/kg), `k` a contact stiffness (N/m), `c` a viscous damping coefficient
(N s/m). A criterion that does not apply (an overdamped contact for the criteria built on a
natural frequency) returns None.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from revdem_cli.timestep.shapes import Body


@dataclass(frozen=True)
class Contact:
    """Linear spring-dashpot contact F_j = -k_j x_j - c_j ẋ_j (Peng 2020 Eq 29)."""

    kn: float
    ks: float
    cn: float = 0.0
    cs: float = 0.0

    def directions(
        self, inverse_masses: tuple[float, float]
    ) -> tuple[tuple[float, float, float], ...]:
        """(stiffness, damping, inverse mass) of the normal and the shear direction, given the
        inverse masses of the two (`inverse_masses`); the normal alone for a frictionless
        contact (ks = 0), whose shear direction has no spring to bound Δt."""
        normal, shear = inverse_masses
        return ((self.kn, self.cn, normal),) + (
            ((self.ks, self.cs, shear),) if self.ks > 0.0 else ()
        )


def a_max(body1: Body, body2: Body) -> float:
    """Largest comprehensive inverse inertia coefficient of the contact, A_max (1/kg).

    The paper pairs the long half-length a, the lever arm of a tip-to-tip contact, with the
    smallest principal moment I_xx (assumption 3). A contact at r from the centre moves its
    point by |(I⁻¹ (r × F)) × r| ≤ |r|² |F| / I_xx, so the lever arm taken is the farthest
    point of the surface, `Body.reach`: a itself for an ellipsoid, but the corner of a
    box-like superquadric or a polyhedron, whose bound the long half-length understates
    (a cube: 3 half-edges² against 1, Δt 1.48 times too long) and which, unlike a
    half-length in a principal frame, no rotation of the body changes (a cube's frame is any
    frame). Pairing it with the smallest moment keeps the bound where assumption 3 fails.
    Two equal spheres give 7/m.
    """
    # Peng 2020 Eq 26, a the farthest point of the surface
    return sum(b.reach**2 / b.moments[0] + 1.0 / b.mass for b in (body1, body2))


def inverse_masses(body1: Body, body2: Body) -> tuple[float, float]:
    """Comprehensive inverse inertia coefficient of the normal and of the shear direction
    (1/kg). Two spheres: the normal force passes through both centres, r × n = 0, leaving
    A_n = 1/m₁ + 1/m₂ (2/m for equal spheres, against A_max = 7/m across). Other bodies: A_max
    in both, Peng's bound for a normal force off the centres (assumption 3)."""
    shear = a_max(body1, body2)
    if body1.shape == body2.shape == "sphere":
        return 1.0 / body1.mass + 1.0 / body2.mass, shear  # Peng 2020 Eq 26 with r × n = 0
    return shear, shear


def damping_from_number(number: float, kn: float, inverse_mass: float) -> float:
    """Damping coefficient c_n = c_s for the paper's dimensionless damping number N: exactly
    0 for N = 0, whatever k / A_max (whose root may leave float64 where k A_max does not)."""
    return number * math.sqrt(kn / inverse_mass) if number else 0.0  # Peng 2020 Section 6.2


def critical_damping(k: float, inverse_mass: float) -> float:
    """Damping coefficient that separates under- from overdamped contact."""
    return 2.0 * math.sqrt(k / inverse_mass)  # Peng 2020 Eq 37


def dt_amplification(k: float, c: float, inverse_mass: float) -> float:
    """Translation-dominant Δt from the real eigenvalue of the Euler amplification matrix."""
    ka, ca = k * inverse_mass, c * inverse_mass
    return (math.sqrt(4.0 * ka + ca**2) + ca) / ka  # Peng 2020 Eq 46 (c = 0: Eq 47, 48)


def dt_belytschko(k: float, c: float, inverse_mass: float) -> float | None:
    """Translation-dominant Δt = 2/ω from the damped natural frequency; underdamped only."""
    ka, ca = k * inverse_mass, c * inverse_mass
    discriminant = 4.0 * ka - ca**2
    if discriminant <= 0.0:
        return None
    return 4.0 / math.sqrt(discriminant)  # Peng 2020 Eq 34 (c = 0: Eq 35)


def dt_collision(kn: float, cn: float, mass: float) -> float | None:
    """Duration of a damped two-sphere collision (Silbert et al. 2001); underdamped only."""
    discriminant = 2.0 * kn / mass - cn**2 / (4.0 * mass**2)
    if discriminant <= 0.0:
        return None
    return math.pi / math.sqrt(discriminant)  # Peng 2020 Eq 36


def dt_velocity_verlet(k: float, c: float, inverse_mass: float) -> float:
    """Stability limit of velocity Verlet on Eq 30, damping force from the half-step velocity.

    The one-step map of (x, Δt·v_half) has trace 2 - kAΔt² - cAΔt and determinant 1 - cAΔt;
    both eigenvalues stay in the unit circle while kAΔt² + 2cAΔt < 4. This is the damped
    central-difference limit of Belytschko (1983), Δt = 2/ω (√(1 + ξ²) - ξ): Eq 46 with the
    sign of the damping term reversed. Undamped it equals Eq 47. Taken as the root of that
    quadratic without a difference, 4 / (√(4kA + c²A²) + cA): the printed form's difference
    loses its digits as cA outgrows √(kA) (8 % too large at ξ = 5e7, 0 at ξ = 1e8).
    """
    ka, ca = k * inverse_mass, c * inverse_mass
    return 4.0 / (math.sqrt(4.0 * ka + ca**2) + ca)  # Peng 2020 Eq 30 by velocity Verlet


def predictor_is_stable(k: float, c: float, inverse_mass: float, dt: float, order: int) -> bool:
    """Whether Eq 30, integrated by velocity Verlet whose damping force reads the velocity
    predictor of order `order` (Kolafa & Lisal 2011, kernels/predictor.py), keeps every mode
    bounded at dt.

    With the half-step velocities u_n and the prediction sum_j b_j u_{n-1-j}, the
    characteristic polynomial of x_n = z^n is
    (z - 1)^2 z^K + kA dt^2 z^(K+1) + cA dt (z - 1) sum_j b_j z^(K-j) = 0, K = order;
    order 0 (velocity Verlet) gives z^2 - (2 - kA dt^2 - cA dt) z + 1 - cA dt. Stable when
    every root lies in the unit circle (to 1e-12)."""
    import numpy as np

    from revdem_cli.kernels.predictor import coefficients

    ka, ca = k * inverse_mass * dt * dt, c * inverse_mass * dt
    polynomial = np.zeros(order + 3)  # highest power, z^(K+2), first
    polynomial[:3] += (1.0, -2.0, 1.0)  # (z - 1)^2 z^K
    polynomial[1] += ka  # kA dt^2 z^(K+1)
    for j, b in enumerate(coefficients(order)):  # cA dt b_j (z^(K+1-j) - z^(K-j))
        polynomial[1 + j] += ca * b
        polynomial[2 + j] -= ca * b
    return bool(np.abs(np.roots(polynomial)).max() <= 1.0 + 1e-12)


def bisected(
    is_stable: Callable[[float], bool], stable: float, unstable: float, rtol: float
) -> tuple[float, float]:
    """The bracket [stable, unstable] of a stability limit (is_stable at the one, not at the
    other) halved until it is narrower than `rtol` of its upper end."""
    while unstable - stable > rtol * unstable:
        middle = 0.5 * (stable + unstable)
        if is_stable(middle):
            stable = middle
        else:
            unstable = middle
    return stable, unstable


def dt_velocity_predictor(k: float, c: float, inverse_mass: float, order: int) -> float:
    """Stability limit of Eq 30 under velocity Verlet with the velocity predictor of order
    `order` (`predictor_is_stable`), found by bisection: the largest dt stable along with
    every dt below it, scanned from 0 in steps of 1/1000 of 2/omega. Order 0 is
    `dt_velocity_verlet`; undamped every order gives 2/omega."""
    omega = math.sqrt(k * inverse_mass)
    step = 2e-3 / omega

    def stable_at(dt: float) -> bool:
        return predictor_is_stable(k, c, inverse_mass, dt, order)

    stable = 0.0
    while stable_at(stable + step):
        stable += step
    return bisected(stable_at, stable, stable + step, 1e-12)[0]


def dt_damped(k: float, c: float, inverse_mass: float, order: int) -> float:
    """Stability limit of Eq 30 as the engine integrates it: velocity Verlet whose damping
    reads the half-step velocity (order 0, `dt_velocity_verlet`) or the velocity predictor
    of `order` (`integrator.scheme = "trvp"`, `dt_velocity_predictor`)."""
    if order and c > 0.0:
        return dt_velocity_predictor(k, c, inverse_mass, order)
    return dt_velocity_verlet(k, c, inverse_mass)


MOMENT_RTOL = 1e-12
"""Principal moments closer than this, relative to the largest, are equal. Each comes from
float64 sums (Gamma functions for a superquadric, a hull's tetrahedra and an eigensolver for a
polyhedron) good to some 1e-15 of the largest, so a sphere-like superquadric or a turned cube
differed by round-off and had Δt 2/(ω_max B_max) of 1e15 s instead of ∞; a real difference
this small would give over 1e12/ω_max s, which bounds nothing."""


def b_max(body: Body) -> float:
    """Largest gyroscopic coefficient of a particle's principal moments; 0 where they are
    equal (to MOMENT_RTOL)."""
    i1, i2, i3 = body.moments

    def difference(a: float, b: float) -> float:
        return 0.0 if abs(a - b) <= MOMENT_RTOL * i3 else abs(a - b)

    gaps = (difference(i1, i2) / i3, difference(i1, i3) / i2, difference(i2, i3) / i1)
    return max(gaps)  # Peng 2020 Eq 54


def dt_rotation(omega_max: float, b1: float, b2: float) -> float:
    """Rotation-dominant Δt for angular speeds up to omega_max (rad/s); ∞ for spheres.

    b1 = b2 = B_max, the largest of a mixed system, gives Eq 57: Δt = 1/(ω_max B_max).
    """
    gyroscopic = omega_max * (b1 + b2)
    return 2.0 / gyroscopic if gyroscopic > 0.0 else math.inf  # Peng 2020 Eq 56


def smallest(values) -> float | None:
    """Smallest of per-direction time steps; None if any direction has none."""
    values = list(values)
    return None if any(v is None for v in values) else min(values)


def sphere_normalised(beta: float) -> dict[str, float | None]:
    """Δt √(k/m) of two equal spheres (A_max = 7/m) against β = c/√(mk), with m = k = 1."""
    return {
        "belytschko": dt_belytschko(1.0, beta, 7.0),  # Peng 2020 Eq 58
        "collision": dt_collision(1.0, beta, 1.0),  # Peng 2020 Eq 59
        "amplification": dt_amplification(1.0, beta, 7.0),  # Peng 2020 Eq 60
        "velocity_verlet": dt_velocity_verlet(1.0, beta, 7.0),
    }
