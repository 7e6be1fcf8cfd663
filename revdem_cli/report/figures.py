"""Figures of a run, forward and reversed overlaid (matplotlib, written as PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from revdem_cli.errors import WriteFailed


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
    xlabel: str,
    over_reversal: bool = False,
) -> Path:
    """Plot series(path) -> [(label, x, values)] for both runs: forward solid, reversed
    dashed, same colour per series; an entry (note, None, None) titles the legend instead
    (what was left out). `over_reversal`: as `_panels`'."""
    return _panels(forward, reverse, png, [(series, ylabel)], xlabel, over_reversal)


def _time_unit(forward: Path) -> tuple[float, str]:
    """(factor, label) of the time axis of a run's figures, in a unit its duration reads
    well in: s from 10 s on (the fcc test's 128 s read as 128 000 ms), µs below 1 ms, else
    ms."""
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(forward) as f:
        times = f["observables/kinetic_energy/time"][:]
    end = float(np.abs(times).max()) if len(times) else 0.0
    factor, unit = (1.0, "s") if end >= 10.0 else (1e6, "µs") if end < 1e-3 else (1e3, "ms")
    return factor, f"time ({unit})"


def _panels(
    forward: Path, reverse: Path | None, png: Path, panels, xlabel: str, over_reversal=False
) -> Path:
    """Panels one above the other over a shared x axis, each (series, ylabel) as in
    `_figure`; `over_reversal` (x the time, the same at a step in both runs): beside a
    reversal, the forward run over the span it covers, which the axis says (a reversed last
    stage of a long run was a few pixels at the right edge)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        len(panels), 1, figsize=(6, 1.5 + 2.5 * len(panels)), dpi=120, sharex=True, squeeze=False
    )
    from matplotlib.lines import Line2D

    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    runs = [("forward", forward, {"lw": 2.5, "alpha": 0.5}), ("reversed", reverse,
            {"lw": 1.2, "ls": "--"})]  # fmt: skip
    clipped = False
    for ax, (series, ylabel) in zip(axes[:, 0], panels, strict=True):
        spans = {"forward": [], "reversed": []}
        named = {}  # each series by its colour, once for both runs
        notes = set()
        drawn = {run: series(path) for run, path, _ in runs if path is not None}
        reversed_runs = drawn.get("reversed", []) if over_reversal else []
        covered = [x for _, x, _ in reversed_runs if x is not None and len(x)]
        low = min(float(np.min(x)) for x in covered) if covered else -np.inf
        high = max(float(np.max(x)) for x in covered) if covered else np.inf
        for run, path, style in runs:
            if path is None:
                continue
            for k, (label, x, values) in enumerate(drawn[run]):
                if x is None:
                    notes.add(label)
                    continue
                inside = (x >= low) & (x <= high)
                clipped |= not inside.all()
                x, values = x[inside], values[inside]
                colour = colours[k % len(colours)]
                ax.plot(x, values, color=colour, **style)
                named[label] = Line2D([], [], color=colour, lw=2.0)
                finite = values[np.isfinite(values)]
                if len(finite):
                    spans[run] += [finite.min(), finite.max()]
        for run, path, style in runs:  # then which line is which run
            if path is not None:
                named[run] = Line2D([], [], color="0.3", **style)
        ax.set_ylim(*_limits(*spans.values()))
        ax.set_ylabel(ylabel)
        _legend(ax, named, "; ".join(sorted(notes)) or None)
        ax.grid(alpha=0.3)
    over = ", over the reversed stage"
    axes[-1, 0].set_xlabel(xlabel + (over if clipped and over not in xlabel else ""))
    return _save(fig, png)


def _legend(ax, named: dict, title: str | None = None) -> None:
    """The legend of `named` (label: line), titled `title`, inside the axes where it is
    short, beside them where its entries would cover the curves (more than 4: eight
    spheres, six walls)."""
    if len(named) <= 4:
        ax.legend(named.values(), named.keys(), fontsize=8, title=title, title_fontsize=8)
    else:
        ax.legend(named.values(), named.keys(), fontsize=7, loc="upper left", title=title,
                  title_fontsize=7, bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # fmt: skip


def _limits(forward: list[float], reversed: list[float]) -> tuple[float, float]:
    """y limits that show the forward run and the reversed run where it strays up to the
    forward run's range beyond it (a reversal that parts from the forward run), with a margin
    of 15 % that does not cross zero: a runaway reversal goes off scale, not the forward run
    into a line."""
    low, high = (min(forward), max(forward)) if forward else (0.0, 1.0)
    reach = high - low
    if reversed:
        low, high = (
            min(low, max(min(reversed), low - reach)),
            max(high, min(max(reversed), high + reach)),
        )
    margin = 0.15 * (high - low) or 1.0
    bottom, top = low - margin, high + margin
    if low >= 0.0:  # no margin across zero: values never negative (a force's magnitude)
        bottom = max(bottom, 0.0)
    elif high <= 0.0:  # nor never positive
        top = min(top, 0.0)
    return bottom, top


def _save(fig, png: Path) -> Path:
    """Write a figure and close it; WriteFailed naming the file if it cannot be written."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    png = Path(png)
    tmp = png.with_name(png.name + ".tmp")  # renamed into place: a figure is whole or absent,
    try:  # even where a signal stops the run while it is drawn (`checkpoint.Unfinished`)
        fig.savefig(tmp, format="png")
        tmp.replace(png)
    except OSError as exc:
        png.unlink(missing_ok=True)
        raise WriteFailed(png, exc) from None
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(fig)
    return png


