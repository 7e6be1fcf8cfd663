"""Linear shear spring: a constant k_s."""

from pydantic import Field

from revdem_cli.kernels import inline

FAMILY = "tangential"
NAME = "linear"
EQUATION = "Hanley 2020 Eq 10 with a constant stiffness"
SUMMARY = "with ks"
FIELDS = {
    "ks": Field(
        default=None, gt=0, description="shear spring stiffness for tangential='linear', N/m"
    )
}
REQUIRED = ("ks",)


@inline
def stiffness(law, overlap, rstar, gstar):
    """k_s, N/m."""
    return law.ks
