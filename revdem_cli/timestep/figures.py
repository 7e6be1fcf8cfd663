"""Figures 3-6 of Peng, Burns & Hanley (2020) as CSV and PNG.

Figures 3-5 add, next to the paper's curves, the stability limit of velocity Verlet as a
formula (dashed) and as found by integration (markers); Figures 4 and 5, where the study asks,
the limit of the two rigid bodies integrated (open squares, `rigid_pair`). Figure 2's
mobilities and Appendix A's Figures A2 and A4 come from `contact_kinematics`.
"""

from __future__ import annotations

import csv
import itertools
import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from revdem_cli.timestep import criteria, shapes, verify

if TYPE_CHECKING:
    from revdem_cli.timestep.study import Particle, TimestepStudy

# File stems of `revdem dt --figures`, the names of the committed copies in scenarios/peng2020.
PAPER_STEMS = {
    3: "figure3_damping",
    4: "figure4_stiffness",
    5: "figure5_density",
    6: "figure6_aspect_ratio",
}
APPENDIX_STEMS = {
    "figure2": "figure2_mobility",
    "A2": "figureA2_contact_points",
    "A4": "figureA4_orientations",
}
APPENDIX_GRID = 41  # polar × azimuthal angles of each Appendix A scan


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


def _marked(i: int, every: int) -> bool:
    """Whether point i is one integrated at every `every`-th point (0: none)."""
    return every > 0 and i % every == 0


def figure3_data(betas: np.ndarray, every: int) -> dict[str, np.ndarray]:
    """Δt √(k/m) of two equal spheres against β (Eq 58-60); integrated at every `every`-th β."""
    curves = [criteria.sphere_normalised(beta) for beta in betas]
    integrated = [
        _integrated_limit(1.0, beta, 7.0) if _marked(i, every) else math.nan
        for i, beta in enumerate(betas)
    ]
    columns = {"beta": betas}
    for key, name in (("belytschko", "eq58"), ("collision", "eq59"), ("amplification", "eq60")):
        columns[f"{name}_{key}"] = np.array([_value(c[key]) for c in curves])
    columns["velocity_verlet"] = np.array([c["velocity_verlet"] for c in curves])
    columns["velocity_verlet_integrated"] = np.array(integrated)
    return columns


def damping_sweep_data(
    study: TimestepStudy, parameter: str, values: np.ndarray, every: int, rigid_every: int = 0
) -> dict[str, np.ndarray]:
    """Figures 4 (parameter "kn") and 5 ("density"): the study's particle pair, one row per N.

    At every `every`-th value the velocity-Verlet limit is integrated; at every
    `rigid_every`-th (0: none) also the two rigid bodies (`rigid_pair.rigid_body_limit`).
    """
    from revdem_cli.timestep.rigid_pair import rigid_body_limit

    particle, contact = study.particle, study.contact
    rows = []
    for i, value in enumerate(values):
        kn = value if parameter == "kn" else contact.kn
        density = value if parameter == "density" else particle.density
        body = particle.body(density, particle.semi_axes)
        inverse_mass = criteria.a_max(body, body)
        for number in contact.damping_numbers:
            c = criteria.damping_from_number(number, kn, inverse_mass)
            integrated = _integrated_limit(kn, c, inverse_mass) if _marked(i, every) else math.nan
            rigid = (
                rigid_body_limit(body, body, criteria.Contact(kn, kn, c, c))
                if _marked(i, rigid_every)
                else math.nan
            )
            rows.append(
                (
                    value,
                    number,
                    inverse_mass,
                    criteria.dt_amplification(kn, c, inverse_mass),
                    criteria.dt_velocity_verlet(kn, c, inverse_mass),
                    integrated,
                    rigid,
                )
            )
    names = (
        parameter,
        "N",
        "a_max",
        "eq46_amplification",
        "velocity_verlet",
        "velocity_verlet_integrated",
        "rigid_body_integrated",
    )
    return dict(zip(names, np.array(rows).T, strict=True))


def body_of_aspect_ratios(study: TimestepStudy, e1: float, e2: float) -> shapes.Body:
    """The Figure 6 particle: a/b = e1, b/c = e2 at the study's volume (Peng 2020 Section 6.4).

    Every length scales with c and the volume with c³, so c follows from the body at c = 1.
    """
    particle = study.particle
    unit = particle.body(particle.density, (e1 * e2, e2, 1.0))
    c = (study.figure6.volume / unit.volume) ** (1.0 / 3.0)
    return particle.body(particle.density, (e1 * e2 * c, e2 * c, c))


def figure6_data(study: TimestepStudy, ratios: np.ndarray) -> dict[str, np.ndarray]:
    """Translation- (Eq 48) and rotation-dominant (Eq 56) Δt over aspect ratios e1, e2."""
    kn, omega_max = study.contact.kn, study.figure6.omega_max
    rows = []
    for e1 in ratios:
        for e2 in ratios:
            body = body_of_aspect_ratios(study, e1, e2)
            b = criteria.b_max(body)
            rows.append(
                (
                    e1,
                    e2,
                    *body.half_lengths,
                    criteria.dt_amplification(kn, 0.0, criteria.a_max(body, body)),
                    criteria.dt_rotation(omega_max, b, b),
                )
            )
    names = ("e1", "e2", "a", "b", "c", "dt_translation_eq48", "dt_rotation_eq56")
    return dict(zip(names, np.array(rows).T, strict=True))


