"""Largest stable time steps found from the integrator itself, to judge the formulas.

A `Verifier` takes two bodies and a contact and returns the largest Δt at which an
integrator keeps that contact bounded. The velocity-Verlet verifier integrates the linear
contact equation (Peng 2020 Eq 30) with the same half kick, drift, new force, half kick as
the engine; `engine_pair.engine_limit` runs the engine itself on a sphere contact.
The Eq 40 functions examine the scheme the paper analyses, through its eigenvalues.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from revdem_cli.timestep.criteria import Contact, bisected, inverse_masses
from revdem_cli.timestep.engine_pair import engine_limit
from revdem_cli.timestep.shapes import Body

Verifier = Callable[[Body, Body, Contact], float | None]
"""Largest stable Δt of a pair in s; None where the verifier does not apply to the pair."""

STEPS = 20_000  # steps integrated per trial Δt
GROWTH = 2.0  # late/early amplitude ratio that counts as unstable
BLOW_UP = 1e6  # |x| (from x = 1) at which a trial stops early as unstable
BISECTION_RTOL = 1e-6
MAX_HALVINGS = 10  # below guess / 1024 a limit is reported as 0.0: never stable
EIGENVALUE_TOL = 1e-12


def _velocity_verlet_peak(state, steps, k, c, inverse_mass, dt):
    """Integrate Eq 30 for `steps` steps; the largest |x| met (stops past BLOW_UP) and the state.

    Half kick v += Δt/2·a, drift x += Δt·v, new acceleration from the new position and the
    half-step velocity, half kick: the engine's update.
    """
    x, v, accel = state
    peak = 0.0
    for _ in range(steps):
        v_half = v + 0.5 * dt * accel
        x += dt * v_half
        accel = -inverse_mass * (k * x + c * v_half)  # Peng 2020 Eq 30
        v = v_half + 0.5 * dt * accel
        size = abs(x)
        if size > peak:
            peak = size
            if size > BLOW_UP:
                break
    return peak, (x, v, accel)


def velocity_verlet_is_stable(k: float, c: float, inverse_mass: float, dt: float) -> bool:
    """Whether velocity Verlet keeps Eq 30 bounded, released from rest at x = 1.

    Unstable if the peak |x| over the second half of STEPS steps exceeds GROWTH times the
    peak over the first half.
    """
    start = (1.0, 0.0, -k * inverse_mass)
    early, state = _velocity_verlet_peak(start, STEPS // 2, k, c, inverse_mass, dt)
    if early > BLOW_UP:
        return False
    late, _ = _velocity_verlet_peak(state, STEPS // 2, k, c, inverse_mass, dt)
    return late <= GROWTH * early


def eq40_matrix(k: float, c: float, inverse_mass: float, dt: float) -> np.ndarray:
    """Amplification matrix of (x, ẋ, ẍ) for the paper's Euler scheme."""
    stiffness, damping = -k * inverse_mass, -c * inverse_mass
    return np.array([[1.0, dt, 0.0], [0.0, 1.0, dt], [stiffness, damping, 0.0]])  # Peng 2020 Eq 40


def eq40_is_stable(k: float, c: float, inverse_mass: float, dt: float) -> bool:
    """Whether every eigenvalue of the Eq 40 matrix lies in the closed unit circle."""
    eigenvalues = np.linalg.eigvals(eq40_matrix(k, c, inverse_mass, dt))
    return bool(np.abs(eigenvalues).max() <= 1.0 + EIGENVALUE_TOL)


def eq40_real_eigenvalues_above_minus_one(k: float, c: float, inverse_mass: float, dt: float):
    """Whether the real eigenvalues of the Eq 40 matrix are ≥ -1 (the paper's Eq 44 test)."""
    eigenvalues = np.linalg.eigvals(eq40_matrix(k, c, inverse_mass, dt))
    real = eigenvalues.real[np.abs(eigenvalues.imag) <= EIGENVALUE_TOL * np.abs(eigenvalues)]
    return bool(real.min(initial=0.0) >= -1.0 - EIGENVALUE_TOL)


def largest_stable_dt(
    is_stable: Callable[[float], bool], guess: float, rtol: float = BISECTION_RTOL
) -> float:
    """Largest Δt with is_stable(Δt), where the stable Δt form an interval from 0.

    Brackets the limit by doubling or halving from `guess`, then bisects to a relative
    width `rtol`. Returns 0.0 when not stable even at guess / 2**MAX_HALVINGS.
    """
    stable, unstable = 0.0, guess
    while is_stable(unstable):
        stable, unstable = unstable, 2.0 * unstable
    for _ in range(MAX_HALVINGS if stable == 0.0 else 0):
        if is_stable(unstable / 2.0):
            stable = unstable / 2.0
            break
        unstable /= 2.0
    if stable == 0.0:
        return 0.0
    return bisected(is_stable, stable, unstable, rtol)[0]


def limit_1d(is_stable, k: float, c: float, inverse_mass: float) -> float:
    """Largest stable Δt of one contact direction, Eq 30 with stiffness k and damping c."""
    scale = 1.0 / np.sqrt(k * inverse_mass)
    return largest_stable_dt(lambda dt: is_stable(k, c, inverse_mass, dt), scale)


def limit_of_pair(is_stable, body1: Body, body2: Body, contact: Contact) -> float:
    """Largest stable Δt of a two-particle contact: the smaller of its two directions, each
    with its own inverse mass (`criteria.inverse_masses`)."""
    directions = set(contact.directions(inverse_masses(body1, body2)))
    return min(limit_1d(is_stable, k, c, a) for k, c, a in directions)


velocity_verlet_limit: Verifier = partial(limit_of_pair, velocity_verlet_is_stable)
eq40_limit: Verifier = partial(limit_of_pair, eq40_is_stable)
eq40_real_eigenvalue_limit: Verifier = partial(limit_of_pair, eq40_real_eigenvalues_above_minus_one)

# The engine's integrators by key: a label, what is integrated, and a verifier. The
# recommended Δt honours all that apply.
ENGINE_VERIFIERS: dict[str, tuple[str, str, Verifier]] = {
    "velocity_verlet": ("velocity-Verlet", "Eq 30", velocity_verlet_limit),
    "engine": ("revdem engine, spheres", "kernels.integrate.advance", engine_limit),
}
