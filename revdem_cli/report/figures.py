"""Figures of a run, forward and reversed overlaid (matplotlib, written as PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _frames(path: Path, field: str) -> tuple[np.ndarray, np.ndarray]:
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(path) as f:
        group = f[f"particles/all/{field}"]
        return group["time"][:], group["value"][:]


def _observable(path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    from revdem_cli.io.h5md import open_trajectory, read_observable

    with open_trajectory(path) as f:
        return read_observable(f, name)


def _figure(
    forward: Path,
    reverse: Path | None,
    png: Path,
    series,
    ylabel: str,
    xlabel: str = "time (ms)",
) -> Path:
    """Plot series(path) -> [(label, x, values)] for both runs: forward solid, reversed
    dashed, same colour per series."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    span = []
    for run, path, style in (
        ("forward", forward, {"lw": 2.5, "alpha": 0.5}),
        ("reversed", reverse, {"lw": 1.2, "ls": "--"}),
    ):
        if path is None:
            continue
        for k, (label, x, values) in enumerate(series(path)):
            ax.plot(x, values, color=colours[k % len(colours)], label=f"{label} {run}", **style)
            if run == "forward":
                span += [values.min(), values.max()]
    margin = 0.15 * (max(span) - min(span)) or 1.0
    ax.set_ylim(min(span) - margin, max(span) + margin)  # a runaway reversal goes off scale
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)
    return png


def speed_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """|v| of each particle against time (Hanley 2020 Figure 1)."""

    def series(path):
        time, v = _frames(path, "velocity")
        speed = np.linalg.norm(v, axis=2)
        return [(f"particle {q}", time * 1e3, speed[:, q]) for q in range(min(speed.shape[1], 8))]

    return _figure(forward, reverse, png, series, "|v| (m/s)")


def velocity_z_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Vertical velocity of each particle against time (Hanley 2020 Figure 6)."""

    def series(path):
        time, v = _frames(path, "velocity")
        return [(f"particle {q}", time * 1e3, v[:, q, 2]) for q in range(min(v.shape[1], 8))]

    return _figure(forward, reverse, png, series, "v_z (m/s)")


def forces_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Largest normal and shear contact force against time (Hanley 2020 Figure 5)."""

    def series(path):
        return [
            (label, time * 1e3, values)
            for label, name in (("normal", "max_normal_force"), ("shear", "max_shear_force"))
            for time, values in [_observable(path, name)]
        ]

    return _figure(forward, reverse, png, series, "force (N)")


def wall_forces_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """z component of the force on each plane wall against the solid fraction (Hanley 2020
    Figure 3), or against time if none is recorded; the forward run over the steps that the
    reversed run covers."""
    import json

    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(forward) as f:
        scenario = json.loads(f["parameters/revdem"].attrs["scenario_json"])
    planes = [wall["name"] for wall in scenario["walls"] if wall["type"] == "plane"]
    by_fraction = scenario.get("solid_fraction") is not None
    window = None
    if reverse is not None:
        with open_trajectory(reverse) as f:
            steps = f["observables/kinetic_energy/step"][:]
            window = (steps.min(), steps.max())

    def series(path):
        with open_trajectory(path) as f:
            steps = f["observables/kinetic_energy/step"][:]
            keep = slice(None) if window is None else (steps >= window[0]) & (steps <= window[1])
            if by_fraction:
                x = f["observables/solid_fraction/value"][:][keep]
            else:
                x = f["observables/kinetic_energy/time"][:][keep] * 1e3
            return [
                (name, x, f[f"observables/wall_force/{name}/value"][:, 2][keep]) for name in planes
            ]

    xlabel = "solid fraction" if by_fraction else "time (ms)"
    return _figure(forward, reverse, png, series, "force on the wall, z (N)", xlabel)


FIGURES = {
    "speed": speed_figure,
    "velocity_z": velocity_z_figure,
    "forces": forces_figure,
    "wall_forces": wall_forces_figure,
}
"""Figure kinds a scenario can ask for in [output] figures."""
