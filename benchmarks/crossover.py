"""Where a parallel loop starts to pay: the sizes from which `kernels.by_size` runs a loop's
parallel build (`kernels.CROSSOVERS`), measured on this machine under each numba threading
layer. The regions run on revdem's own threads under every layer (`kernels.pool`), so the
layers should agree; before they did, workqueue paid from 6 912 spheres and TBB never.

Two kinds of loop make up a step. Light loops do a few flops a particle (the half kick, the
drift, the largest reach since the last pair-list build); heavy loops (the pair loop, the
walls, the neighbour search) tens of nanoseconds and more. Each is measured where it runs,
in the step of the fcc Hertz benchmark with history (`fcc_hertz.py`), at sizes from 256 to
55 296 spheres, three ways: on one thread; on two with the heavy loops parallel and the
light ones serial; on two with every loop parallel. A light loop timed alone misleads: a
parallel half kick leaves each thread's particles in its own core's cache for the pair loop
that follows, and serial light loops cost the step more than they cost themselves (4 000
spheres under OpenMP: 413 against 388 us a step, where the half kick alone pays only from
about 3 000 particles on). The crossover of heavy loops is the smallest size from which two
threads step faster than one in every larger size too, and that of light loops the
smallest size from which they step faster in parallel than serially likewise.

    python benchmarks/crossover.py [--layers omp workqueue tbb] [--out benchmarks/results]

Each layer runs in a process of its own (numba loads one layer a process); TBB is measured
where libtbb12 loads. The three ways are timed in turns, REPEATS rounds, the best of each
kept: this machine's second core changes speed from one second to the next.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from revdem_cli.kernels import NEVER

ROOT = Path(__file__).resolve().parents[1]
CELLS = [4, 6, 8, 10, 12, 15, 24]  # fcc lattices of 256 ... 55 296 spheres
PARTICLE_STEPS = 400_000  # a timing's particle-steps, in 20 to 400 steps: TBB's regions grow
# slower the more a process has started (at 256 spheres, 1 000 000 a timing did not finish the
# five rounds in 20 minutes)
REPEATS = 5
WAYS = {"one_thread": (1, NEVER, NEVER), "heavy_parallel": (2, NEVER, 1), "all_parallel": (2, 1, 1)}
"""(threads, light crossover, heavy crossover) of each way a step is timed."""


def step_times(layer: str) -> list[dict]:
    """Microseconds a step of the fcc benchmark with history, each of WAYS, for each of
    CELLS."""
    import numba
    from fcc_hertz import loop_seconds, scenario_data, warm_up

    from revdem_cli.config import Scenario
    from revdem_cli.kernels import parallel_from
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm_up("history", "float")
    rows = []
    for cells in CELLS:
        steps = min(400, max(20, PARTICLE_STEPS // (4 * cells**3)))
        scenario = Scenario.model_validate(scenario_data(cells, "history", steps))
        state, model = initial_state(scenario), Model.of(scenario)
        best = {}
        for _ in range(REPEATS):
            for way, (threads, light, heavy) in WAYS.items():
                numba.set_num_threads(threads)
                parallel_from[:] = [light, heavy]
                loop_seconds(state, model, 5)  # the threads' first regions
                us = loop_seconds(state, model, steps) / steps * 1e6
                best[way] = min(best.get(way, us), us)
        rows.append({"particles": 4 * cells**3, **best})
    assert numba.threading_layer() == layer, numba.threading_layer()
    return rows


def crossovers(rows: list[dict]) -> tuple[int, int]:
    """(light, heavy): the smallest sizes from which every larger one too stepped faster on
    two threads than on one, and with the light loops parallel than serial (NEVER if none),
    but not below the heavy loops': a light loop in parallel pays for the pair loop's sake,
    not for its own."""

    def from_(faster) -> int:
        size = NEVER
        for row in reversed(rows):
            if not faster(row):
                break
            size = row["particles"]
        return size

    heavy = from_(lambda row: min(row["heavy_parallel"], row["all_parallel"]) < row["one_thread"])
    light = from_(lambda row: row["all_parallel"] < row["heavy_parallel"])
    return max(light, heavy), heavy


def size(crossover: int) -> str:
    return "never" if crossover == NEVER else str(crossover)


def in_layer(layer: str) -> list[dict] | None:
    """`step_times` in a process whose numba loads `layer`; None if it cannot load it (or the
    process fails)."""
    env = os.environ | {"NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": "2"}
    code = (
        "import json, sys; sys.path.insert(0, 'benchmarks'); from crossover import step_times; "
        f"print(json.dumps(step_times({layer!r})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
    )
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        print(f"{layer}: failed ({why})")
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
        light, heavy = crossovers(rows)
        results[layer] = {"steps": rows, "light_from": light, "heavy_from": heavy}
        print(f"{layer}: fcc step with history, us (1 thread / 2, light serial / 2, all parallel)")
        for row in rows:
            print(
                f"  {row['particles']:>7}  {row['one_thread']:9.1f}  {row['heavy_parallel']:9.1f}"
                f"  {row['all_parallel']:9.1f}"
            )
        print(f"  parallel from: light loops {size(light)}, heavy loops {size(heavy)}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "crossover.json").write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
