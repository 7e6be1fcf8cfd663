"""Figures of a run, forward and reversed overlaid (matplotlib, written as PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _speeds(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(path) as f:
        group = f["particles/all/velocity"]
        return group["time"][:], np.linalg.norm(group["value"][:], axis=2)


def speed_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """|v| of each particle against time, forward solid and reversed dashed (Hanley 2020 Fig 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    time, speed = _speeds(forward)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for q in range(min(speed.shape[1], len(colours))):
        ax.plot(
            time * 1e3,
            speed[:, q],
            color=colours[q],
            lw=2.5,
            alpha=0.5,
            label=f"particle {q} forward",
        )
    if reverse is not None:
        time, speed = _speeds(reverse)
        for q in range(min(speed.shape[1], len(colours))):
            ax.plot(
                time * 1e3,
                speed[:, q],
                color=colours[q],
                ls="--",
                lw=1.2,
                label=f"particle {q} reversed",
            )
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("|v| (m/s)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)
    return png


FIGURES = {"speed": speed_figure}
"""Figure kinds a scenario can ask for in [output] figures."""
