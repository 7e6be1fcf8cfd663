"""The cost of the information tape ([reversal] tape = true) on the fcc Hertz benchmark
(benchmarks/fcc_hertz.py) in fixed-point arithmetic: the forward stepping loop recording
the tape (blocks written out to a file as they fill) against the same loop without it.

n x n x n fcc cells, Mindlin shear springs (mu = 0.5, `history`) or none
(`frictionless`); each measurement in a process of its own (its thread count, its
memory): the loop's particle-steps per second (best of REPEATS, set-up and compilation
excluded), the peak memory per sphere above what the process held before the spheres
were made, and for the tape its bytes and bits per step. The REPEATS timings follow one
another from the same start, so that with the tape each covers other steps of one run:
with history the lattice's contacts start to slip after some 150 steps (n = 24), and
the tape's cost then grows with its entries; each timing's cost is reported beside the
entries per step it recorded (`cost_each`, `entries_per_step_each`). The costs come from
a process of their own that steps the run without the tape and the run with it in turns
(`interleaved`, `fcc_hertz.in_turns`), so that both meet the same machine: on a shared
one the speed of separate processes moves by a tenth and more from minute to minute.
`cost` is that of the benchmark's own steps, the first timing. Results: OUT/tape_cost.json.

    NUMBA_NUM_THREADS=1 python benchmarks/tape_cost.py [--n 10 24]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from fcc_hertz import REPEATS, STEPS, _rss, in_turns, measured_apart, scenario_data  # noqa: E402


def taped(n: int, variant: str, steps: int, tape: bool) -> dict:
    data = scenario_data(n, variant, steps, "fixed")
    data["reversal"] = {"tape": tape}
    return data


def stepped(state, model, steps: int, recorder, finish: bool = True) -> float:
    """Seconds of `steps` forward steps of the compiled stage loop, recording into
    `recorder` (`io.tape.Recorder`, its blocks written out as they fill; `finish`: the last
    block too, waited for) or without a tape."""
    from revdem_cli.io.tape import no_tape
    from revdem_cli.kernels.integrate import OK, TAPE_FULL, advance
    from revdem_cli.stage import stepping_bundles
    from revdem_cli.state import empty_events

    obs, obs_steps = model.buffers(2)
    first = state.step
    stepping = model.stepping(1.0e-6, first, first + steps, steps)
    events = empty_events()
    started = time.perf_counter()
    while state.step != first + steps or recorder and recorder.retaking:
        tape = recorder.bundle(state, events, model.law, model.dynamics) if recorder else no_tape()
        bundles = stepping_bundles(state, model, model.dynamics, model.law, tape)
        status, state.step, _, _ = advance(
            *bundles, events, tape, stepping, state.step, first + steps, first + steps, obs,
            obs_steps,
        )  # fmt: skip
        if status == TAPE_FULL:
            recorder.flush()
        elif status != OK:
            raise RuntimeError(f"the stepping loop stopped with status {status}")
    if recorder and finish:
        recorder.flush(wait=True)
    return time.perf_counter() - started


def warm_up(folder: Path, variant: str, tape: bool) -> None:
    """Compile the stepping loop (or load it from the cache): one step of a small lattice."""
    from revdem_cli.config import Scenario
    from revdem_cli.io.tape import Recorder
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    warm = Scenario.model_validate(taped(2, variant, 1, tape))
    state = initial_state(warm)
    recorder = Recorder(folder / "warm.h5", "run", (0, 0.0, 1.0e-6), state) if tape else None
    stepped(state, Model.of(warm), 1, recorder)


def measure(n: int, variant: str, tape: bool) -> dict:
    from revdem_cli.config import Scenario
    from revdem_cli.io.tape import Recorder, summary
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    steps = STEPS.get(n, 200)
    with tempfile.TemporaryDirectory() as folder:
        warm_up(Path(folder), variant, tape)
        clock = (0, 0.0, 1.0e-6)
        baseline = _rss("VmRSS")
        Path("/proc/self/clear_refs").write_text("5")  # peak memory from here on
        scenario = Scenario.model_validate(taped(n, variant, steps * REPEATS, tape))
        model, state = Model.of(scenario), initial_state(scenario)
        path = Path(folder) / "tape.h5"
        recorder = Recorder(path, "run", clock, state) if tape else None
        loops, entries = [], []
        for _ in range(REPEATS):
            loops.append(stepped(state, model, steps, recorder))
            entries.append(recorder.written_entries if tape else 0)
        loop = min(loops)
        count = len(state.particles.x)
        row = {
            "n": n,
            "variant": variant,
            "tape": tape,
            "particles": count,
            "steps": steps,
            "threads": int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count())),
            "loop_s": loop,
            "loop_s_each": loops,
            "particle_steps_per_s": count * steps / loop,
            "peak_bytes_per_particle": (_rss("VmHWM") - baseline) / count,
        }
        if tape:
            recorded = summary(path)
            row["tape_bytes_per_step"] = recorded["bytes"] / recorded["steps"]
            row["bits_per_step"] = recorded["bits_per_step"]
            row["size_over_full_state"] = recorded["size_over_full_state"]
            row["entries_per_step_each"] = list(np.diff(entries, prepend=0) / steps)
    return row


def interleaved(n: int, variant: str) -> dict:
    """Seconds of each of REPEATS stretches of the benchmark's steps without the tape and
    with it: two runs from one start, stepped in turns (`fcc_hertz.in_turns`), the tape's
    writer finishing each stretch inside its time."""
    from revdem_cli.config import Scenario
    from revdem_cli.io.tape import Recorder
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    steps = STEPS.get(n, 200)
    with tempfile.TemporaryDirectory() as folder:
        runs = {}
        for tape in (False, True):
            warm_up(Path(folder), variant, tape)
            scenario = Scenario.model_validate(taped(n, variant, steps * REPEATS, tape))
            state = initial_state(scenario)
            clock = (0, 0.0, 1.0e-6)
            recorder = Recorder(Path(folder) / "tape.h5", "run", clock, state) if tape else None
            model = Model.of(scenario)
            runs[tape] = lambda count, last, s=state, m=model, r=recorder: stepped(
                s, m, count, r, last
            )
        seconds = in_turns(runs, steps)
    return {"without_s_each": seconds[False], "with_s_each": seconds[True]}


def in_process(n: int, variant: str, tape: bool) -> dict:
    return measured_apart("tape_cost", n, variant, tape)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, nargs="+", default=[10, 24])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    arguments = parser.parse_args()
    rows = []
    print(f"{'n':>3} {'variant':>12} {'without':>10} {'with tape':>10} {'cost':>5} {'B/sphere':>9}"
          "  cost (entries/step) of each timing")  # fmt: skip
    for n in arguments.n:
        for variant in ("frictionless", "history"):
            bare, recorded = in_process(n, variant, False), in_process(n, variant, True)
            turns = measured_apart("tape_cost", n, variant, function="interleaved")
            recorded["interleaved"] = turns
            recorded["cost_each"] = [
                t / b for t, b in zip(turns["with_s_each"], turns["without_s_each"], strict=True)
            ]
            recorded["cost"] = recorded["cost_each"][0]
            rows += [bare, recorded]
            print(
                f"{n:3d} {variant:>12} {bare['particle_steps_per_s']:10.3g} "
                f"{recorded['particle_steps_per_s']:10.3g} {recorded['cost']:5.2f} "
                f"{bare['peak_bytes_per_particle']:4.0f}/{recorded['peak_bytes_per_particle']:4.0f}"
                + "".join(
                    f"  {c:.2f} ({e:.0f})"
                    for c, e in zip(
                        recorded["cost_each"], recorded["entries_per_step_each"], strict=True
                    )
                )
            )
    arguments.out.mkdir(parents=True, exist_ok=True)
    (arguments.out / "tape_cost.json").write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
