"""The time-reversible velocity predictor (Kolafa & Lisal 2011, J Chem Theory Comput 7,
3596): the velocity at a full step that velocity-dependent forces read, extrapolated from
the k + 1 last half-step velocities with coefficients that make the extrapolation
time-symmetric.

Velocity Verlet (Hanley 2020 Eq 1-3, 11-12) computes the forces at t + dt with the
half-step velocity v(t + dt/2): the predictor of order 0. Reversed, the same force is
computed with v(t + 3dt/2), so damping breaks reversibility (Hanley 2020 §5.2). The
predictor of order k,

    v_P(t) = sum_{j=0..k} b_j v(t - (j + 1/2) dt),
    b_0 = (2k + 1)/(k + 1),  b_{j+1} = -b_j (k - j)/(k + j + 2),

has sum_j b_j = 1 and sum_j b_j (j + 1/2)^m = 0 for the odd m = 1, 3, ..., 2k - 1, so the
forward prediction from the earlier half steps and the reversed one from the later half
steps differ by O(dt^(2k+1)) only (k = 1: 3/2, -1/2; k = 2: 5/3, -5/6, 1/6).
"""

import numba
import numpy as np

from revdem_cli.kernels import LIGHT, by_size, jit


@jit
def coefficients(k):
    """b_0 ... b_k of the predictor of order k (Kolafa & Lisal 2011; the recurrence of
    MACSIMUS sim/trvpscale.c): b_0 = (2k + 1)/(k + 1), b_{j+1} = -b_j (k - j)/(k + j + 2)."""
    b = np.zeros(k + 1)
    b[0] = (2.0 * k + 1.0) / (k + 1.0)
    for j in range(k):
        b[j + 1] = -b[j] * (k - j) / (k + j + 2.0)
    return b


def _predict(v, past, predicted, b0, b1, b2, b3, b4):
    """predicted = b_0 v + b_1 past[0] + ... + b_k past[k - 1], summed in that order, then the
    half-step velocity v pushed onto `past` (newest first), the oldest dropped."""
    k = past.shape[0]
    for q in numba.prange(v.shape[0]):
        for d in range(3):
            total = b0 * v[q, d]
            if k > 0:
                total += b1 * past[0, q, d]
            if k > 1:
                total += b2 * past[1, q, d]
            if k > 2:
                total += b3 * past[2, q, d]
            if k > 3:
                total += b4 * past[3, q, d]
            predicted[q, d] = total
            for j in range(k - 1, 0, -1):
                past[j, q, d] = past[j - 1, q, d]
            past[0, q, d] = v[q, d]


predict_rows = by_size(_predict, LIGHT)

MAX_ORDER = 4
"""The highest order (integrator.trvp_order)."""


@jit
def predict(p):
    """The predicted velocities and angular velocities at the full step the forces are about
    to be computed for, from the half-step ones now in p.v and p.omega and the k before them;
    those then join the history. Nothing to do for velocity Verlet (k = 0)."""
    k = p.v_past.shape[0]
    if k == 0:
        return
    b = coefficients(k)
    c = np.zeros(MAX_ORDER + 1)
    for j in range(k + 1):
        c[j] = b[j]
    n = p.v.shape[0]
    predict_rows(n, p.v, p.v_past, p.v_pred, c[0], c[1], c[2], c[3], c[4])
    predict_rows(n, p.omega, p.omega_past, p.omega_pred, c[0], c[1], c[2], c[3], c[4])
