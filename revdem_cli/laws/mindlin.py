"""Mindlin shear spring: k_s = 8 G* sqrt(R* d), stiffening with the overlap as Hertz does
(Mindlin & Deresiewicz 1953, no slip). Hanley 2020 Eq 10 prints H^s = H^n sqrt(U^n 3(1 - nu) /
(2 - nu)), the factor under the root; Mindlin's stiffness has it outside, H^n sqrt(U^n)
3(1 - nu)/(2 - nu) = 8 G* sqrt(R* d) for equal materials, which is the one taken here."""

import math

from revdem_cli.kernels import inline

FAMILY = "tangential"
NAME = "mindlin"
EQUATION = "Hanley 2020 Eq 10 (Mindlin's H^s = H^n sqrt(U^n) 3(1 - nu)/(2 - nu) = 8 G* sqrt(R* d))"
SUMMARY = "k_s = 8 G* sqrt(R* d) from the materials"
FIELDS = {}
REQUIRED = ()


@inline
def stiffness(law, overlap, rstar, gstar):
    """k_s at an overlap > 0, N/m."""
    return 8.0 * gstar * math.sqrt(rstar * overlap)
