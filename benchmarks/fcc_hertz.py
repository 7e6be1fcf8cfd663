"""The fcc Hertz benchmark of ../shared/bench/README.md, revdem beside LAMMPS in one run.

n x n x n cubic fcc cells (N = 4 n^3 spheres of diameter 10 mm, lattice constant
0.999 d sqrt(2): every sphere presses on its 12 neighbours with an overlap of 10 um),
periodic, Hertz with G = 2 MPa and nu = 0.2, density 1000 kg/m^3, no damping, velocity
components uniform in [-0.01, 0.01] m/s, dt = 1 us, skin 0.5 mm; `frictionless`, or
`history` (Mindlin shear springs with history, mu = 0.5).

    python benchmarks/fcc_hertz.py [--sizes 10 24 64] [--threads 1 2] [--no-lammps]
                                   [--scaling] [--out benchmarks/results]

Each measurement runs in a process of its own (its thread count, its memory): the stepping
loop's particle-steps per second (N x steps / loop time, set-up and compilation excluded,
the best of REPEATS timings, as is LAMMPS's figure),
the state's bytes per sphere, the process's peak memory per sphere above what it held
before the spheres were made, and a digest of the final state, which must not depend on the
thread count. Beside them: the JIT compile time (a run with an empty kernel cache), the warm
start (a second `revdem run configs/collision.toml` of one step, from process start to
exit), LAMMPS on the same workload when it can be installed, and the ratios. Results go to
OUT/fcc_hertz.json; --scaling adds the time per particle-step against N, OUT/scaling.png.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAMMPS = ROOT.parent / "shared" / "bench" / "lammps" / "run.sh"
STEPS = {10: 1000, 24: 200, 64: 20}
"""Steps timed at each size: the benchmark's 1000 at n = 10 and 200 at n = 24, and enough
at n = 64 (about a million spheres) for a few seconds of stepping."""

REPEATS = 3
"""Each figure is the best of this many timings (one process, one after another for revdem;
separate runs for LAMMPS): the machines are shared, and a slower timing measures the other
work on them."""

DIAMETER = 0.01
SPACING = 0.999 * DIAMETER * 2**0.5


def scenario_data(n: int, variant: str, steps: int, arithmetic: str = "float") -> dict:
    """The benchmark as a revdem scenario."""
    contact = {"model": "hertz"}
    if variant == "history":
        contact |= {"tangential": "mindlin", "friction": 0.5}
    return {
        "name": f"fcc_hertz_{variant}_{n}",
        "materials": {"m": {"density": 1000.0, "shear_modulus": 2.0e6, "poisson_ratio": 0.2}},
        "contact": contact,
        "lattices": [
            {
                "material": "m",
                "radius": DIAMETER / 2,
                "cells": [n, n, n],
                "spacing": SPACING,
                "random_velocity": 0.01,
                "seed": 1,
            }
        ],
        "cell": {"size": [n * SPACING] * 3},
        "integrator": {"dt": 1.0e-6, "arithmetic": arithmetic},
        "neighbours": {"skin": 5.0e-4},
        "stages": [{"name": "run", "steps": steps, "output_every": steps}],
    }


def _rss(field: str) -> int:
    """A memory figure of this process from /proc/self/status, bytes."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    return 0


def measure(n: int, variant: str, steps: int, arithmetic: str = "float") -> dict:
    """Build the benchmark and time its stepping loop, in this process."""
    import numpy as np

    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm = Scenario.model_validate(scenario_data(2, variant, 1, arithmetic))  # compile or load
    loop_seconds(initial_state(warm), Model.of(warm), 1)
    baseline = _rss("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")  # peak memory from here on
    started = time.perf_counter()
    scenario = Scenario.model_validate(scenario_data(n, variant, steps, arithmetic))
    model = Model.of(scenario)
    state = initial_state(scenario)
    setup = time.perf_counter() - started
    loop = min(loop_seconds(state, model, steps) for _ in range(REPEATS))
    arrays = [state.particles, state.pairs, state.walls, state.cell, state.fixed]
    state_bytes = sum(a.nbytes for bundle in arrays for a in bundle if isinstance(a, np.ndarray))
    count = len(state.particles.x)
    digest = hashlib.sha256()
    for a in (state.particles.x, state.particles.v, state.particles.omega):
        digest.update(a.tobytes())
    return {
        "n": n,
        "variant": variant,
        "arithmetic": arithmetic,
        "particles": count,
        "steps": steps,
        "threads": int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count())),
        "setup_s": setup,
        "loop_s": loop,
        "particle_steps_per_s": count * steps / loop,
        "state_bytes_per_particle": state_bytes / count,
        "peak_bytes_per_particle": (_rss("VmHWM") - baseline) / count,
        "pairs": int(state.pairs.count[0]),
        "digest": digest.hexdigest()[:16],
    }


def loop_seconds(state, model, steps: int) -> float:
    """Seconds of `steps` steps of the compiled stage loop, observables only at the end."""

    from revdem_cli.io.tape import no_tape
    from revdem_cli.kernels.integrate import OK, advance
    from revdem_cli.stage import stepping_bundles
    from revdem_cli.state import empty_events

    obs, obs_steps = model.buffers(2)
    stepping = model.stepping(1.0e-6, 0, steps, steps)
    bundles = stepping_bundles(state, model, model.dynamics, model.law)
    started = time.perf_counter()
    status, _, _, _ = advance(
        *bundles, empty_events(), no_tape(), stepping, 0, steps, steps, obs, obs_steps
    )
    seconds = time.perf_counter() - started
    if status != OK:
        raise RuntimeError(f"the stepping loop stopped with status {status}")
    return seconds


