"""Figures and tables of the critical-state runs (run.sh writes them into OUT):
Hanley 2020 Figure 7 from real runs, and what reversal says about it.

    python scenarios/hanley2020/critical_state/figures.py OUT [--into DIR]

reads OUT/<case>/critical_state_{dense,loose}.{forward,reverse,restart}.h5 for the cases
friction (mu = 0.5), elastic (mu = 0, undamped), viscous (mu = 0, viscous normal damping),
tangential (mu = 0, viscous tangential damping), seed23 (mu = 0.5 from another random
packing) and long (mu = 0.5 to 40 %), and writes into DIR (default: this folder) the
figures and results.json: for each run the values at the start of shearing, and their mean,
standard deviation, least and largest over the last 5 % of axial strain; and where OUT/tape
holds the mu = 0.5 runs with an information tape, the bits they destroyed (information.png).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import NullFormatter, ScalarFormatter  # noqa: E402

from revdem_cli.io.h5md import (  # noqa: E402
    from_stage_start,
    open_trajectory,
    read_observable,
)
from revdem_cli.io.restart import read_restart  # noqa: E402

HERE = Path(__file__).resolve().parent
CASES = {
    "friction": "mu = 0.5, undamped",
    "elastic": "mu = 0, undamped (energy-conserving)",
    "viscous": "mu = 0, viscous normal damping 0.3",
    "tangential": "mu = 0, viscous tangential damping 0.3",
    "seed23": "mu = 0.5, undamped, another packing (seed 23)",
    "long": "mu = 0.5, undamped, to 40 % axial strain at 0.1 1/s",
}
SAMPLES = ("dense", "loose")
COLOURS = {"dense": "black", "loose": "tab:grey"}
SERIES = ("void_ratio", "mean_stress", "deviator_stress", "mechanical_coordination_number")
SERIES += ("fabric_deviator", "sliding_fraction", "kinetic_energy", "cell_length")
LAST = 0.05
"""The spread of a final value is taken over this last axial strain."""


def shearing(folder: Path, sample: str, run: str = "forward") -> dict[str, np.ndarray]:
    """The observables of the shear stage of a run against its axial strain, 1 - L_z / L_z0
    (compression positive), L_z0 the z edge where shearing began: from the stage's own row
    at its start, where its friction cut the preparation's shear forces and it wrote one
    beside the preparation's end (`from_stage_start`)."""
    name = f"critical_state_{sample}"
    first = read_restart(folder / f"{name}.restart.h5").stage_first_step
    with open_trajectory(folder / f"{name}.{run}.h5") as f:
        steps = f["observables/void_ratio/step"][:]
        data = {key: read_observable(f, key)[1] for key in SERIES}
    keep = from_stage_start(steps, first, reverse=run == "reverse")
    data = {key: value[keep] for key, value in data.items()}
    data["step"] = steps[keep]
    order = np.argsort(data["step"])  # a reversed run is stored from the end back
    data = {key: value[order] for key, value in data.items()}
    lz = data["cell_length"][:, 2]
    data["strain"] = 1.0 - lz / lz[0]
    data["stress_ratio"] = data["deviator_stress"] / data["mean_stress"]
    return data


