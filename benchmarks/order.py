"""What the spheres' order in memory costs the step: the fcc Hertz benchmark (`fcc_hertz.py`)
with its spheres in lattice order, shuffled, and shuffled then numbered in space as a packing
is (`assembly.packing.spatial_order`).

The pair loop reads both spheres' rows of each pair; the list is sorted by (i, j), so in
lattice order a sphere's partners lie a few rows, or a plane of cells, from it and their
rows are in cache, and in a random order (spheres placed one by one at random, or read from
a data file written in the order they were inserted) each partner's row is anywhere in
memory.

    python benchmarks/order.py [--sizes 10 24] [--threads 1 2] [--out benchmarks/results]

Each size and thread count runs in a process of its own; in it the three orders, built from
the same lattice and velocities, are stepped in turns (`fcc_hertz.in_turns`), so that all
three meet the same machine, and the best of REPEATS stretches of each is kept. Results go
to OUT/order.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fcc_hertz import STEPS, in_turns, loop_seconds, measured_apart, scenario_data, warm_up

ORDERS = ("lattice", "shuffled", "spatial")
VARIANTS = ("frictionless", "history")
SEED = 5


def reordered(spheres, order: str):
    """The benchmark's spheres in `order`: as the lattice gives them, shuffled (SEED), or
    shuffled then numbered in space (`spatial_order`)."""
    import numpy as np

    from revdem_cli.assembly.packing import spatial_order

    if order == "lattice":
        return spheres
    k = np.random.default_rng(SEED).permutation(len(spheres))
    if order == "spatial":
        k = k[spatial_order(spheres.position[k], 2.0 * spheres.radius.max())]
    return spheres.taken(k)


def measure(n: int) -> list[dict]:
    """Particle-steps per second of each of VARIANTS in each of ORDERS at size n, in this
    process."""
    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    rows = []
    steps = STEPS[n]
    for variant in VARIANTS:
        warm_up(variant, "float")
        runs = {}
        for order in ORDERS:
            scenario = Scenario.model_validate(scenario_data(n, variant, steps))
            scenario._spheres = reordered(scenario.spheres, order)  # as `generate` left them
            state, model = initial_state(scenario), Model.of(scenario)
            count = len(state.particles.x)
            runs[order] = lambda k, last, s=state, m=model: loop_seconds(s, m, k)
        seconds = in_turns(runs, steps)
        for order, each in seconds.items():
            rows.append(
                {
                    "n": n,
                    "particles": count,
                    "variant": variant,
                    "order": order,
                    "particle_steps_per_s": count * steps / min(each),
                    "seconds_each": each,
                }
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 24])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    rows = []
    for threads in args.threads:
        for n in args.sizes:
            for row in measured_apart("order", n, threads=threads):
                rows.append(row | {"threads": threads})
                print(
                    f"n = {n:2d}  {threads} thread(s)  {row['variant']:12s} {row['order']:8s} "
                    f"{row['particle_steps_per_s']:.3g} particle-steps/s",
                    flush=True,
                )
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "order.json"
    result = {"date": time.strftime("%Y-%m-%d %H:%M"), "runs": rows}
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
