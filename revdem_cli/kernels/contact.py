"""Normal contact laws between spheres (Hanley 2020 Eq 6), as small compiled functions."""

import math

from revdem_cli.kernels import jit

HERTZ = 0
LINEAR = 1


@jit
def hertz_normal(estar, rstar, overlap):
    """Hertz force and stored energy: F = 4/3 E* sqrt(R*) d^1.5, U = 2/5 F d (Hanley 2020 Eq 6)."""
    h = 4.0 / 3.0 * estar * math.sqrt(rstar)  # Hanley 2020 Eq 6: H = 4G/(3(1-nu)) sqrt(R*)
    force = h * overlap * math.sqrt(overlap)
    return force, 0.4 * force * overlap  # U = 2/5 H d^2.5 = integral of F dd


@jit
def linear_normal(kn, overlap):
    """Linear spring force and stored energy: F = kn d, U = 1/2 kn d^2 (Hanley 2020 Eq 6)."""
    force = kn * overlap
    return force, 0.5 * force * overlap


@jit
def normal_force(law, overlap, rstar, mat_a, mat_b):
    """Magnitude of the repulsive normal force and the elastic energy of one contact."""
    if law.model == LINEAR:
        return linear_normal(law.kn, overlap)
    return hertz_normal(law.estar[mat_a, mat_b], rstar, overlap)
