import math

import numpy as np
import pytest

from revdem_cli.config import Material
from revdem_cli.kernels.contact import hertz_normal, linear_normal
from revdem_cli.state import effective_modulus


def test_equal_materials_give_the_papers_hertz_stiffness():
    # Hanley 2020 Eq 6: H = 4G/(3(1-nu)) sqrt(r_a r_b/(r_a+r_b)) for identical particles
    g, nu, r = 2e6, 0.2, 0.005
    estar = effective_modulus(*(Material(density=1000, shear_modulus=g, poisson_ratio=nu),) * 2)
    overlap = 1e-5
    force, _ = hertz_normal(estar, r / 2, overlap)
    h = 4 * g / (3 * (1 - nu)) * math.sqrt(r * r / (2 * r))
    assert force == pytest.approx(h * overlap**1.5, rel=1e-14)


def test_a_rigid_wall_halves_the_compliance_sum():
    soft = Material(density=1000, shear_modulus=2e6, poisson_ratio=0.2)
    rigid = Material(density=1000, shear_modulus=1e15, poisson_ratio=0.2)
    assert effective_modulus(soft, rigid) == pytest.approx(
        2 * effective_modulus(soft, soft), rel=1e-8
    )


@pytest.mark.parametrize("law", ["hertz", "linear"])
def test_force_is_minus_the_derivative_of_the_stored_energy(law):
    def evaluate(overlap):
        return (
            hertz_normal(2.5e6, 0.0025, overlap) if law == "hertz" else linear_normal(1e4, overlap)
        )

    for overlap in np.geomspace(1e-7, 1e-4, 5):
        h = overlap * 1e-5
        derivative = (evaluate(overlap + h)[1] - evaluate(overlap - h)[1]) / (2 * h)
        assert derivative == pytest.approx(evaluate(overlap)[0], rel=1e-7)
