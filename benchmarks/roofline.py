"""Where a step of the fcc Hertz benchmark (benchmarks/fcc_hertz.py) spends its time, loop by
loop, against the memory traffic each loop cannot avoid: a roofline of the stepping loop.

Each loop of a forward step is timed alone on the benchmark's state (one thread, best of
REPEATS): the pair loop (with the sums of each sphere's
forces: `pairs.sum_in_order`), the gather (the net force of each sphere and its half kick),
the first half kick, the drift (in fixed-point arithmetic with the positions the integers
give), and the check for a rebuild of the pair list; the rest of the step is what the whole
step takes beyond them. Beside each loop, the bytes it must move at least, each array it
reads or writes touched once (a pair's particles' rows counted once per particle, a store
once), and the time those bytes take at the copy bandwidth measured here by numpy on one core
(read + write); a loop at 1.0 runs at that bandwidth. A loop far below it is bound by its
arithmetic or by the latency of its scattered reads, not by memory. The pair loop's
arithmetic has a floor of its own: the square roots and divisions of its contact stage
(ROOTS_AND_DIVISIONS) at the divide unit's throughput, measured here too (`divide_unit`).

    NUMBA_NUM_THREADS=1 python benchmarks/roofline.py [--n 24] [--out benchmarks/results]

Results: OUT/roofline.json and OUT/roofline.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from fcc_hertz import REPEATS, measured_apart, scenario_data  # noqa: E402

STEPS = 100
"""Steps of the whole step's timing; each loop alone is timed over as many calls."""

LOOPS = ("pair loop", "gather", "first half kick", "drift", "rebuild check", "rest of the step")

ROOTS_AND_DIVISIONS = {"frictionless": (2, 2), "history": (4, 4)}
"""Square roots and divisions a pair of the floating-point contact stage (`pairs.contacts`,
stepping forward, each a vector operation of the divide unit, which the rest of the stage
does not use): frictionless, the distance |d| and 1/|d| for the normal, R* = r_i r_j /
(r_i + r_j) and the root sqrt(R* delta) of the Hertz law (Hanley 2020 Eq 6); with history
also the remap's sqrt(|f_s|^2 / |f_s,projected|^2) (Eq 8, a root and a division) and the
Coulomb cap's |f_s| and mu |f_n| / |f_s| (§2); Mindlin's sqrt(R* delta) (Eq 10) is Hertz's."""


