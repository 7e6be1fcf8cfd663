"""Figures 3-6 of Peng, Burns & Hanley (2020) as CSV and PNG.

Figures 3-5 add, next to the paper's curves, the stability limit of velocity Verlet as a
formula (dashed) and as found by integration (markers).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from revdem_cli.timestep import criteria, shapes, verify

ELLIPSOID = (3.0, 2.0, 1.0)  # semi-axes of Figures 4 and 5 (m)
DENSITY = 1000.0  # kg/m³
KN = 1e10  # N/m; k_s = k_n throughout
DAMPING_NUMBERS = (0, 1, 2, 3, 4, 5)
VOLUME = 8.0 * math.pi  # Figure 6 (m³)
OMEGA_MAX = 1.0  # Figure 6 (rad/s)
FIGURE6_CURVES = (1.0, 2.0, 3.0, 4.0, 5.0)  # e2 of the plotted curves


def _write_csv(path: Path, columns: dict[str, np.ndarray]) -> Path:
    """Columns of equal length as CSV; NaN cells are left empty."""
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(columns)
        for row in zip(*columns.values(), strict=True):
            writer.writerow(["" if np.isnan(v) else f"{v:.10g}" for v in row])
    return path


def _value(dt: float | None) -> float:
    return math.nan if dt is None else dt


def _integrated_limit(k: float, c: float, inverse_mass: float) -> float:
    return verify.limit_1d(verify.velocity_verlet_is_stable, k, c, inverse_mass)


def figure3_data(betas: np.ndarray, every: int) -> dict[str, np.ndarray]:
    """Δt √(k/m) of two equal spheres against β (Eq 58-60); integrated at every `every`-th β."""
    curves = [criteria.sphere_normalised(beta) for beta in betas]
    integrated = [
        _integrated_limit(1.0, beta, 7.0) if i % every == 0 else math.nan
        for i, beta in enumerate(betas)
    ]
    columns = {"beta": betas}
    for key, name in (("belytschko", "eq58"), ("collision", "eq59"), ("amplification", "eq60")):
        columns[f"{name}_{key}"] = np.array([_value(c[key]) for c in curves])
    columns["velocity_verlet"] = np.array([c["velocity_verlet"] for c in curves])
    columns["velocity_verlet_integrated"] = np.array(integrated)
    return columns


def damping_sweep_data(parameter: str, values: np.ndarray, every: int) -> dict[str, np.ndarray]:
    """Figures 4 (parameter "kn") and 5 ("density"): the ellipsoid pair for N = 0..5."""
    rows = []
    for i, value in enumerate(values):
        kn = value if parameter == "kn" else KN
        density = value if parameter == "density" else DENSITY
        body = shapes.ellipsoid(*ELLIPSOID, density)
        inverse_mass = criteria.a_max(body, body)
        for number in DAMPING_NUMBERS:
            c = criteria.damping_from_number(number, kn, inverse_mass)
            integrated = _integrated_limit(kn, c, inverse_mass) if i % every == 0 else math.nan
            rows.append(
                (
                    value,
                    number,
                    inverse_mass,
                    criteria.dt_amplification(kn, c, inverse_mass),
                    criteria.dt_velocity_verlet(kn, c, inverse_mass),
                    integrated,
                )
            )
    names = (
        parameter,
        "N",
        "a_max",
        "eq46_amplification",
        "velocity_verlet",
        "velocity_verlet_integrated",
    )
    return dict(zip(names, np.array(rows).T, strict=True))


def ellipsoid_of_aspect_ratios(e1: float, e2: float) -> shapes.Body:
    """The Figure 6 ellipsoid: a/b = e1, b/c = e2, volume 8π m³."""
    c = (VOLUME / (4.0 / 3.0 * math.pi * e1 * e2**2)) ** (1.0 / 3.0)
    return shapes.ellipsoid(e1 * e2 * c, e2 * c, c, DENSITY)


def figure6_data(ratios: np.ndarray) -> dict[str, np.ndarray]:
    """Translation- (Eq 48) and rotation-dominant (Eq 56) Δt over aspect ratios e1, e2."""
    rows = []
    for e1 in ratios:
        for e2 in ratios:
            body = ellipsoid_of_aspect_ratios(e1, e2)
            b = criteria.b_max(body)
            rows.append(
                (
                    e1,
                    e2,
                    *body.half_lengths,
                    criteria.dt_amplification(KN, 0.0, criteria.a_max(body, body)),
                    criteria.dt_rotation(OMEGA_MAX, b, b),
                )
            )
    names = ("e1", "e2", "a", "b", "c", "dt_translation_eq48", "dt_rotation_eq56")
    return dict(zip(names, np.array(rows).T, strict=True))


def _plot_figure3(columns, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    beta = columns["beta"]
    ax.plot(beta, columns["eq58_belytschko"], label="Eq 58 (Belytschko)")
    ax.plot(beta, columns["eq59_collision"], label="Eq 59 (Silbert collision time)")
    ax.plot(beta, columns["eq60_amplification"], label="Eq 60 (amplification matrix)")
    ax.plot(beta, columns["velocity_verlet"], "k--", label="velocity-Verlet limit")
    ax.plot(
        beta, columns["velocity_verlet_integrated"], "ko", ms=4, label="velocity Verlet, integrated"
    )
    ax.axvline(2.0 / math.sqrt(7.0), color="0.6", lw=0.8, ls=":")
    ax.axvline(2.0 * math.sqrt(2.0), color="0.6", lw=0.8, ls=":")
    ax.set(xlabel="β = c / √(mk)", ylabel="Δt_cri √(k/m)", ylim=(0, 8), xlim=(beta[0], beta[-1]))
    ax.set_title("Two equal spheres (Peng 2020 Figure 3)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _plot_damping_sweep(columns, parameter: str, xlabel: str, title: str, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for number, colour in zip(
        DAMPING_NUMBERS, plt.rcParams["axes.prop_cycle"].by_key()["color"], strict=False
    ):
        rows = columns["N"] == number
        x = columns[parameter][rows]
        ax.plot(x, columns["eq46_amplification"][rows], color=colour, label=f"N = {number}, Eq 46")
        ax.plot(x, columns["velocity_verlet"][rows], color=colour, ls="--")
        ax.plot(x, columns["velocity_verlet_integrated"][rows], "o", color=colour, ms=4)
    ax.plot([], [], "k--", label="velocity-Verlet limit")
    ax.plot([], [], "ko", ms=4, label="velocity Verlet, integrated")
    ax.set(xlabel=xlabel, ylabel="Δt_cri (s)", yscale="log", title=title)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _plot_figure6(columns, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    panels = (
        ("dt_translation_eq48", "(A) translation-dominant, Eq 48"),
        ("dt_rotation_eq56", f"(B) rotation-dominant, Eq 56, ω_max = {OMEGA_MAX:g} rad/s"),
    )
    for ax, (key, title) in zip(axes, panels, strict=True):
        for e2 in FIGURE6_CURVES:
            rows = np.isclose(columns["e2"], e2)
            ax.plot(columns["e1"][rows], columns[key][rows], label=f"e2 = b/c = {e2:g}")
        ax.set(xlabel="e1 = a/b", ylabel="Δt_cri (s)", yscale="log", title=title)
        ax.legend(fontsize=8)
    fig.suptitle(
        "Two equal ellipsoids, V = 8π m³, k_n = 1e10 N/m, ρ = 1000 kg/m³ (Peng 2020 Figure 6)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def write_figures(directory: Path) -> list[Path]:
    """Write Figures 3-6 as PNG and CSV into `directory`; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []

    def save(name, columns, plot, *args):
        written.append(_write_csv(directory / f"{name}.csv", columns))
        plot(columns, *args, directory / f"{name}.png")
        written.append(directory / f"{name}.png")

    betas = np.linspace(0.0, 3.0, 301)
    save("figure3_damping", figure3_data(betas, every=25), _plot_figure3)
    kn = np.linspace(1e10, 1e11, 37)
    save(
        "figure4_stiffness",
        damping_sweep_data("kn", kn, every=12),
        _plot_damping_sweep,
        "kn",
        "k_n = k_s (N/m)",
        "Ellipsoids 3×2×1 m, ρ = 1000 kg/m³ (Peng 2020 Figure 4)",
    )
    density = np.linspace(500.0, 5000.0, 37)
    save(
        "figure5_density",
        damping_sweep_data("density", density, every=12),
        _plot_damping_sweep,
        "density",
        "ρ (kg/m³)",
        "Ellipsoids 3×2×1 m, k_n = k_s = 1e10 N/m (Peng 2020 Figure 5)",
    )
    ratios = np.linspace(1.0, 5.0, 41)
    save("figure6_aspect_ratio", figure6_data(ratios), _plot_figure6)
    return written