def _number(value: float) -> str:
    """A number for a plot title: 1e10, not 1e+10."""
    return f"{value:g}".replace("e+", "e")


def _particles(particle: Particle, semi_axes: bool) -> str:
    """The particle pair in words, for plot titles."""
    words = f"{particle.shape.capitalize()}s"
    if semi_axes:
        words += " " + "×".join(f"{h:g}" for h in particle.semi_axes) + " m"
    if particle.exponents is not None:
        words += ", ε1 = {:g}, ε2 = {:g}".format(*particle.exponents)
    return words


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
    ax.axvline(2.0 / math.sqrt(7.0), color="0.6", lw=0.8, ls=":")  # Eq 37, A m = 7 (Eq 26)
    ax.axvline(2.0 * math.sqrt(2.0), color="0.6", lw=0.8, ls=":")  # Eq 36, 59: overdamped
    ax.set(xlabel="β = c / √(mk)", ylabel="Δt_cri √(k/m)", ylim=(0, 8), xlim=(beta[0], beta[-1]))
    ax.set_title("Two equal spheres (Peng 2020 Figure 3)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _plot_damping_sweep(columns, parameter: str, xlabel: str, title: str, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    colours = itertools.cycle(plt.rcParams["axes.prop_cycle"].by_key()["color"])
    numbers = dict.fromkeys(columns["N"])  # the damping numbers N, in the study's order
    for number, colour in zip(numbers, colours, strict=False):
        rows = columns["N"] == number
        x = columns[parameter][rows]
        ax.plot(
            x, columns["eq46_amplification"][rows], color=colour, label=f"N = {number:g}, Eq 46"
        )
        ax.plot(x, columns["velocity_verlet"][rows], color=colour, ls="--")
        ax.plot(x, columns["velocity_verlet_integrated"][rows], "o", color=colour, ms=4)
        ax.plot(x, columns["rigid_body_integrated"][rows], "s", color=colour, ms=5, mfc="none")
    ax.plot([], [], "k--", label="velocity-Verlet limit")
    ax.plot([], [], "ko", ms=4, label="velocity Verlet, integrated")
    if np.isfinite(columns["rigid_body_integrated"]).any():
        ax.plot([], [], "ks", ms=5, mfc="none", label="two rigid bodies, integrated")
    ax.set(xlabel=xlabel, ylabel="Δt_cri (s)", yscale="log", title=title)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _plot_figure6(columns, study: TimestepStudy, path: Path) -> None:
    import matplotlib.pyplot as plt

    figure6 = study.figure6
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    panels = (
        ("dt_translation_eq48", "(A) translation-dominant, Eq 48"),
        ("dt_rotation_eq56", f"(B) rotation-dominant, Eq 56, ω_max = {figure6.omega_max:g} rad/s"),
    )
    for ax, (key, title) in zip(axes, panels, strict=True):
        for e2 in figure6.plotted_e2:
            rows = np.isclose(columns["e2"], e2)
            ax.plot(columns["e1"][rows], columns[key][rows], label=f"e2 = b/c = {e2:g}")
        ax.set(xlabel="e1 = a/b", ylabel="Δt_cri (s)", yscale="log", title=title)
        ax.legend(fontsize=8)
    fig.suptitle(
        f"Two equal {_particles(study.particle, semi_axes=False).lower()}, "
        f"V = {figure6.volume / math.pi:.4g}π m³, k_n = {_number(study.contact.kn)} N/m, "
        f"ρ = {study.particle.density:g} kg/m³ (Peng 2020 Figure 6)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def figure2_data(body: shapes.Body) -> dict[str, np.ndarray]:
    """The mobility A of Eq 25 (from Eq 1-19) of each Figure 2 configuration, times m₁."""
    from revdem_cli.timestep import contact_kinematics as kinematics

    rows = []
    for number, placement in enumerate(kinematics.figure2(body, body).values()):
        mobility = kinematics.mobility((body, body), placement) * body.mass
        rows.append((number, *mobility.ravel(), np.linalg.eigvalsh(mobility).max()))
    names = ("configuration", *(f"A{i}{j}_m1" for i in "xyz" for j in "xyz"), "largest_m1")
    return dict(zip(names, np.array(rows).T, strict=True))


def appendix_data(body: shapes.Body, scan) -> dict[str, np.ndarray]:
    """An Appendix A scan (`contact_kinematics.scan_*`) for both scenarios, stacked."""
    parts = [scan(body, body, scenario, APPENDIX_GRID) for scenario in (1, 2)]
    columns = {"scenario": np.repeat([1.0, 2.0], [len(p["acceleration"]) for p in parts])}
    return columns | {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def _plot_appendix(columns, position: str, title: str, path: Path) -> None:
    """Both scenarios' points (`position`: the column prefix) coloured by |ẍ_c|, the largest
    marked."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 4.8))
    for scenario in (1, 2):
        rows = columns["scenario"] == scenario
        x, y, z = (columns[f"{position}{axis}"][rows] for axis in "xyz")
        values = columns["acceleration"][rows]
        ax = fig.add_subplot(1, 2, scenario, projection="3d")
        shown = ax.scatter(x, y, z, c=values, cmap="jet", s=4)
        top = np.argmax(values)
        ax.scatter(x[top], y[top], z[top], color="k", s=60, marker="x")
        where = ", ".join(f"{v:.3g}" for v in np.round([x[top], y[top], z[top]], 9) + 0.0)
        ax.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
        ax.set_title(
            f"Scenario {scenario}: largest {values[top]:.4g} m/s² at ({where}) m",
            fontsize=9,
        )
        fig.colorbar(shown, ax=ax, shrink=0.6, label="|ẍ_c| (m/s²)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def figure_files(directory: Path, stems) -> list[Path]:
    """The CSV and the PNG, in that order, of each figure `stems` names in `directory`."""
    return [Path(directory) / f"{stem}.{suffix}" for stem in stems for suffix in ("csv", "png")]


def appendix_files(directory: Path) -> list[Path]:
    """What `write_appendix_figures` writes into `directory`, in its order: Figure 2's
    mobilities (CSV), then Figures A2 and A4 (CSV and PNG each)."""
    mobility = Path(directory) / f"{APPENDIX_STEMS['figure2']}.csv"
    return [mobility, *figure_files(directory, (APPENDIX_STEMS[key] for key in ("A2", "A4")))]


def study_files(directory: Path, study: TimestepStudy, stems: dict[int, str]) -> list[Path]:
    """What `write_figures` writes into `directory` of `study`, figure n as `stems[n]`.*."""
    return figure_files(directory, (stems[number] for number in study.figures))


def write_appendix_figures(directory: Path) -> Iterator[Path]:
    """Figure 2's mobilities (CSV) and Appendix A's Figures A2 and A4 (CSV and PNG) for the
    paper's ellipsoids at unit density, contact force (1, 1, 1) N; each path once written."""
    import matplotlib

    from revdem_cli.timestep import contact_kinematics as kinematics

    matplotlib.use("Agg")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    body = shapes.ellipsoid(3.0, 2.0, 1.0, 1.0)
    yield _write_csv(appendix_files(directory)[0], figure2_data(body))  # a table alone
    figures = (
        ("A2", kinematics.scan_contact_points, "", "ellipsoid 2 moved to touch each point"),
        ("A4", kinematics.scan_orientations, "centre2_", "ellipsoid 2 turned about the tip"),
    )
    for key, scan, position, words in figures:
        table, image = figure_files(directory, [APPENDIX_STEMS[key]])
        columns = appendix_data(body, scan)
        yield _write_csv(table, columns)
        title = f"Peng 2020 Figure {key}: |ẍ_c| for F = (1, 1, 1) N, unit density; {words}"
        _plot_appendix(columns, position, title, image)
        yield image


def write_figures(directory: Path, study: TimestepStudy, stems: dict[int, str]) -> Iterator[Path]:
    """Write the study's figures as PNG and CSV into `directory`, figure n as `stems[n]`.*;
    each path once written (a figure's points take seconds: its caller says so as they come)."""
    import matplotlib

    matplotlib.use("Agg")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)

    def save(number, columns, plot, *args):
        table, image = figure_files(directory, [stems[number]])
        yield _write_csv(table, columns)
        plot(columns, *args, image)
        yield image

    particle, kn = study.particle, study.contact.kn
    for number in study.figures:
        if number == 3:
            figure = study.figure3
            yield from save(
                3, figure3_data(figure.beta.values(), figure.integrate_every), _plot_figure3
            )
        elif number == 4:
            figure = study.figure4
            yield from save(
                4,
                damping_sweep_data(
                    study,
                    "kn",
                    figure.kn.values(),
                    figure.integrate_every,
                    figure.integrate_rigid_every,
                ),
                _plot_damping_sweep,
                "kn",
                "k_n = k_s (N/m)",
                f"{_particles(particle, semi_axes=True)}, ρ = {particle.density:g} kg/m³ "
                "(Peng 2020 Figure 4)",
            )
        elif number == 5:
            figure = study.figure5
            yield from save(
                5,
                damping_sweep_data(
                    study,
                    "density",
                    figure.density.values(),
                    figure.integrate_every,
                    figure.integrate_rigid_every,
                ),
                _plot_damping_sweep,
                "density",
                "ρ (kg/m³)",
                f"{_particles(particle, semi_axes=True)}, k_n = k_s = {_number(kn)} N/m "
                "(Peng 2020 Figure 5)",
            )
        else:
            ratios = study.figure6.aspect_ratios.values()
            yield from save(6, figure6_data(study, ratios), _plot_figure6, study)
