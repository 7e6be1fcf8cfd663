"""Hertz normal contact: F = 4/3 E* sqrt(R*) d^(3/2), with E* and R* of the two bodies."""

import math

from revdem_cli.kernels import inline

FAMILY = "normal"
NAME = "hertz"
EQUATION = "Hanley 2020 Eq 6 (H = 4G/(3(1 - nu)) sqrt(R*) for equal materials)"
SUMMARY = "F = 4/3 E* sqrt(R*) d^1.5 from the materials"
FIELDS = {}
FROM_MATERIALS = True  # a stiffness from the elastic moduli: the Rayleigh step bounds it
REQUIRED = ()


@inline
def force(law, overlap, rstar, estar):
    """(elastic normal force, its stiffness dF/dd, stored energy) at an overlap > 0: Hanley
    2020 Eq 6 written F = 4/3 E* d sqrt(R* d), the root Mindlin's k_s takes too; dF/dd =
    2 E* sqrt(R* d), U = 2/5 F d."""
    root = math.sqrt(rstar * overlap)
    elastic = 4.0 / 3.0 * estar * overlap * root
    return elastic, 2.0 * estar * root, 0.4 * elastic * overlap


def impact_overlap(law, energy, rstar, estar):
    """The overlap storing `energy`: U = 2/5 H d^(5/2) with H = 4/3 E* sqrt(R*) (Eq 6)."""
    hertz = 4.0 / 3.0 * estar * math.sqrt(rstar)
    return (2.5 * energy / hertz) ** 0.4
