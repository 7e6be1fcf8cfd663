"""Where a parallel loop starts to pay: the size from which `kernels.by_size` runs a loop's
parallel build, measured on this machine for each numba threading layer.

Two kinds of loop make up a step. Light loops do a few flops a particle (the half kick, the
drift, the largest reach since the last pair-list build): measured here by timing the
half kick's serial and parallel builds (`kernels.gather._kick`, a part a thread) at sizes
from 64 to 262 144 particles, with 2 threads. Heavy loops (the pair loop, the gather, the walls) do
tens of nanoseconds of work a particle: measured by the whole step of the fcc Hertz
benchmark (`fcc_hertz.py`) with 1 and 2 threads, whose time they dominate.

    python benchmarks/crossover.py [--layers omp workqueue tbb] [--out benchmarks/results]

Each layer runs in a process of its own (numba loads one layer a process); TBB is measured
where libtbb12 loads. A figure is the median of REPEATS timings of CALLS calls each.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIZES = [64 * 4**k for k in range(7)]  # 64 ... 262 144 particles
REPEATS = 7
CALLS = 200


def light_loop(layer: str) -> list[dict]:
    """Microseconds a call of the half kick of the velocities, on 1 thread and on 2 threads
    (its part-a-thread build from any size: `kernels.by_parts` with threshold 1), at each
    size."""
    import numba
    import numpy as np

    from revdem_cli.kernels import by_parts, renamed
    from revdem_cli.kernels.gather import _kick

    kick = by_parts(renamed(_kick, "_kick_bench"), threshold=1)
    rows = []
    for n in SIZES:
        v, f = np.zeros((n, 3)), np.ones((n, 3))
        inv_m = np.ones(n)
        args = (n, v, v, f, f, inv_m, inv_m, 1e-9, False)  # the velocities alone
        timings = {}
        for name, threads in (("serial", 1), ("parallel", 2)):
            numba.set_num_threads(threads)
            kick(*args)  # compile or load
            samples = []
            for _ in range(REPEATS):
                started = time.perf_counter()
                for _ in range(CALLS):
                    kick(*args)
                samples.append((time.perf_counter() - started) / CALLS * 1e6)
            timings[name] = float(np.median(samples))
        rows.append(
            {"particles": n, "serial_us": timings["serial"], "parallel_us": timings["parallel"]}
        )
    assert numba.threading_layer() == layer, numba.threading_layer()
    return rows


def in_layer(layer: str) -> list[dict] | None:
    """`light_loop` in a process whose numba loads `layer`; None if it cannot load it."""
    env = os.environ | {"NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": "2"}
    code = (
        "import json, sys; sys.path.insert(0, 'benchmarks'); from crossover import light_loop; "
        f"print(json.dumps(light_loop({layer!r})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
    )
    if done.returncode != 0:
        print(f"{layer}: cannot load ({done.stderr.strip().splitlines()[-1]})")
        return None
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--layers", nargs="+", default=["omp", "workqueue", "tbb"])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = parser.parse_args()
    results = {}
    for layer in args.layers:
        rows = in_layer(layer)
        if rows is None:
            continue
        results[layer] = rows
        print(f"{layer}: half kick, microseconds a call (serial / 2 threads)")
        for row in rows:
            ratio = row["serial_us"] / row["parallel_us"]
            print(
                f"  {row['particles']:>7}  {row['serial_us']:9.2f}  {row['parallel_us']:9.2f}"
                f"  speed-up {ratio:5.2f}"
            )
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "crossover.json").write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