def copy_bandwidth(megabytes: int = 512) -> float:
    """Bytes per second one core copies between two arrays of `megabytes` (read + write)."""
    a = np.ones(megabytes * 2**20 // 8)
    b = np.empty_like(a)
    best = min(_timed(lambda: np.copyto(b, a)) for _ in range(5))
    return 2 * a.nbytes / best


def divide_unit() -> dict[str, float]:
    """Seconds per element of a vectorised square root and of a division (the divide unit's
    throughput), each over 4 096 doubles held in the first-level cache, compiled as revdem's
    kernels are (no fast math), the best of five runs."""
    from revdem_cli.kernels import jit

    @jit
    def roots(a, b, times):
        for _ in range(times):
            for k in range(a.shape[0]):
                b[k] = np.sqrt(a[k])

    @jit
    def divisions(a, b, times):
        for _ in range(times):
            for k in range(a.shape[0]):
                b[k] = 1.5 / a[k]

    a = 1.0 + np.random.default_rng(1).random(4096)
    b = np.empty_like(a)
    times = 20_000
    seconds = {}
    for name, kernel in (("square root", roots), ("division", divisions)):
        kernel(a, b, 1)
        best = min(_timed(lambda k=kernel: k(a, b, times)) for _ in range(5))
        seconds[name] = best / times / a.size
    seconds["division, two threads at once"] = min(
        _two_at_once(divisions, a, times) for _ in range(5)
    )
    return seconds


def _two_at_once(kernel, a, times: int) -> float:
    """Seconds per element of `kernel` run by two threads at once, each over its own copy of
    `a` (revdem's kernels run without the GIL): the one thread's time where each has a
    divide unit of its own, twice it where the two are hardware threads of one core and
    share it."""
    copies = [(a.copy(), np.empty_like(a)) for _ in range(2)]
    threads = [threading.Thread(target=kernel, args=(*pair, times)) for pair in copies]
    started = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return (time.perf_counter() - started) / times / a.size


def contact_floor(row: dict, unit: dict[str, float]) -> float:
    """Seconds per particle-step the floating-point contact stage needs at least: its square
    roots and divisions a pair (ROOTS_AND_DIVISIONS) at the divide unit's throughput."""
    roots, divisions = ROOTS_AND_DIVISIONS[row["variant"]]
    per_pair = roots * unit["square root"] + divisions * unit["division"]
    return per_pair * row["pairs"] / row["particles"]


def _timed(call) -> float:
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def _best(call, times: int) -> float:
    """Seconds per call, the best of REPEATS runs of `times` calls."""
    return min(_timed(lambda: [call() for _ in range(times)]) for _ in range(REPEATS)) / times


def traffic(state) -> dict[str, int]:
    """The bytes each loop must move at least (see the module docstring): the arrays it
    reads, and those it writes, each once (the pair arrays as far as the list goes). The
    pair loop sums the particles' forces and moments (`pairs.sum_in_order`); in floating
    point it writes no pair forces, n x f or overlaps (fixed point writes them, and the
    normals the next step turns the histories from), and the gather reads no pair arrays."""
    p, pairs, fixed = state.particles, state.pairs, state.fixed
    count = int(pairs.count[0])
    i, j, force = (a[:count] for a in (pairs.i, pairs.j, pairs.force))
    shear = pairs.history.shape[0] > 0
    history, overlap, destroyed = (
        a[:count] for a in (pairs.history, pairs.overlap, pairs.destroyed)
    )
    pair_reads = [i, j, p.x, p.radius, p.material, p.mass]
    pair_writes = [p.f]
    gather_reads = [p.f, p.inv_mass, p.v]
    gather_writes = [p.v]  # without local damping (the benchmark's), the forces stay
    kick_reads, kick_writes = [p.f, p.inv_mass, p.v], [p.v]
    drift_reads, drift_writes = [p.v, p.x], [p.x]
    if shear:
        pair_reads += [p.v, p.omega, history]
        pair_writes += [history, destroyed, p.torque]
        gather_reads += [p.torque, p.inv_inertia, p.omega]
        gather_writes += [p.omega]
        kick_reads += [p.torque, p.inv_inertia, p.omega]
        kick_writes += [p.omega]
    if fixed.v.shape[0] > 0:  # the integers read and written beside their images
        spins = [fixed.omega] if shear else []
        if shear:  # the forces kept beside the histories (`forces.compute_forces`)
            pair_writes.append(force)
        gather_reads += [pairs.first, pairs.start, p.mass, fixed.v] + spins
        gather_writes += [fixed.v] + spins + ([p.torque] if shear else [])  # moments rounded
        kick_reads += [fixed.v] + spins
        kick_writes += [fixed.v] + spins
        drift_reads, drift_writes = [p.v, fixed.x], [fixed.x, p.x]
        if pairs.normal.shape[0] > 0:  # the normals the histories turn from, and to
            pair_reads.append(pairs.normal[:count])
            pair_writes += [pairs.normal[:count], overlap]

    def size(arrays: list) -> int:
        return sum(a.nbytes for a in arrays)

    return {
        "pair loop": size(pair_reads) + size(pair_writes),
        "gather": size(gather_reads) + size(gather_writes),
        "first half kick": size(kick_reads) + size(kick_writes),
        "drift": size(drift_reads) + size(drift_writes),
        "rebuild check": size([p.x, pairs.x_built, p.v, p.f]),
    }


def measure(n: int, variant: str, arithmetic: str) -> dict:
    """Each loop's seconds per step at n x n x n cells (see the module docstring)."""
    from revdem_cli.config import Scenario
    from revdem_cli.io.tape import no_tape
    from revdem_cli.kernels.contact import FORWARD
    from revdem_cli.kernels.forces import loop_arguments
    from revdem_cli.kernels.gather import complete_sums, damp_and_kick, damp_and_kick_on_grids
    from revdem_cli.kernels.integrate import OK, advance, drift, kick_particles, needs_rebuild
    from revdem_cli.kernels.pairs import pair_loop
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import empty_events, initial_state

    scenario = Scenario.model_validate(scenario_data(n, variant, 10 * STEPS, arithmetic))
    model, state = Model.of(scenario), initial_state(scenario)
    obs, obs_steps = model.buffers(2)
    events = empty_events()
    bundles = stepping_bundles(state, model, model.dynamics, model.law)
    p, pairs, walls, cell, fixed, law, moduli, dyn = bundles
    dt, skin = scenario.integrator.dt, model.skin

    def steps(count: int) -> None:
        stepping = model.stepping(dt, 0, 10 * STEPS, 10 * STEPS)
        stop = state.step + count
        status, state.step, _, _ = advance(
            *bundles, events, no_tape(), stepping, state.step, stop, stop, obs, obs_steps
        )
        if status != OK:
            raise RuntimeError(f"the stepping loop stopped with status {status}")

    steps(2)  # compile or load, and a first rebuild
    step_s = min(_timed(lambda: steps(STEPS)) for _ in range(REPEATS)) / STEPS
    particle_args, pair_args, _, sum_args, end_args = loop_arguments(
        p, pairs, walls, cell, fixed, law, moduli, dyn, FORWARD, dt, 0.0
    )
    length = cell.length
    image = (length[0], length[1], length[2], 1 / length[0], 1 / length[1], 1 / length[2])
    count = len(p.x)
    pair_call = (*particle_args, image, *pair_args, False)  # as between observables rows
    _, largest = pair_loop(count, *pair_call)  # what the gather takes

    def gather():  # what `forces.compute_forces` calls without walls
        if arithmetic == "float":
            return damp_and_kick(count, *end_args)
        complete_sums(count, *sum_args, largest, False)
        return damp_and_kick_on_grids(count, *end_args, fixed.v, fixed.omega, fixed.grid)

    seconds = {
        "pair loop": _best(lambda: pair_loop(count, *pair_call), STEPS),
        "gather": _best(gather, STEPS),
        "first half kick": _best(lambda: kick_particles(p, fixed, law, 0.0), STEPS),
        "drift": _best(lambda: drift(p, cell, fixed, 0.0, events, state.step), STEPS),
        "rebuild check": _best(lambda: needs_rebuild(p, pairs, cell, dt, skin, 1), STEPS),
    }
    seconds["rest of the step"] = max(step_s - sum(seconds.values()), 0.0)
    return {
        "n": n,
        "variant": variant,
        "arithmetic": arithmetic,
        "particles": count,
        "pairs": int(pairs.count[0]),
        "step_s": step_s,
        "particle_steps_per_s": count / step_s,
        "seconds": seconds,
        "bytes": traffic(state),
    }


def in_process(n: int, variant: str, arithmetic: str) -> dict:
    return measured_apart("roofline", n, variant, arithmetic)


def figure(rows: list[dict], bandwidth: float, png: Path) -> Path:
    """Each loop's time per particle-step, float and fixed point, beside the time its bytes
    take at the copy bandwidth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, variant in zip(axes, ("frictionless", "history"), strict=True):
        chosen = [r for r in rows if r["variant"] == variant]
        y = np.arange(len(LOOPS))
        for k, row in enumerate(chosen):
            ns = [1e9 * row["seconds"][loop] / row["particles"] for loop in LOOPS]
            ax.barh(y + 0.38 * k - 0.19, ns, height=0.36, label=row["arithmetic"])
        floor = [1e9 * chosen[0]["bytes"].get(loop, 0) / bandwidth / chosen[0]["particles"]
                 for loop in LOOPS]  # fmt: skip
        ax.scatter(floor, y - 0.19, marker="|", s=300, color="k", label="its bytes at copy speed")
        ax.set_yticks(y, LOOPS)
        ax.invert_yaxis()
        ax.set_xlabel("ns per particle-step (one core)")
        ax.set_title(f"fcc Hertz n = {chosen[0]['n']}, {variant}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    return png


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=24)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    arguments = parser.parse_args()
    bandwidth = copy_bandwidth()
    print(f"copy bandwidth, one core: {bandwidth / 1e9:.1f} GB/s")
    unit = divide_unit()
    print(f"divide unit, one core: a square root {1e9 * unit['square root']:.2f} ns, "
          f"a division {1e9 * unit['division']:.2f} ns (vectorised, an element); "
          f"a division {1e9 * unit['division, two threads at once']:.2f} ns with two threads "
          f"dividing at once (the same: each thread's core its own; twice: one core's two "
          f"hardware threads)")  # fmt: skip
    rows = []
    for variant in ("frictionless", "history"):
        for arithmetic in ("float", "fixed"):
            row = in_process(arguments.n, variant, arithmetic)
            rows.append(row)
            print(f"\n{variant}, {arithmetic}: {row['particle_steps_per_s']:.3g} particle-steps/s")
            print(f"  {'loop':<18} {'ns/particle':>11} {'share':>6} {'bytes/particle':>14} "
                  f"{'of bandwidth':>12}")  # fmt: skip
            for loop in LOOPS:
                seconds, moved = row["seconds"][loop], row["bytes"].get(loop)
                ns = 1e9 * seconds / row["particles"]
                share = seconds / row["step_s"]
                if moved is None:
                    print(f"  {loop:<18} {ns:11.1f} {share:6.1%}")
                    continue
                used = moved / seconds / bandwidth
                print(f"  {loop:<18} {ns:11.1f} {share:6.1%} {moved / row['particles']:14.0f} "
                      f"{used:12.2f}")  # fmt: skip
            if arithmetic == "float":
                row["contact_floor_s"] = contact_floor(row, unit)
                roots, divisions = ROOTS_AND_DIVISIONS[variant]
                floor = 1e9 * row["contact_floor_s"]
                print(f"  of the pair loop, its {roots} roots and {divisions} divisions a pair "
                      f"at the divide unit's speed: {floor:.1f} ns/particle")  # fmt: skip
    arguments.out.mkdir(parents=True, exist_ok=True)
    result = {"copy_bandwidth_bytes_per_s": bandwidth, "divide_unit_s": unit, "rows": rows}
    (arguments.out / "roofline.json").write_text(json.dumps(result, indent=2) + "\n")
    print(figure(rows, bandwidth, arguments.out / "roofline.png"))


if __name__ == "__main__":
    main()
