"""The observables' per-contact parts (`kernels.observables`)."""

import math

import numpy as np
import pytest

from revdem_cli.kernels.observables import normal_and_shear


@pytest.mark.parametrize("seed", range(5))
def test_a_contact_force_splits_into_its_normal_and_shear_parts_to_round_off(seed):
    """|f_t| was sqrt(|f|^2 - (f.n)^2), whose cancellation left about 1e-8 |f| where f lies
    along n: a frictionless run reported a largest shear force of 2e-8 N beside 0.875 N. Now
    it is |f - (f.n) n|, to round-off of |f|, and 0 where no shear law acts."""
    rng = np.random.default_rng(seed)
    n = rng.standard_normal(3)
    n /= np.linalg.norm(n)
    t = np.cross(n, rng.standard_normal(3))
    t /= np.linalg.norm(t)
    normal = tuple(0.875 * n)
    fn, fs = normal_and_shear(normal, tuple(n), True)
    assert fn == pytest.approx(0.875, rel=1e-15) and fs < 1e-15
    assert normal_and_shear(normal, tuple(n), False) == (fn, 0.0)
    for shear in (1e-6, 0.3):
        fn, fs = normal_and_shear(tuple(0.875 * n + shear * t), tuple(n), True)
        assert fn == pytest.approx(0.875, rel=1e-14)
        assert fs == pytest.approx(shear, rel=1e-9 if shear < 1e-3 else 1e-14)
        assert not math.isnan(fs)