PLOTTED_SPHERES = 8
"""The spheres a figure of each sphere's velocity draws at most: the first, by index."""


def _each_sphere(component, factor: float):
    """series(path) of `component(velocities [F, N, 3])` [F, N] for each of the first
    PLOTTED_SPHERES spheres, named as messages name them (`state.particle_named`), against
    time times `factor` (`_time_unit`)."""
    from revdem_cli.io.h5md import open_trajectory
    from revdem_cli.state import particle_named

    def series(path):
        time, v = _frames(path, "velocity")
        with open_trajectory(path) as f:
            ids = f["particles/all/id"][:]
        values = component(v)
        count = min(values.shape[1], PLOTTED_SPHERES)
        drawn = [(particle_named(q, ids), time * factor, values[:, q]) for q in range(count)]
        if count < values.shape[1]:
            drawn.append((f"the first {count} of {values.shape[1]} spheres", None, None))
        return drawn

    return series


def speed_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """|v| of each particle against time (Hanley 2020 Figure 1)."""
    factor, xlabel = _time_unit(forward)
    speed = _each_sphere(lambda v: np.linalg.norm(v, axis=2), factor)
    return _figure(forward, reverse, png, speed, "|v| (m/s)", xlabel, over_reversal=True)


def velocity_z_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Vertical velocity of each particle against time (Hanley 2020 Figure 6)."""
    factor, xlabel = _time_unit(forward)
    vertical = _each_sphere(lambda v: v[:, :, 2], factor)
    return _figure(forward, reverse, png, vertical, "v_z (m/s)", xlabel, over_reversal=True)


def forces_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Largest normal and shear contact force against time (Hanley 2020 Figure 5)."""

    factor, xlabel = _time_unit(forward)

    def series(path):
        return [
            (label, time * factor, values)
            for label, name in (("normal", "max_normal_force"), ("shear", "max_shear_force"))
            for time, values in [_observable(path, name)]
        ]

    ylabel = "largest contact force (N)"
    return _figure(forward, reverse, png, series, ylabel, xlabel, over_reversal=True)


def wall_forces_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """z component of the force on each plane wall across z (`Wall.across_z`, a platen)
    against the solid fraction (Hanley 2020 Figure 3), or against time if none is recorded;
    the forward run over the steps that the reversed run covers, which the axis says."""
    from revdem_cli.config import Scenario
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(forward) as f:
        scenario = Scenario.model_validate_json(f["parameters/revdem"].attrs["scenario_json"])
    planes = [wall.name for wall in scenario.walls if wall.across_z]
    by_fraction = scenario.solid_fraction is not None
    window = _reversed_window(reverse)
    factor, in_time = _time_unit(forward)

    def series(path):
        with open_trajectory(path) as f:
            keep = _within(f, f["observables/kinetic_energy/step"][:], window)
            if by_fraction:
                x = f["observables/solid_fraction/value"][:][keep]
            else:
                x = f["observables/kinetic_energy/time"][:][keep] * factor
            return [
                (name, x, f[f"observables/wall_force/{name}/value"][:, 2][keep]) for name in planes
            ]

    xlabel = ("solid fraction" if by_fraction else in_time) + (
        ", over the reversed stage" if window else ""
    )
    return _figure(forward, reverse, png, series, "force on the wall, z (N)", xlabel)