def final(data: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Mean and standard deviation of each quantity over the last LAST of axial strain."""
    tail = data["strain"] >= data["strain"][-1] - LAST
    keys = ("void_ratio", "stress_ratio", "mechanical_coordination_number", "fabric_deviator")
    keys += ("mean_stress", "sliding_fraction", "kinetic_energy")
    return {
        key: {
            "mean": float(data[key][tail].mean()),
            "std": float(data[key][tail].std()),
            "min": float(data[key][tail].min()),
            "max": float(data[key][tail].max()),
        }
        for key in keys
    }


def start(data: dict[str, np.ndarray]) -> dict[str, float]:
    keys = ("void_ratio", "stress_ratio", "mechanical_coordination_number", "fabric_deviator")
    return {key: float(data[key][0]) for key in keys}


def figure7(runs: dict, path: Path) -> None:
    """Hanley 2020 Figure 7 from the mu = 0.5 runs: void ratio against axial strain and
    against the mean stress; the pair from another packing dashed, where it was run."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6))
    for sample in SAMPLES if "seed23" in runs else ():  # another packing, thin and dashed
        data = runs["seed23"][sample]
        style = {"color": COLOURS[sample], "ls": "--", "lw": 0.8, "label": f"{sample}, seed 23"}
        left.plot(100 * data["strain"], data["void_ratio"], **style)
        right.plot(data["mean_stress"] / 1e3, data["void_ratio"], **style)
    for sample in SAMPLES:
        data = runs["friction"][sample]
        style = {"color": COLOURS[sample], "label": sample}
        left.plot(100 * data["strain"], data["void_ratio"], **style)
        right.plot(data["mean_stress"] / 1e3, data["void_ratio"], **style)
        right.plot(data["mean_stress"][0] / 1e3, data["void_ratio"][0], "o", color=style["color"])
    left.set(xlabel="axial strain (%)", ylabel="void ratio e")
    right.set(xlabel="mean stress p (kPa), log scale", ylabel="void ratio e", xscale="log")
    right.xaxis.set_major_formatter(ScalarFormatter())
    right.xaxis.set_minor_formatter(NullFormatter())
    right.set_xticks([10, 12, 14, 16, 18])
    left.legend(fontsize=8)
    fig.suptitle("Dense and loose samples sheared to one critical state (mu = 0.5)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


PANELS = (
    ("void_ratio", "void ratio e"),
    ("stress_ratio", "q / p"),
    ("mechanical_coordination_number", "mechanical coordination Z_m"),
    ("fabric_deviator", "deviatoric fabric"),
)


def panels(runs: dict, case: str, path: Path, reverse: dict | None = None) -> None:
    """e, q/p, Z_m and the deviatoric fabric against axial strain for dense and loose; with
    `reverse`, the reversed runs dashed over them."""
    fig, axes = plt.subplots(2, 2, figsize=(9, 6), sharex=True)
    for sample in SAMPLES:
        data = runs[case][sample]
        for ax, (key, label) in zip(axes.flat, PANELS, strict=True):
            ax.plot(100 * data["strain"], data[key], color=COLOURS[sample], label=sample)
            if reverse is not None:
                back = reverse[sample]
                ax.plot(
                    100 * back["strain"], back[key], "--", color="tab:red", lw=0.8,
                    label=f"{sample}, reversed",
                )  # fmt: skip
            ax.set_ylabel(label)
    for ax in axes[1]:
        ax.set_xlabel("axial strain (%)")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(CASES[case])
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def information(folder: Path, path: Path) -> dict:
    """The information the mu = 0.5 shearing destroys (the tape runs: `[reversal] tape`),
    against axial strain, for both samples: the bits recorded since the start of shearing,
    and their rate per 1 % of axial strain (a moving mean over 0.5 %); and for each sample
    its tape's totals by mechanism, its rate over the last 5 %, and its reversal's verdict."""
    from revdem_cli.report.figures import information_by_step

    fig, (total, rate) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
    summary = {}
    for sample in SAMPLES:
        forward = folder / f"critical_state_{sample}.forward.h5"
        _, steps, _, bits, names = information_by_step(forward)
        data = shearing(folder, sample)
        strain = np.interp(steps, data["step"], data["strain"])
        per_step = bits.sum(axis=1)
        spent = np.cumsum(per_step)
        width = 0.005
        tail = strain >= strain[-1] - LAST
        summary[sample] = {
            "bits_destroyed": float(spent[-1]),
            "by_mechanism": {name: float(bits[:, k].sum()) for k, name in enumerate(names)},
            "bits_per_percent_strain_last": float(per_step[tail].sum() / (100 * LAST)),
        }
        verdict = json.loads((folder / f"critical_state_{sample}.compare.json").read_text())
        summary[sample]["reversal"] = {
            key: verdict[key] for key in ("reversible", "bitwise_identical", "max_position_error")
        }
        summary[sample]["tape_bytes"] = verdict["information_tape"]["bytes"]
        centres = np.linspace(width / 2, strain[-1] - width / 2, 200)
        edges = np.searchsorted(strain, np.stack([centres - width / 2, centres + width / 2]))
        summed = np.concatenate([[0.0], spent])  # the bits before each step
        in_window = (summed[edges[1]] - summed[edges[0]]) / (100 * width)
        total.plot(100 * strain, spent, color=COLOURS[sample], label=sample)
        rate.plot(100 * centres, in_window, color=COLOURS[sample], label=sample)
    total.set_ylabel("bits destroyed since shearing began")
    rate.set_ylabel("bits per 1 % of axial strain")
    rate.set_xlabel("axial strain (%)")
    for ax in (total, rate):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Information destroyed on the way to the critical state (mu = 0.5)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--into", type=Path, default=HERE)
    args = parser.parse_args()
    runs, results = {}, {}
    for case in CASES:
        restarts = [args.out / case / f"critical_state_{s}.restart.h5" for s in SAMPLES]
        if not all(path.is_file() for path in restarts):
            print(f"{case}: not run (no {' and '.join(map(str, restarts))})")
            continue
        runs[case] = {s: shearing(args.out / case, s) for s in SAMPLES}
        results[case] = {
            s: {"start": start(runs[case][s]), "final": final(runs[case][s])} for s in SAMPLES
        }
    if "friction" in runs:
        figure7(runs, args.into / "figure7.png")
    for case in runs:
        reverse = None
        if case == "elastic":
            reverse = {s: shearing(args.out / case, s, "reverse") for s in SAMPLES}
            for s in SAMPLES:
                comparison = args.out / case / f"critical_state_{s}.compare.json"
                verdict = json.loads(comparison.read_text())
                keys = ("reversible", "bitwise_identical", "max_position_error_rel")
                results[case][s]["reversal"] = {k: verdict[k] for k in keys}
                results[case][s]["reversal"]["void_ratio_back"] = float(reverse[s]["void_ratio"][0])
        panels(runs, case, args.into / f"{case}.png", reverse)
    if all((args.out / "tape" / f"critical_state_{s}.tape.h5").is_file() for s in SAMPLES):
        results["tape"] = information(args.out / "tape", args.into / "information.png")
    text = json.dumps(results, indent=2) + "\n"
    (args.into / "results.json").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
