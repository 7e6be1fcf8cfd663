"""Contact forces: each pair's force computed once into its own slot, then gathered per
particle in a fixed order, so sums do not depend on the thread count.

The parallel loops take plain arrays: numba's parallel loops do not write through arrays
held in tuples.
"""

import math

import numba

from revdem_cli.kernels import jit, pjit
from revdem_cli.kernels.contact import normal_force


@pjit
def pair_forces(x, radius, material, law, pair_i, pair_j, n_pairs, force, energy):
    """Normal force on i from j for every listed pair (Hanley 2020 Eq 6), and its energy."""
    for k in numba.prange(n_pairs):
        i = pair_i[k]
        j = pair_j[k]
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = radius[i] + radius[j] - dist
        if overlap <= 0.0:
            force[k, :] = 0.0
            energy[k] = 0.0
            continue
        rstar = radius[i] * radius[j] / (radius[i] + radius[j])
        magnitude, energy[k] = normal_force(law, overlap, rstar, material[i], material[j])
        scale = -magnitude / dist  # pushes i away from j along n = (x_j - x_i)/|x_j - x_i|
        force[k, 0] = scale * dx
        force[k, 1] = scale * dy
        force[k, 2] = scale * dz


@pjit
def gather_forces(mass, gravity, pair_i, force, start, slots, f):
    """Net force on each particle: weight, then its contacts by partner index (Hanley 2020 Eq 4)."""
    for q in numba.prange(f.shape[0]):
        fx = mass[q] * gravity[0]
        fy = mass[q] * gravity[1]
        fz = mass[q] * gravity[2]
        for s in range(start[q], start[q + 1]):
            k = slots[s]
            if pair_i[k] == q:
                fx += force[k, 0]
                fy += force[k, 1]
                fz += force[k, 2]
            else:
                fx -= force[k, 0]
                fy -= force[k, 1]
                fz -= force[k, 2]
        f[q, 0] = fx
        f[q, 1] = fy
        f[q, 2] = fz


@jit
def compute_forces(p, pairs, law, gravity):
    """Forces at the current positions (Hanley 2020 Eq 4-6 forward, Eq 19 reversed)."""
    pair_forces(
        p.x, p.radius, p.material, law, pairs.i, pairs.j, pairs.count[0], pairs.force, pairs.energy
    )
    gather_forces(p.mass, gravity, pairs.i, pairs.force, pairs.start, pairs.slots, p.f)