def _reversed_window(reverse: Path | None) -> tuple[int, int] | None:
    """First and last step of the reversed run's observables, or None without one."""
    from revdem_cli.io.h5md import open_trajectory

    if reverse is None:
        return None
    with open_trajectory(reverse) as f:
        steps = f["observables/kinetic_energy/step"][:]
        return int(steps.min()), int(steps.max())


def _within(f, steps: np.ndarray, window: tuple[int, int] | None) -> np.ndarray | slice:
    """Which rows of the observables of the open trajectory `f` (their `steps`) lie in the
    reversed run's `window` (`_reversed_window`; every row without one): at its first step
    only the row of the stage that began there, not the end of the stage before written
    beside it (`io.h5md.from_stage_start`)."""
    from revdem_cli.io.h5md import from_stage_start

    if window is None:
        return slice(None)
    reverse = f["parameters/revdem"].attrs.get("direction") == "reverse"
    return from_stage_start(steps, window[0], reverse) & (steps <= window[1])


def stress_ratios_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Principal stress ratios sigma_1 / sigma_3 and sigma_2 / sigma_3, and the coordination
    number, against the compression of the cell along its strain-rate axis (mm), over the
    reversed stage (Hanley 2020 Figure 4)."""
    import json

    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(forward) as f:
        scenario = json.loads(f["parameters/revdem"].attrs["scenario_json"])
    stage = next((s for s in scenario["stages"] if s.get("reverse")), scenario["stages"][-1])
    motion = stage.get("cell") or {}
    axis = next(
        (k for k, name in enumerate("xyz") if (motion.get(name) or {}).get("strain_rate")), 2
    )
    window = _reversed_window(reverse)
    with open_trajectory(forward) as f:
        steps = f["observables/cell_length/step"][:]
        first = window[0] if window else int(steps.min())
        start = f["observables/cell_length/value"][np.nonzero(steps == first)[0][0], axis]

    def read(path, name):
        with open_trajectory(path) as f:
            keep = _within(f, f["observables/cell_length/step"][:], window)
            compression = (start - f["observables/cell_length/value"][:, axis][keep]) * 1e3
            return compression, f[f"observables/{name}/value"][:][keep]

    def ratios(path):
        compression, principal = read(path, "principal_stress")
        # not plotted where σ3 (compression positive) is not a compression: no contacts, or
        # a packing pulled apart, whose ratios (-44 in a lattice's brief loss of contacts)
        # would squeeze the others into a line
        confined = np.where(principal[:, 2] > 0.0, principal[:, 2], np.nan)
        return [
            ("σ1/σ3", compression, principal[:, 0] / confined),
            ("σ2/σ3", compression, principal[:, 1] / confined),
        ]

    def coordination(path):
        return [("coordination", *read(path, "coordination_number"))]

    panels = [(ratios, "principal stress ratio"), (coordination, "coordination number")]
    return _panels(forward, reverse, png, panels, f"compression along {'xyz'[axis]} (mm)")


def _sphere_contacts(path: Path, step: int | None = None) -> dict[str, np.ndarray]:
    """The contacts between spheres (walls left out) of a trajectory's frame at `step` (its
    last where None)."""
    from revdem_cli.io.h5md import frame_steps, open_trajectory, read_contacts

    with open_trajectory(path) as f:
        steps = frame_steps(f)
        frame = len(steps) - 1 if step is None else int(np.nonzero(steps == step)[0][0])
        contacts = read_contacts(f, frame)
    pairs = contacts["value"][:, 1] >= 0
    return {name: values[pairs] for name, values in contacts.items()}


def _normalised_forces(path: Path, step: int | None = None) -> np.ndarray:
    """|f_n| / <|f_n|> of the sphere contacts of the frame at `step` (the last where None)."""
    normal = _sphere_contacts(path, step)["normal_force"]
    magnitude = np.sqrt((normal**2).sum(axis=1))
    return magnitude / magnitude.mean() if len(magnitude) else magnitude


def contact_forces_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """The distribution of normal contact forces normalised by their mean, semi-log: at the
    end of the forward run (the exponential tail of strong forces, Radjai et al. 1996) and,
    with a reversal, at the step it returned to, forward and reversed: where the reversal
    brings back the network the forward run had there, the two lie on each other."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from revdem_cli.io.h5md import frame_steps, open_trajectory

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    runs = [("forward end", _normalised_forces(forward), {"lw": 2.5, "alpha": 0.35})]
    if reverse is not None:
        with open_trajectory(reverse) as f:
            back = int(frame_steps(f)[-1])  # the step the reversal returned to
        runs.append((f"forward at step {back}", _normalised_forces(forward, back), {"lw": 2.0}))
        runs.append(
            (f"reversed, at step {back}", _normalised_forces(reverse), {"lw": 1.2, "ls": "--"})
        )
    runs = [(run, forces, style) for run, forces, style in runs if len(forces)]
    # the axis to 4 means or the 99.9th percentile: one force of 32 means in a few hundred
    # squeezed the rest against the left edge; those beyond are counted in the legend
    top = max([4.0] + [float(np.quantile(forces, 0.999)) for _, forces, _ in runs])
    for run, forces, style in runs:
        density, edges = np.histogram(
            forces, bins=np.arange(0.0, forces.max() + 0.2, 0.1), density=True
        )  # bins of a tenth of the mean, as 40 over [0, 4]
        beyond = int((forces > top).sum())
        label = f"{run} ({len(forces)} contacts{f', {beyond} beyond the axis' if beyond else ''})"
        ax.step(edges[:-1], np.where(density > 0, density, np.nan), where="post", label=label,
                **style)  # fmt: skip
    ax.set_xlim(0.0, top)
    ax.set_yscale("log")
    ax.set_xlabel("normal contact force / mean")
    ax.set_ylabel("probability density")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no contacts between spheres", ha="center", transform=ax.transAxes)
    ax.grid(alpha=0.3)
    return _save(fig, png)


