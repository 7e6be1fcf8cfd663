"""The cost of the velocity predictor (integrator.scheme = 'trvp') against velocity Verlet on
the fcc Hertz benchmark (benchmarks/fcc_hertz.py) with viscous damping at its contacts.

n x n x n fcc cells, Mindlin shear springs (mu = 0.5, `history`) or none (`frictionless`),
normal and tangential damping of 0.1 of critical; the stepping loop timed as fcc_hertz.py
times it (best of REPEATS, set-up and compilation excluded), in this process and its thread
count, for velocity Verlet and trvp of each order given. Results: OUT/trvp_cost.json.

    NUMBA_NUM_THREADS=1 python benchmarks/trvp_cost.py [--n 10] [--orders 2 4]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from fcc_hertz import REPEATS, STEPS, loop_seconds, scenario_data  # noqa: E402

DAMPING = 0.1  # fraction of critical, normal and tangential


def damped(n: int, variant: str, steps: int, order: int) -> dict:
    """The benchmark's scenario with viscous damping, stepped by velocity Verlet (order 0)
    or with the velocity predictor of that order."""
    data = scenario_data(n, variant, steps)
    data["contact"] |= {"normal_damping": DAMPING}
    if variant == "history":
        data["contact"] |= {"tangential_damping": DAMPING}
    if order:
        data["integrator"] |= {"scheme": "trvp", "trvp_order": order}
    return data


def measure(n: int, variant: str, order: int) -> dict:
    from revdem_cli.config import Scenario
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm = Scenario.model_validate(damped(2, variant, 1, order))  # compile or load
    loop_seconds(initial_state(warm), Model.of(warm), 1)
    steps = STEPS[n] if n in STEPS else 200
    scenario = Scenario.model_validate(damped(n, variant, steps, order))
    model, state = Model.of(scenario), initial_state(scenario)
    loop = min(loop_seconds(state, model, steps) for _ in range(REPEATS))
    count = len(state.particles.x)
    return {
        "n": n,
        "variant": variant,
        "scheme": "trvp" if order else "verlet",
        "order": order,
        "particles": count,
        "steps": steps,
        "threads": int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count())),
        "loop_s": loop,
        "particle_steps_per_s": count * steps / loop,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=10)
    parser.add_argument("--orders", type=int, nargs="+", default=[2, 4])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    arguments = parser.parse_args()
    rows = []
    for variant in ("frictionless", "history"):
        verlet = measure(arguments.n, variant, 0)
        rows.append(verlet)
        for order in arguments.orders:
            row = measure(arguments.n, variant, order)
            row["time_per_step_vs_verlet"] = (
                verlet["particle_steps_per_s"] / row["particle_steps_per_s"]
            )
            rows.append(row)
    for row in rows:
        print(json.dumps(row))
    arguments.out.mkdir(parents=True, exist_ok=True)
    (arguments.out / "trvp_cost.json").write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
