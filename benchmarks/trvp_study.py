"""The time-reversible velocity predictor (Kolafa & Lisal 2011) against velocity Verlet for
damped DEM run forward and reversed: the study Hanley 2020 §5.2 leaves for future work.

Each case (a damped two-sphere collision, the drop with viscous damping, the oedometer's
settle stage under local damping) runs forward and reversed with integrator.scheme =
'verlet' and 'trvp' of orders 1 to 4, in floating-point and in fixed-point arithmetic (the
control: its kicks and drifts reverse exactly, so what error remains is the scheme's, the
damping forces of the two directions that differ). Written to scenarios/kolafa2011/:
`study.csv` (a row a run: the first divergence step and the reversed time it comes at,
the largest errors, the energy dissipated forward and returned in reverse, seconds),
`errors.csv` (the error of every compared frame against reversed time) and `study.png`.

    NUMBA_NUM_THREADS=1 python -m benchmarks.trvp_study [--cases collision,drop,oedometer]
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from revdem_cli import api as revdem

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "collision": ROOT / "configs/trvp/collision_damped.toml",
    "drop": ROOT / "configs/trvp/drop_viscous.toml",
    "oedometer": ROOT / "configs/trvp/oedometer_settle.toml",
}
SCHEMES = [("verlet", 0), ("trvp", 1), ("trvp", 2), ("trvp", 3), ("trvp", 4)]
ARITHMETIC = ("float", "fixed")
STUDY = ROOT / "scenarios/kolafa2011"
COLUMNS = (
    "case", "scheme", "order", "arithmetic", "reversed_steps", "first_divergence_step",
    "divergence_reversed_time", "max_position_error_rel", "max_velocity_error",
    "error_at_end", "dissipated", "returned", "seconds",
)  # fmt: skip


def variant(case: str, scheme: str, order: int, arithmetic: str) -> revdem.Experiment:
    changes = {"integrator.scheme": scheme, "integrator.arithmetic": arithmetic}
    if order:
        changes["integrator.trvp_order"] = order
    return revdem.load(CASES[case]).changed(changes)


def measured(result: revdem.Result) -> tuple[dict, np.ndarray]:
    """A run's row of study.csv (but its names and seconds) and its errors [frame, (reversed
    time s, velocity error m/s, position error / diameter)], in the reversed run's order."""
    comparison = result.comparison
    frames = comparison["frames"]
    steps, times, _ = result.frames("position", run="reverse")
    at = {int(s): float(t) for s, t in zip(steps, times, strict=True)}
    end = float(times[0])  # the restart: where the reversed run starts
    reversed_time = np.array([end - at[s] for s in frames["step"]])
    errors = np.column_stack(
        [reversed_time, frames["velocity_error"], frames["position_error_rel"]]
    )
    forward_time, forward = result.observable("total_energy")
    back_time, back = result.observable("total_energy", run="reverse")
    start = forward[np.argmin(np.abs(forward_time - back_time[-1]))]  # where the stage began
    divergence = comparison["first_divergence_step"]
    row = {
        "reversed_steps": int(steps[0] - steps[-1]),
        "first_divergence_step": "" if divergence is None else divergence,
        "divergence_reversed_time": "" if divergence is None else end - at[divergence],
        "max_position_error_rel": comparison["max_position_error_rel"],
        "max_velocity_error": comparison["max_velocity_error"],
        "error_at_end": float(frames["velocity_error"][-1]),
        "dissipated": float(start - back[0]),  # J, forward through the stage
        "returned": float(back[-1] - back[0]),  # J, by the reversed run
    }
    return row, errors


def run_study(cases: list[str], out: Path) -> None:
    STUDY.mkdir(parents=True, exist_ok=True)
    rows, curves = [], []
    for case in cases:
        for scheme, order in SCHEMES:
            for arithmetic in ARITHMETIC:
                name = f"{case}-{scheme}{order or ''}-{arithmetic}"
                started = time.perf_counter()
                result = revdem.run(
                    variant(case, scheme, order, arithmetic), out / name, force=True
                )
                row, errors = measured(result)
                seconds = time.perf_counter() - started
                keys = {"case": case, "scheme": scheme, "order": order, "arithmetic": arithmetic}
                rows.append({**keys, **row, "seconds": round(seconds, 1)})
                curves += [{**keys, "reversed_time": e[0], "velocity_error": e[1],
                            "position_error_rel": e[2]} for e in errors]  # fmt: skip
                print(name, {k: rows[-1][k] for k in COLUMNS[5:]}, flush=True)
    _write(STUDY / "study.csv", COLUMNS, rows)
    _write(STUDY / "errors.csv", tuple(curves[0]), curves)
    figure(rows, curves, STUDY / "study.png")


def _write(path: Path, columns: tuple, rows: list[dict]) -> None:
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows(rows)


def figure(rows: list[dict], curves: list[dict], path: Path) -> None:
    """Velocity error against reversed time, a panel a case: each scheme and order, floating
    point solid, fixed point dashed; the tolerance dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = list(dict.fromkeys(r["case"] for r in rows))
    fig, axes = plt.subplots(1, len(cases), figsize=(5 * len(cases), 4), squeeze=False)
    colours = dict(zip(SCHEMES, ("k", "C0", "C1", "C2", "C3"), strict=True))
    for ax, case in zip(axes[0], cases, strict=True):
        for (scheme, order), colour in colours.items():
            for arithmetic, style in (("float", "-"), ("fixed", "--")):
                picked = [
                    c for c in curves
                    if (c["case"], c["scheme"], c["order"], c["arithmetic"])
                    == (case, scheme, order, arithmetic)
                ]  # fmt: skip
                t = np.array([c["reversed_time"] for c in picked]) * 1e3
                error = np.array([c["velocity_error"] for c in picked])
                label = f"{scheme} k={order}" if scheme == "trvp" else "verlet"
                ax.semilogy(t, np.maximum(error, 1e-20), style, color=colour,
                            label=label if arithmetic == "float" else None)  # fmt: skip
        ax.axhline(1e-9, color="grey", linestyle=":", linewidth=1)
        ax.set_title(case)
        ax.set_xlabel("reversed time (ms)")
        ax.set_ylabel("velocity error (m/s); dashed: fixed point")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--out", type=Path, default=ROOT / "out/kolafa2011")
    arguments = parser.parse_args()
    run_study(arguments.cases.split(","), arguments.out)
