"""The fcc Hertz benchmark of ../shared/bench/README.md, revdem beside its peers in one run.

n x n x n cubic fcc cells (N = 4 n^3 spheres of diameter 10 mm, lattice constant
0.999 d sqrt(2): every sphere presses on its 12 neighbours with an overlap of 10 um),
periodic, Hertz with G = 2 MPa and nu = 0.2, density 1000 kg/m^3, no damping, velocity
components uniform in [-0.01, 0.01] m/s, dt = 1 us, skin 0.5 mm; `frictionless`, or
`history` (Mindlin shear springs with history, mu = 0.5).

    python benchmarks/fcc_hertz.py [--sizes 10 24 64] [--threads 1 2]
                                   [--peers lammps liggghts yade] [--peer-sizes 10 24]
                                   [--scaling] [--out benchmarks/results]

Each measurement runs in a process of its own (its thread count, its memory): the stepping
loop's particle-steps per second (N x steps / loop time, set-up and compilation excluded,
as is LAMMPS's figure; the best of REPEATS processes),
the state's bytes per sphere, the process's peak memory per sphere above what it held
before the spheres were made, and a digest of the final state, which must not depend on the
thread count. Beside them: the JIT compile time (a run with an empty kernel cache), the warm
start (a second `revdem run configs/collision.toml` of one step, from process start to
exit). The peers (LAMMPS, LIGGGHTS and Yade, each through ../shared/bench/PEER/run.sh, which
installs it when missing) run the same workload at the sizes of --peer-sizes, with as many
MPI ranks or OpenMP threads as revdem has threads, in turns with revdem: REPEATS rounds of
revdem's process and each peer's run, so that all meet the same slow spells of a shared
machine; beside each figure its ratio to each peer and to the fastest of them, best to
best (`--peers` with no names runs none). Before them ../shared/bench/check.sh runs the
three on a small case from one velocity field; its output goes to OUT/peers_check.txt.
The cost of fixed-point arithmetic (n = 24, the most threads) comes from a process of its
own that steps a floating-point run and a fixed-point one in turns of TURN steps
(`arithmetic_cost`), so that both meet the same machine. Results go to OUT/fcc_hertz.json;
--scaling adds the time per particle-step against N, OUT/scaling.png.
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
BENCH = ROOT.parent / "shared" / "bench"
PEERS = ("lammps", "liggghts", "yade")
"""The codes of ../shared/bench, each with its own `run.sh N_CELLS STEPS PROCS VARIANT`."""
STEPS = {10: 1000, 24: 200, 64: 20}
"""Steps timed at each size: the benchmark's 1000 at n = 10 and 200 at n = 24, and enough
at n = 64 (about a million spheres) for a few seconds of stepping."""

REPEATS = 3
"""Each figure is the best of this many timings, revdem's and each peer's taken in turns, one
a process: the machines are shared, and a slower timing measures the other work on them."""

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


def measure(
    n: int, variant: str, steps: int, arithmetic: str = "float", repeats: int = REPEATS
) -> dict:
    """Build the benchmark and time its stepping loop, in this process: the best of
    `repeats` stretches of `steps` steps."""
    import numpy as np

    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm_up(variant, arithmetic)
    baseline = _rss("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")  # peak memory from here on
    started = time.perf_counter()
    scenario = Scenario.model_validate(scenario_data(n, variant, steps, arithmetic))
    model = Model.of(scenario)
    state = initial_state(scenario)
    setup = time.perf_counter() - started
    loop = min(loop_seconds(state, model, steps) for _ in range(repeats))
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


TURN = 20
"""Steps of each turn of runs stepped in turns (`in_turns`)."""


def in_turns(runs: dict, steps: int) -> dict:
    """Seconds of each of REPEATS stretches of `steps` steps of each run, the runs stepped in
    turns of TURN steps in this process, so that all meet the same machine: runs[key](count,
    last) steps a run `count` steps (`last`: the stretch's last turn) and returns its
    seconds."""
    seconds = {key: [0.0] * REPEATS for key in runs}
    for stretch in range(REPEATS):
        for turn in range(0, steps, TURN):
            for key, step in runs.items():
                seconds[key][stretch] += step(min(TURN, steps - turn), turn + TURN >= steps)
    return seconds


def warm_up(variant: str, arithmetic: str) -> None:
    """Compile the stepping loop (or load it from the cache): one step of a small lattice."""
    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm = Scenario.model_validate(scenario_data(2, variant, 1, arithmetic))
    loop_seconds(initial_state(warm), Model.of(warm), 1)


def arithmetic_cost(n: int, variant: str, steps: int) -> dict:
    """How much slower fixed-point arithmetic steps than floating point: a run of each from
    one start, stepped in turns (`in_turns`), the best of REPEATS timings of `steps` steps
    each."""
    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    runs = {}
    for arithmetic in ("float", "fixed"):
        warm_up(variant, arithmetic)
        scenario = Scenario.model_validate(scenario_data(n, variant, steps, arithmetic))
        state, model = initial_state(scenario), Model.of(scenario)
        runs[arithmetic] = lambda count, last, s=state, m=model: loop_seconds(s, m, count)
    seconds = in_turns(runs, steps)
    best = {arithmetic: min(each) for arithmetic, each in seconds.items()}
    return {
        "float_s_each": seconds["float"],
        "fixed_s_each": seconds["fixed"],
        "slowdown_against_float": best["fixed"] / best["float"],
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


def measured_apart(
    module: str, *args, threads: int | None = None, function: str = "measure"
) -> dict:
    """`function(*args)` of benchmarks/`module`.py in a fresh process (its own memory, and
    `threads` threads where given), its result read back as JSON."""
    env = os.environ | ({"NUMBA_NUM_THREADS": str(threads)} if threads else {})
    call = ", ".join(repr(a) for a in args)
    code = (
        f"import json, sys; sys.path.insert(0, 'benchmarks'); from {module} import {function}; "
        f"print(json.dumps({function}({call})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def in_process(
    n: int,
    variant: str,
    steps: int,
    threads: int,
    arithmetic: str = "float",
    repeats: int = REPEATS,
) -> dict:
    """`measure` in a fresh process with `threads` threads."""
    return measured_apart("fcc_hertz", n, variant, steps, arithmetic, repeats, threads=threads)


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


def peer(name: str, n: int, steps: int, procs: int, variant: str) -> dict | None:
    """A peer's particle-steps per second on the same workload with `procs` MPI ranks or
    OpenMP threads, from one run of its run.sh, or None, said on stderr, where it gives no
    figure."""
    script = BENCH / name / "run.sh"
    done = subprocess.run(
        ["bash", str(script), str(n), str(steps), str(procs), variant],
        capture_output=True,
        text=True,
    )
    for line in done.stdout.splitlines():
        words = line.split()
        if words and words[0] == name:
            fields = dict(word.split("=", 1) for word in words[1:] if "=" in word)
            return {
                "peer": name,
                "n": n,
                "variant": variant,
                "particles": int(fields["particles"]),
                "steps": steps,
                "procs": procs,
                "kind": "threads" if "threads" in fields else "ranks",
                "particle_steps_per_s": float(fields["particle_steps_per_s"]),
            }
    said = (done.stderr.strip().splitlines() or ["nothing on stderr"])[-1]
    print(f"{name}: {script} gave no figure (exit status {done.returncode}: {said})",
          file=sys.stderr)  # fmt: skip
    return None


def in_turns_with_peers(
    n: int, variant: str, steps: int, threads: int, peers: list[str]
) -> tuple[dict, dict]:
    """REPEATS rounds, each of one revdem process (`in_process`, one stretch of `steps`
    steps) and one run of each peer, so that all meet the same spells of the machine:
    (revdem's best, with every round's rate and digest; each peer's best, with every round's
    rate, where it gave any)."""
    runs, theirs = [], {name: [] for name in peers}
    for _ in range(REPEATS):
        runs.append(in_process(n, variant, steps, threads, repeats=1))
        for name in peers:
            figure = peer(name, n, steps, threads, variant)
            if figure is not None:
                theirs[name].append(figure)
    rate = "particle_steps_per_s"
    best = max(runs, key=lambda run: run[rate])
    best |= {"rounds": [run[rate] for run in runs], "digests": sorted({r["digest"] for r in runs})}
    bests = {
        name: max(figures, key=lambda f: f[rate]) | {"rounds": [f[rate] for f in figures]}
        for name, figures in theirs.items()
        if figures
    }
    return best, bests


def peers_check(out: Path) -> Path | None:
    """../shared/bench/check.sh at its default size, its output in OUT/peers_check.txt."""
    script = BENCH / "check.sh"
    if not script.exists():
        return None
    done = subprocess.run(["bash", str(script)], capture_output=True, text=True)
    path = out / "peers_check.txt"
    path.write_text(
        f"# ../shared/bench/check.sh (n = 4, 100 steps, 1 rank or thread), "
        f"{time.strftime('%Y-%m-%d')}, exit status {done.returncode}\n" + done.stdout
    )
    return path


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
    parser.add_argument(
        "--peers", nargs="*", choices=PEERS, default=list(PEERS), help="none: revdem alone"
    )
    parser.add_argument("--peer-sizes", type=int, nargs="+", default=[10, 24])
    parser.add_argument("--scaling", action="store_true")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = parser.parse_args()
    if args.peers and not BENCH.is_dir():
        alone = "--peers alone (make bench PEERS=) runs revdem alone"
        parser.exit(2, f"{BENCH}: not there to run the peers from; {alone}\n")
    for name in [name for name in args.peers if not (BENCH / name / "run.sh").exists()]:
        print(f"{name}: no {BENCH / name / 'run.sh'}; left out", file=sys.stderr)
        args.peers.remove(name)
    args.out.mkdir(parents=True, exist_ok=True)
    results = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "load_average_at_start": os.getloadavg(),
        "startup": startup_times(),
        "runs": [],
        "peers": [],
        "fixed_point": [],
        "scaling": [],
    }
    print(
        f"start-up: JIT compile {results['startup']['jit_compile_s']:.1f} s, "
        f"warm start {results['startup']['warm_start_s']:.2f} s"
    )
    if args.peers:
        check = peers_check(args.out)
        print(f"wrote {check}" if check else "no ../shared/bench/check.sh")
    header = f"{'variant':13} {'n':>3} {'N':>8} {'thr':>3} {'particle-steps/s':>17} "
    header += f"{'B/sphere':>9} {'peak B/sph':>10}"
    print(header + "".join(f" {name:>9} {'ratio':>5}" for name in args.peers) + "  best peer")
    for variant in ("frictionless", "history"):
        for n in args.sizes:
            steps = STEPS.get(n, max(10, int(4e6 / (4 * n**3))))
            digests = set()
            for threads in args.threads:
                load = os.getloadavg()[0]
                peers = args.peers if n in args.peer_sizes else []
                row, bests = in_turns_with_peers(n, variant, steps, threads, peers)
                digests.update(row["digests"])
                row["load_average_1min"] = load
                row["peers"], row["ratio_to"] = {}, {}
                line = (
                    f"{variant:13} {n:3d} {row['particles']:8d} {threads:3d} "
                    f"{row['particle_steps_per_s']:17.4g} {row['state_bytes_per_particle']:9.0f} "
                    f"{row['peak_bytes_per_particle']:10.0f}"
                )
                for name in args.peers:
                    theirs = bests.get(name)
                    if theirs is None:
                        line += f" {'-':>9} {'-':>5}"
                        continue
                    results["peers"].append(theirs)
                    figure = theirs["particle_steps_per_s"]
                    row["peers"][name] = figure
                    row["ratio_to"][name] = row["particle_steps_per_s"] / figure
                    line += f" {figure:9.3g} {row['ratio_to'][name]:5.2f}"
                if row["peers"]:
                    best = max(row["peers"], key=row["peers"].get)
                    row["best_peer"], row["ratio_to_best_peer"] = best, row["ratio_to"][best]
                    line += f"  {best} {row['ratio_to_best_peer']:.2f}"
                results["runs"].append(row)
                print(line)
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
        apart = floating["particle_steps_per_s"] / fixed["particle_steps_per_s"]
        turns = measured_apart(
            "fcc_hertz", n, variant, steps, threads=threads, function="arithmetic_cost"
        )
        ratio = turns["slowdown_against_float"]
        fixed |= {"slowdown_against_float": ratio, "slowdown_apart": apart, "interleaved": turns}
        results["fixed_point"].append(fixed)
        print(
            f"fixed-point {variant:13} n = {n}, {threads} threads: "
            f"{fixed['particle_steps_per_s']:.4g} particle-steps/s, {ratio:.2f} x slower than "
            f"float in turns ({apart:.2f} x from the rates of separate processes)"
        )
    if args.scaling:
        threads = max(args.threads)
        for variant in ("frictionless", "history"):
            for n in (6, 8, 10, 14, 18, 24, 32, 40, 50, 64):
                steps = max(10, int(2e7 / (4 * n**3)))
                results["scaling"].append(in_process(n, variant, steps, threads))
        png = scaling_figure(results["scaling"], args.out / "scaling.png")
        print(f"wrote {png}")
    results["load_average_at_end"] = os.getloadavg()
    path = args.out / "fcc_hertz.json"
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
