"""Linear normal spring: F = k_n d."""

import math

from pydantic import Field

from revdem_cli.kernels import inline

FAMILY = "normal"
NAME = "linear"
EQUATION = "Hanley 2020 Eq 6, linear form"
SUMMARY = "F = kn d"
FIELDS = {
    "kn": Field(default=None, gt=0, description="normal spring stiffness for the linear law, N/m")
}
FROM_MATERIALS = False  # k_n is given, not made of the elastic moduli: no Rayleigh step
REQUIRED = ("kn",)


@inline
def force(law, overlap, rstar, estar):
    """(elastic normal force, its stiffness, stored energy) at an overlap > 0: F = k_n d,
    U = 1/2 F d."""
    elastic = law.kn * overlap
    return elastic, law.kn, 0.5 * elastic * overlap


def impact_overlap(law, energy, rstar, estar):
    """The overlap storing `energy`: 1/2 k_n d^2 = U."""
    return math.sqrt(2.0 * energy / law.kn)
