"""The time-reversible velocity predictor (Kolafa & Lisal 2011) against velocity Verlet for
damped DEM run forward and reversed: the study Hanley 2020 §5.2 leaves for future work.

Each case (a damped two-sphere collision, the drop with viscous damping, the oedometer's
settle stage under local damping, and under viscous contact damping instead) runs forward
and reversed with integrator.scheme = 'verlet' and 'trvp' of orders 1 to 4, in floating
point and in fixed-point arithmetic (the control: its kicks and drifts reverse exactly, so
what error remains is the scheme's, the damping forces of the two directions that differ).
The runs go into --out; the tables and the figure into --into (default: --out, beside the
runs; `--into scenarios/kolafa2011` rewrites the results the README quotes, and only when
named, as the critical state's figures.py writes into its --into): `study.csv` (a row a run:
the first divergence step and the reversed time it comes at, the largest errors, the energy
dissipated forward and returned in reverse, seconds), `errors.csv` (the error of every
compared frame against reversed time) and `study.png`, the rows of cases not run kept from
those files in --into. Then the forward accuracy, `restitution.csv` (a viscous contact's
coefficient of restitution against exp(-pi beta / sqrt(1 - beta^2))) and `rebounds.csv`
(the drop's apex heights, where the drop is among the cases), and `collision_dt.csv` (the
collision's reversal error against dt) and `critical_dt.csv` (the critical time step with
the predictor, formula and engine).

    NUMBA_NUM_THREADS=1 python -m benchmarks.trvp_study [--cases collision,drop,oedometer]
                                                       [--accuracy] [--out DIR] [--into DIR]
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from revdem_cli import api as revdem
from revdem_cli.io.restart import read_restart

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "collision": (ROOT / "configs/trvp/collision_damped.toml", {}),
    "drop": (ROOT / "configs/trvp/drop_viscous.toml", {}),
    "oedometer": (ROOT / "configs/trvp/oedometer_settle.toml", {}),
    "oedometer_viscous": (  # the settle stage damped at the contacts instead
        ROOT / "configs/trvp/oedometer_settle.toml",
        {"contact.normal_damping": 0.1, "stages.2.damping.local": 0.0},
    ),
}
"""Each case: its scenario file and the fields changed in it."""
SCHEMES = [("verlet", 0), ("trvp", 1), ("trvp", 2), ("trvp", 3), ("trvp", 4)]
ARITHMETIC = ("float", "fixed")
COLUMNS = (
    "case", "scheme", "order", "arithmetic", "reversed_steps", "first_divergence_step",
    "divergence_reversed_time", "max_position_error_rel", "max_velocity_error",
    "error_at_end", "dissipated", "returned", "blown_up_reversed_time", "seconds",
)  # fmt: skip


def variant(case: str, scheme: str, order: int, arithmetic: str) -> revdem.Experiment:
    changes = {"integrator.scheme": scheme, "integrator.arithmetic": arithmetic}
    if order:
        changes["integrator.trvp_order"] = order
    path, fields = CASES[case]
    return revdem.load(path).changed(fields | changes)


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
    restart = read_restart(result.outputs.restart)
    forward_time, forward = result.observable("total_energy")
    _, back = result.observable("total_energy", run="reverse")
    began = np.argmin(np.abs(forward_time - restart.stage_first_time))  # the reversed stage's
    start = forward[began]
    divergence = comparison["first_divergence_step"]
    row = {
        "reversed_steps": restart.state.step - restart.stage_first_step,
        "first_divergence_step": "" if divergence is None else divergence,
        "divergence_reversed_time": "" if divergence is None else end - at[divergence],
        "max_position_error_rel": comparison["max_position_error_rel"],
        "max_velocity_error": comparison["max_velocity_error"],
        "error_at_end": float(frames["velocity_error"][-1]),
        "dissipated": float(start - back[0]),  # J, forward through the stage
        "returned": float(back[-1] - back[0]),  # J, by the reversed run (until a blow-up)
    }
    return row, errors


def run_study(cases: list[str], out: Path, into: Path) -> None:
    """Each case of `cases` run with every scheme and arithmetic into `out`, its rows written
    into study.csv, errors.csv and study.png in `into`."""
    rows, curves = [], []
    for case in cases:
        for scheme, order in SCHEMES:
            for arithmetic in ARITHMETIC:
                name = f"{case}-{scheme}{order or ''}-{arithmetic}"
                started = time.perf_counter()
                result, blown = _run(variant(case, scheme, order, arithmetic), out / name)
                row, errors = measured(result)
                row["blown_up_reversed_time"] = blown
                seconds = time.perf_counter() - started
                keys = {"case": case, "scheme": scheme, "order": order, "arithmetic": arithmetic}
                rows.append({**keys, **row, "seconds": round(seconds, 1)})
                curves += [{**keys, "reversed_time": e[0], "velocity_error": e[1],
                            "position_error_rel": e[2]} for e in errors]  # fmt: skip
                print(name, {k: rows[-1][k] for k in COLUMNS[5:]}, flush=True)
    rows = _merged(into / "study.csv", rows, cases)
    curves = _merged(into / "errors.csv", curves, cases)
    _write(into / "study.csv", COLUMNS, rows)
    _write(into / "errors.csv", tuple(curves[0]), curves)
    figure(rows, curves, into / "study.png")


def _run(experiment: revdem.Experiment, out: Path) -> tuple[revdem.Result, float | str]:
    """The run forward and reversed, and the reversed time at which the reversal blew up
    ('' if it did not): a reversed run that blows up is compared up to its last frame."""
    from revdem_cli.compare import compare_trajectories
    from revdem_cli.engine import output_paths
    from revdem_cli.state import BlownUp

    try:
        return revdem.run(experiment, out, force=True), ""
    except BlownUp as failure:
        paths = output_paths(out, experiment.scenario.name)
        verdict = compare_trajectories(paths["forward"], paths["reverse"])
        outputs = revdem.Outputs(
            forward=paths["forward"], reverse=paths["reverse"], restart=paths["restart"]
        )
        outputs.verdict = verdict
        result = revdem.Result(outputs)
        steps, times, _ = result.frames("position", run="reverse")
        dt = (times[0] - times[1]) / (steps[0] - steps[1])
        return result, float((steps[0] - failure.step) * dt)


def _merged(path: Path, rows: list[dict], cases: list[str]) -> list[dict]:
    """`rows` after those of the other cases already in the table at `path`, in the order of
    CASES; numbers read back as numbers."""

    def number(text: str):
        try:
            return int(text) if text.lstrip("-").isdigit() else float(text)
        except ValueError:
            return text

    kept = []
    if path.exists():
        with path.open() as f:
            kept = [
                {key: number(value) for key, value in row.items()}
                for row in csv.DictReader(f)
                if row["case"] not in cases
            ]
    order = list(CASES)
    return sorted(kept + rows, key=lambda row: order.index(row["case"]))


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
    columns = min(2, len(cases))
    lines = -(-len(cases) // columns)
    fig, axes = plt.subplots(lines, columns, figsize=(6 * columns, 4 * lines), squeeze=False)
    colours = dict(zip(SCHEMES, ("k", "C0", "C1", "C2", "C3"), strict=True))
    for ax, case in zip(axes.flat, cases, strict=False):
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


def restitution(out: Path, into: Path) -> list[dict]:
    """Forward accuracy: the coefficient of restitution of the linear spring-dashpot of
    configs/trvp/collision_damped.toml, head on (A at 0.9 m/s, B at rest), against
    exp(-pi beta / sqrt(1 - beta^2)) (the damped oscillator's half period), for each scheme
    at omega dt = 0.01 and 0.1, omega = sqrt(k_n / m*)."""
    base = revdem.load(CASES["collision"][0])
    mass = 1000.0 * 4.0 / 3.0 * np.pi * 0.005**3
    omega = np.sqrt(1000.0 / (0.5 * mass))  # k_n = 1000 N/m, m* = m / 2
    rows = []
    for beta in (0.1, 0.3, 0.5):
        exact = float(np.exp(-np.pi * beta / np.sqrt(1.0 - beta**2)))
        for omega_dt in (0.01, 0.1):
            dt = omega_dt / omega
            for scheme, order in SCHEMES:
                changes = {
                    "contact.normal_damping": beta,
                    "particles.0.velocity": [0.9, 0.0, 0.0],
                    "particles.1.velocity": [0.0, 0.0, 0.0],
                    "integrator.dt": dt,
                    "integrator.scheme": scheme,
                    "stages.0.steps": int(np.ceil(3e-3 / dt)),
                    "stages.0.output_every": int(np.ceil(3e-3 / dt)),
                }
                if order:
                    changes["integrator.trvp_order"] = order
                name = f"restitution-{beta}-{omega_dt}-{scheme}{order or ''}"
                result = revdem.run(base.changed(changes), out / name, force=True, reverse=False)
                _, _, v = result.frames("velocity")
                e = float((v[-1, 1, 0] - v[-1, 0, 0]) / 0.9)
                rows.append({
                    "beta": beta, "omega_dt": omega_dt, "scheme": scheme, "order": order,
                    "restitution": e, "exact": exact, "relative_error": e / exact - 1.0,
                })  # fmt: skip
                print(rows[-1], flush=True)
    _write(into / "restitution.csv", tuple(rows[0]), rows)
    return rows


def collision_convergence(out: Path, into: Path) -> list[dict]:
    """The damped collision's reversal error against dt (2, 1 and 0.5 us, the same 3 ms):
    first order in dt for velocity Verlet; for the predictor, the order of what its
    extrapolation across the kinks of a linear dashpot (contact onset, separation) leaves."""
    rows = []
    for dt, steps in ((2e-6, 1500), (1e-6, 3000), (5e-7, 6000)):
        for scheme, order in SCHEMES[:3]:
            changes = {
                "integrator.dt": dt,
                "integrator.scheme": scheme,
                "stages.0.steps": steps,
                "stages.0.output_every": steps // 150,
            }
            if order:
                changes["integrator.trvp_order"] = order
            experiment = revdem.load(CASES["collision"][0]).changed(changes)
            name = f"convergence-{dt}-{scheme}{order or ''}"
            verdict = revdem.run(experiment, out / name, force=True).comparison
            rows.append({
                "dt": dt, "scheme": scheme, "order": order,
                "max_velocity_error": verdict["max_velocity_error"],
                "max_position_error_rel": verdict["max_position_error_rel"],
            })  # fmt: skip
            print(rows[-1], flush=True)
    _write(into / "collision_dt.csv", tuple(rows[0]), rows)
    return rows


def drop_forward_runs(out: Path) -> list[Path]:
    """The trajectories of the drop's forward runs in floating point that the study writes
    into `out`, a scheme each, in the order of SCHEMES."""
    return [
        out / f"drop-{scheme}{order or ''}-float" / "drop_viscous.forward.h5"
        for scheme, order in SCHEMES
    ]


def rebounds(out: Path, into: Path) -> list[dict]:
    """Forward accuracy: the apex heights of the drop's rebounds (the gap under the sphere
    at each maximum of its potential energy after the first impact) in the study's forward
    runs, floating point, for each scheme."""
    rows = []
    for (scheme, order), path in zip(SCHEMES, drop_forward_runs(out), strict=True):
        result = revdem.Result(revdem.Outputs(forward=path))
        time, potential = result.observable("potential_energy")
        mass = 1000.0 * 4.0 / 3.0 * np.pi * 0.005**3
        gap = potential / (mass * 9.81) - 0.005  # m above the plane
        peaks = [
            i for i in range(1, len(gap) - 1)
            if gap[i] > gap[i - 1] and gap[i] >= gap[i + 1] and gap[i] > 1e-7
        ]  # fmt: skip
        for bounce, i in enumerate(peaks, start=1):
            rows.append({"scheme": scheme, "order": order, "bounce": bounce,
                         "time": float(time[i]), "height": float(gap[i])})  # fmt: skip
    _write(into / "rebounds.csv", tuple(rows[0]), rows)
    return rows


def critical_time_steps(into: Path) -> list[dict]:
    """The critical time step of a damped linear contact with the velocity predictor: the
    root of the scheme's characteristic polynomial (`criteria.dt_velocity_predictor`) and
    the engine's own limit on the resting sphere pair (`engine_pair.engine_limit`), two
    spheres of radius 10 mm and 2500 kg/m^3, k_n = 1e6 N/m, frictionless, for damping of
    0.1 and 0.5 of critical; in units of 2/omega, omega = sqrt(k_n A_n)."""
    from revdem_cli.timestep import criteria, engine_pair, shapes

    kn, sphere = 1e6, shapes.sphere(0.01, 2500.0)
    inverse_mass = 2.0 / sphere.mass
    unit = 2.0 / np.sqrt(kn * inverse_mass)
    rows = []
    for beta in (0.1, 0.5):
        c = beta * 2.0 * np.sqrt(kn / inverse_mass)
        for scheme, order in SCHEMES:
            contact = criteria.Contact(kn=kn, ks=0.0, cn=c)
            formula = criteria.dt_velocity_predictor(kn, c, inverse_mass, order)
            engine = engine_pair.engine_limit(sphere, sphere, contact, order)
            rows.append({
                "beta": beta, "scheme": scheme, "order": order, "formula": formula / unit,
                "engine": engine / unit, "engine_over_formula": engine / formula,
            })  # fmt: skip
            print(rows[-1], flush=True)
    _write(into / "critical_dt.csv", tuple(rows[0]), rows)
    return rows


def markdown_table(into: Path) -> str:
    """study.csv in `into` as the README's table: a row a case and scheme, floating point
    beside fixed point: the reversed step (and time) of the first divergence, the largest
    velocity error, and the energy returned over the energy dissipated."""
    with (into / "study.csv").open() as f:
        rows = list(csv.DictReader(f))
    runs = {(r["case"], r["scheme"], r["order"], r["arithmetic"]): r for r in rows}
    lines = [
        "| case | scheme | first divergence, reversed step, float (fixed) | largest velocity "
        "error, m/s, "
        "float (fixed) | returned ÷ dissipated, float |",
        "|---|---|---|---|---|",
    ]

    def divergence(r: dict) -> str:
        if not r["first_divergence_step"]:
            return "none"
        scenario = variant(r["case"], r["scheme"], int(r["order"]), r["arithmetic"]).scenario
        dt = scenario.stages[-1].dt or scenario.integrator.dt  # the reversed stage's
        at = float(r["divergence_reversed_time"])
        steps = f"step {round(at / dt)} of {r['reversed_steps']} ({at * 1e3:.3g} ms)"
        blown = ""
        if r["blown_up_reversed_time"]:
            blown = f", blew up at {float(r['blown_up_reversed_time']) * 1e3:.2f} ms"
        return f"{steps}{blown}"

    for case, scheme, order, _ in [k for k in runs if k[3] == "float"]:
        a, b = runs[case, scheme, order, "float"], runs[case, scheme, order, "fixed"]
        name = "verlet" if scheme == "verlet" else f"trvp k = {order}"
        ratio = float(a["returned"]) / float(a["dissipated"])
        lines.append(
            f"| {case} | {name} | {divergence(a)} ({divergence(b)}) | "
            f"{float(a['max_velocity_error']):.2g} ({float(b['max_velocity_error']):.2g}) | "
            f"{ratio:.9f} |"
        )
    return "\n".join(lines)


def main() -> None:
    """The study as its command line asks for it."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument(
        "--out", type=Path, default=ROOT / "out/kolafa2011", help="the runs (default: %(default)s)"
    )
    parser.add_argument(
        "--into", type=Path,
        help="the tables and the figure (default: --out; scenarios/kolafa2011 rewrites the "
        "results the README quotes)",
    )  # fmt: skip
    parser.add_argument(
        "--accuracy", action="store_true",
        help="only the forward accuracy (restitution, the rebounds of the drop's runs already "
        "in --out) and the critical time steps",
    )  # fmt: skip
    parser.add_argument("--table", action="store_true", help="print --into's study.csv as Markdown")
    arguments = parser.parse_args()
    cases, out = arguments.cases.split(","), arguments.out
    if unknown := [case for case in cases if case not in CASES]:
        parser.error(
            f"--cases {arguments.cases}: no case {', '.join(unknown)}; of {', '.join(CASES)}"
        )
    into = arguments.into or out
    if arguments.table:
        print(markdown_table(into))
        return
    drop = "drop" in cases
    if arguments.accuracy and drop and (missing := not_there(drop_forward_runs(out))):
        parser.error(
            f"--accuracy: {missing}: the drop's runs come from the study (run it without "
            "--accuracy into the same --out), or leave drop out of --cases"
        )
    into.mkdir(parents=True, exist_ok=True)
    if not arguments.accuracy:
        run_study(cases, out, into)
    restitution(out, into)
    if drop:
        rebounds(out, into)
    else:
        print("rebounds.csv: not written, the drop is not among --cases", flush=True)
    collision_convergence(out, into)
    critical_time_steps(into)


def not_there(paths: list[Path]) -> Path | None:
    """The first of `paths` that is not a file, None if each is."""
    return next((path for path in paths if not path.is_file()), None)


if __name__ == "__main__":
    main()