def contact_normals_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """Rose diagrams of the contact normals at the end of the forward run, projected on the
    xz and the xy planes: each 10° sector holds the contacts whose projected normal points
    in it, each weighted by the square of its projection (so that the rose is the in-plane
    part of the fabric tensor <n ⊗ n>, Oda 1982) and counted at n and -n."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    contacts = _sphere_contacts(forward)
    normal = contacts["normal_force"]
    length = np.sqrt((normal**2).sum(axis=1))
    n = normal[length > 0] / length[length > 0, None]
    fig, axes = plt.subplots(1, 2, figsize=(8, 4), dpi=120, subplot_kw={"projection": "polar"})
    edges = np.linspace(-np.pi, np.pi, 37)
    for ax, (a, b, plane) in zip(axes, ((0, 2, "xz"), (0, 1, "xy")), strict=True):
        angle = np.arctan2(n[:, b], n[:, a])
        both = np.concatenate([angle, np.where(angle > 0, angle - np.pi, angle + np.pi)])
        weight = np.tile(n[:, a] ** 2 + n[:, b] ** 2, 2)
        counts, _ = np.histogram(both, bins=edges, weights=weight)
        share = counts / max(weight.sum(), np.finfo(float).tiny)
        ax.bar(edges[:-1], share, width=np.diff(edges), align="edge", alpha=0.7, edgecolor="k")
        ax.set_title(f"contact normals, {plane} plane ({len(n)} contacts)", fontsize=9)
        ax.yaxis.set_major_locator(MaxNLocator(3))  # radial labels that do not overlap
        ax.tick_params(axis="y", labelsize=7)
        ax.set_xticks(np.radians([0, 90, 180, 270]), [plane[0], plane[1], f"-{plane[0]}",
                                                      f"-{plane[1]}"])  # fmt: skip
    fig.supxlabel("radius: the sector's share of the contacts, weighted by the square of each "
                  "normal's projection", fontsize=8)  # fmt: skip
    return _save(fig, png)


def information_by_step(forward: Path) -> tuple[list, np.ndarray, np.ndarray, np.ndarray, list]:
    """The information tapes beside a forward trajectory (`engine.stage_paths`), end to end
    in stage order: those of every stage with `[reversal] all_stages`, else the last
    stage's, each where it is there. Returns the stages read, each (name, first step,
    first time in s), then as `io.tape.by_step` their steps, times (s), bits of each step
    by mechanism, and the mechanisms' names. InputError where none is there."""
    from revdem_cli.engine import stage_paths
    from revdem_cli.io import stored_scenario
    from revdem_cli.io.h5md import open_trajectory
    from revdem_cli.io.tape import by_step

    with open_trajectory(forward) as f:
        scenario = stored_scenario(f["parameters/revdem"].attrs["scenario_json"], forward)
    last = len(scenario.stages) - 1
    indices = range(last + 1) if scenario.reversal.all_stages else [last]
    paths = [stage_paths(Path(forward).parent, scenario.name, k, scenario)["tape"] for k in indices]
    present = [(k, path) for k, path in zip(indices, paths, strict=True) if path.exists()]
    parts = [(k, by_step(path)) for k, path in present or [(last, paths[-1])]]
    stages = [(scenario.stages[k].name, int(part[0][0]), float(part[1][0])) for k, part in parts
              if len(part[0])]  # fmt: skip
    steps, times, bits = (np.concatenate([part[i] for _, part in parts]) for i in range(3))
    return stages, steps, times, bits, parts[-1][1][3]


