"""Elastic-plastic spring-dashpot rolling resistance (EPSD), without its dashpot: a rolling
spring of stiffness k_r resists the rotation of one body relative to the other, its moment
limited to mu_r R* |f_n|."""

from pydantic import Field

from revdem_cli.kernels import inline

FAMILY = "rolling"
NAME = "epsd"
EQUATION = (
    "Ai, Chen, Rotter & Ooi 2011, model type C (the one Hanley 2020 §5.3 cites): "
    "dM_r = -k_r dtheta_r, |M_r| <= mu_r R* |f_n|"
)
SUMMARY = "a rolling spring rolling_stiffness whose moment is limited to rolling_friction R* |f_n|"
FIELDS = {
    "rolling_stiffness": Field(
        default=None, gt=0, description="rolling spring stiffness k_r for rolling='epsd', N m/rad"
    ),
    "rolling_friction": Field(
        default=None,
        ge=0,
        description="rolling friction coefficient mu_r for rolling='epsd': the rolling moment "
        "is at most mu_r R* |f_n|, -",
    ),
}
REQUIRED = ("rolling_stiffness", "rolling_friction")


@inline
def stiffness(law, overlap, rstar):
    """k_r, N m/rad."""
    return law.rolling_stiffness


@inline
def limit(law, normal, rstar):
    """The largest rolling moment, mu_r R* |f_n| (0 where the bodies pull apart), N m."""
    return law.rolling_friction * rstar * max(normal, 0.0)