def in_process(n: int, variant: str, steps: int, threads: int, arithmetic: str = "float") -> dict:
    """`measure` in a fresh process with `threads` threads."""
    env = os.environ | {"NUMBA_NUM_THREADS": str(threads)}
    code = (
        "import json, sys; sys.path.insert(0, 'benchmarks'); from fcc_hertz import measure; "
        f"print(json.dumps(measure({n}, {variant!r}, {steps}, {arithmetic!r})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def startup_times() -> dict:
    """JIT compile time (a one-step collision with an empty kernel cache) and warm start (the
    same again, the cache filled), seconds from process start to exit."""
    revdem = Path(sys.executable).with_name("revdem")
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        command = [str(revdem), "run", "configs/collision.toml", "--out", out, "--force", "-q"]
        command += ["--no-reverse", "--set", "stages.0.steps=1"]
        env = os.environ | {"NUMBA_CACHE_DIR": cache}
        times = []
        for _ in range(2):
            started = time.perf_counter()
            subprocess.run(command, cwd=ROOT, env=env, check=True, capture_output=True)
            times.append(time.perf_counter() - started)
    return {
        "cold_start_s": times[0],
        "warm_start_s": times[1],
        "jit_compile_s": times[0] - times[1],
    }


def lammps(n: int, steps: int, ranks: int, variant: str) -> float | None:
    """LAMMPS's particle-steps per second on the same workload, the best of REPEATS runs,
    or None if it cannot run."""
    if not LAMMPS.exists():
        return None
    best = None
    for _ in range(REPEATS):
        done = subprocess.run(
            ["bash", str(LAMMPS), str(n), str(steps), str(ranks), variant],
            capture_output=True,
            text=True,
        )
        for word in done.stdout.split():
            if word.startswith("particle_steps_per_s="):
                best = max(best or 0.0, float(word.split("=")[1]))
    return best


def scaling_figure(rows: list[dict], png: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    for variant in ("frictionless", "history"):
        mine = sorted((r for r in rows if r["variant"] == variant), key=lambda r: r["particles"])
        ax.plot(
            [r["particles"] for r in mine],
            [1e9 / r["particle_steps_per_s"] for r in mine],
            "o-",
            label=f"{variant}, {mine[0]['threads']} threads",
        )
    ax.set_xscale("log")
    ax.set_xlabel("spheres N")
    ax.set_ylabel("time per particle-step (ns)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("revdem, fcc Hertz benchmark")
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)
    return png


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=sorted(STEPS))
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--no-lammps", action="store_true")
    parser.add_argument("--scaling", action="store_true")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    results = {
        "startup": startup_times(),
        "runs": [],
        "lammps": [],
        "fixed_point": [],
        "scaling": [],
    }
    print(
        f"start-up: JIT compile {results['startup']['jit_compile_s']:.1f} s, "
        f"warm start {results['startup']['warm_start_s']:.2f} s"
    )
    header = f"{'variant':13} {'n':>3} {'N':>8} {'thr':>3} {'particle-steps/s':>17} "
    print(header + f"{'B/sphere':>9} {'peak B/sph':>10} {'LAMMPS':>9} {'ratio':>6}")
    for variant in ("frictionless", "history"):
        for n in args.sizes:
            steps = STEPS.get(n, max(10, int(4e6 / (4 * n**3))))
            digests = set()
            for threads in args.threads:
                row = in_process(n, variant, steps, threads)
                digests.add(row["digest"])
                theirs = None if args.no_lammps else lammps(n, steps, threads, variant)
                if theirs is not None:
                    results["lammps"].append(
                        {
                            "n": n,
                            "variant": variant,
                            "ranks": threads,
                            "particle_steps_per_s": theirs,
                        }
                    )
                row["lammps_particle_steps_per_s"] = theirs
                row["ratio_to_lammps"] = row["particle_steps_per_s"] / theirs if theirs else None
                results["runs"].append(row)
                print(
                    f"{variant:13} {n:3d} {row['particles']:8d} {threads:3d} "
                    f"{row['particle_steps_per_s']:17.4g} {row['state_bytes_per_particle']:9.0f} "
                    f"{row['peak_bytes_per_particle']:10.0f} "
                    + (f"{theirs:9.3g} {row['ratio_to_lammps']:6.2f}" if theirs else f"{'-':>9}")
                )
            same = len(digests) == 1
            results.setdefault("bitwise_identical_across_threads", []).append(
                {"n": n, "variant": variant, "identical": same}
            )
            print(
                f"  final state with {args.threads} threads: {'identical' if same else 'DIFFERENT'}"
            )
    threads = max(args.threads)
    for variant in ("frictionless", "history"):
        n = 24 if 24 in args.sizes else min(args.sizes)
        steps = STEPS.get(n, 100)
        fixed = in_process(n, variant, steps, threads, "fixed")
        floating = next(
            r
            for r in results["runs"]
            if (r["n"], r["variant"], r["threads"]) == (n, variant, threads)
        )
        ratio = floating["particle_steps_per_s"] / fixed["particle_steps_per_s"]
        fixed["slowdown_against_float"] = ratio
        results["fixed_point"].append(fixed)
        print(
            f"fixed-point {variant:13} n = {n}, {threads} threads: "
            f"{fixed['particle_steps_per_s']:.4g} particle-steps/s, {ratio:.2f} x slower than float"
        )
    if args.scaling:
        threads = max(args.threads)
        for variant in ("frictionless", "history"):
            for n in (6, 8, 10, 14, 18, 24, 32, 40, 50, 64):
                steps = max(10, int(2e7 / (4 * n**3)))
                results["scaling"].append(in_process(n, variant, steps, threads))
        png = scaling_figure(results["scaling"], args.out / "scaling.png")
        print(f"wrote {png}")
    path = args.out / "fcc_hertz.json"
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