def moving_mean(values: np.ndarray, window: int, cuts) -> np.ndarray:
    """The mean of the `window` values around each (fewer at an end), within each stretch
    between the indices `cuts` (the stages' starts), so that no stage's values run into
    another's and a stretch's ends are not pulled towards zero."""
    kernel = np.ones(window)
    means = []
    for part in np.split(values, cuts):
        if len(part):
            width = min(window, len(part))
            sums = np.convolve(part, kernel[:width], mode="same")
            means.append(sums / np.convolve(np.ones(len(part)), kernel[:width], mode="same"))
    return np.concatenate(means) if means else values


def information_figure(forward: Path, reverse: Path | None, png: Path) -> Path:
    """The information the run destroyed, from its tapes (`io.tape`; every stage's with
    `[reversal] all_stages`, `information_by_step`): the bits recorded, summed from the start
    of the first stage taped on through the later ones, and per step (averaged over a
    hundredth of the steps), by mechanism, against time, each stage's start marked by a
    thin vertical line with its name where there are several. With one stage, in a cell
    with a strain-rate axis, against the compression along it (mm) instead: over several
    stages the cell may move otherwise from stage to stage, so they stay against time."""
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from revdem_cli.io.h5md import open_trajectory

    stages, steps, times, bits, names = information_by_step(forward)
    factor, xlabel = _time_unit(forward)
    x = times * factor
    starts = [first_time * factor for _, _, first_time in stages]
    if len(stages) == 1:
        with open_trajectory(forward) as f:
            scenario = json.loads(f["parameters/revdem"].attrs["scenario_json"])
        stage = next(s for s in scenario["stages"] if s["name"] == stages[0][0])
        motion = stage.get("cell") or {}
        axis = next(
            (k for k, a in enumerate("xyz") if (motion.get(a) or {}).get("strain_rate")), None
        )
        if axis is not None:
            with open_trajectory(forward) as f:
                at = f["observables/cell_length/step"][:]
                length = f["observables/cell_length/value"][:, axis]
            edge = np.interp(steps, at, length)
            x, xlabel = (edge[0] - edge) * 1e3, f"compression along {'xyz'[axis]} (mm)"
    window = max(1, len(steps) // 100)
    cuts = np.searchsorted(steps, [first for _, first, _ in stages[1:]])
    fig, (total, rate) = plt.subplots(2, 1, figsize=(6, 6.5), dpi=120, sharex=True)
    shown = [k for k in range(len(names)) if bits[:, k].sum() != 0.0]
    for k in shown:
        total.plot(x, np.cumsum(bits[:, k]), label=names[k])
        rate.plot(x, moving_mean(bits[:, k], window, cuts), label=names[k], lw=1)
    if not shown:  # a line at zero over the run says so, and spans the axes over it
        for ax in (total, rate):
            ax.plot(x, np.zeros(len(x)), color="0.4", label="no mechanism destroyed any")
    total.set_ylabel("bits destroyed since the start")
    rate.set_ylabel(f"bits per step (mean of {window})")
    for ax in (total, rate):
        ax.set_yscale("symlog", linthresh=1.0)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    if len(stages) > 1:
        for (name, _, _), start in zip(stages, starts, strict=True):
            for ax in (total, rate):
                ax.axvline(start, color="0.4", lw=0.6)
            total.text(start, 0.98, f" {name}", transform=total.get_xaxis_transform(),
                       rotation=90, va="top", ha="left", fontsize=7, color="0.3")  # fmt: skip
    rate.set_xlabel(xlabel)
    return _save(fig, png)


FIGURES = {
    "speed": speed_figure,
    "velocity_z": velocity_z_figure,
    "forces": forces_figure,
    "wall_forces": wall_forces_figure,
    "stress_ratios": stress_ratios_figure,
    "contact_forces": contact_forces_figure,
    "contact_normals": contact_normals_figure,
    "information": information_figure,
}
"""Figure kinds a scenario can ask for in [output] figures."""
