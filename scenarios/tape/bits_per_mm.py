"""Bits destroyed per millimetre of axial compression in the fcc test's tape case
(`run.sh OUT fcc_mu0.25` or `fcc_mu0.25_proportional`): before the first Coulomb slip,
from it to the opening of the xz and yz contacts (coordination below 11.5), and after,
with each mechanism's share, from the forward trajectory's `bits_destroyed` observable.

    .venv/bin/python scenarios/tape/bits_per_mm.py OUT/fcc_mu0.25.tape_true
"""

import sys

import h5py
import numpy as np


def main(folder: str) -> None:
    with (
        h5py.File(f"{folder}/fcc_triaxial.forward.h5", "r") as f,
        h5py.File(f"{folder}/fcc_triaxial.tape.h5", "r") as t,
    ):
        mechanisms = list(t.attrs["mechanisms"])
        first = int(t.attrs["first_step"])
        o = f["observables"]
        step = o["bits_destroyed/step"][:]
        bits = o["bits_destroyed/value"][:]
        edge = o["cell_length/value"][:, 2]
        coordination = o["coordination_number/value"][:]
        principal = o["principal_stress/value"][:]
    taped = (step >= first) & np.isfinite(bits).all(axis=1)  # the tape's stage
    bits, edge, coordination = bits[taped] - bits[taped][0], edge[taped], coordination[taped]
    ratio = principal[taped].max(axis=1) / principal[taped].min(axis=1)
    mm = (edge[0] - edge) * 1e3
    before = int(np.argmax(bits[:, mechanisms.index("coulomb_slip")] > 0)) - 1
    opened = int(np.argmax(coordination < 11.5))
    print(
        f"first slip after {mm[before]:.2f} mm; contacts open at {mm[opened]:.2f} mm "
        f"(sigma1/sigma3 {ratio[opened]:.4f}); end {mm[-1]:.2f} mm (sigma1/sigma3 "
        f"{ratio[-1]:.4f}); largest sigma1/sigma3 {ratio.max():.4f}"
    )
    for a, b, label in ((0, before, "before the first slip"), (before, opened, "to the opening"),
                        (opened, len(mm) - 1, "after it")):  # fmt: skip
        destroyed = bits[b] - bits[a]
        shares = ", ".join(
            f"{name} {100 * d / destroyed.sum():.0f} %"
            for name, d in zip(mechanisms, destroyed, strict=True)
            if d > 0.005 * destroyed.sum()
        )
        print(f"{label}: {destroyed.sum() / (mm[b] - mm[a]):.3g} bits/mm ({shares})")


if __name__ == "__main__":
    main(sys.argv[1])
