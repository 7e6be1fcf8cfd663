"""A whole run of a real packing, which the fcc benchmark (`fcc_hertz.py`) is not: `revdem run
configs/packings/dense_periodic.toml --no-reverse`, 4 000 spheres compacted and held by the
servo of a periodic cell, friction 0.05, 100 000 steps.

In the fcc lattice every pair listed touches, the cell is fixed and no sum is over more than
one thread's spheres; here a fifth of the pairs listed are apart, the servo sums the cell's
stress at every step, and the sums span several blocks (`kernels.sums`). The run is the
user's command, start-up and output included, on one thread and on two (`--threads`), in
turns, ROUNDS of each; the best wall time of each is kept, and the restarts of all the runs
must be the same bits (the state does not depend on the thread count).

    python benchmarks/packing.py [--threads 1 2] [--out benchmarks/results]

Results go to OUT/packing.json.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "packings" / "dense_periodic.toml"
ROUNDS = 2
REVDEM = str(Path(sys.executable).parent / "revdem")  # the command installed beside Python


def restart_digest(path: Path) -> str:
    """A digest of a restart's datasets, from the digest each carries (`io.restart`, which
    checks it on reading), in name order."""
    import h5py

    stored: list[str] = []
    with h5py.File(path, "r") as f:
        f.visititems(
            lambda name, item: (
                stored.append(f"{name} {item.attrs['sha256']}")
                if isinstance(item, h5py.Dataset)
                else None
            )
        )
    return hashlib.sha256("\n".join(sorted(stored)).encode()).hexdigest()[:16]


def timed_run(threads: int, out: Path) -> float:
    """Wall seconds of the run on `threads` threads, its outputs in `out`."""
    command = [REVDEM, "run", str(CONFIG), "--no-reverse", "--threads", str(threads), "--out",
               str(out), "-q", "--force"]  # fmt: skip
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from revdem_cli.api import load

    scenario = load(CONFIG).scenario
    steps = sum(stage.steps for stage in scenario.stages)
    spheres = sum(block.count for block in scenario.packings)
    seconds: dict[int, list[float]] = {threads: [] for threads in args.threads}
    digests = set()
    with tempfile.TemporaryDirectory() as scratch:
        timed_run(args.threads[0], Path(scratch))  # compile or load the kernels
        for _ in range(ROUNDS):
            for threads in args.threads:
                seconds[threads].append(timed_run(threads, Path(scratch)))
                digests.add(restart_digest(Path(scratch) / f"{scenario.name}.restart.h5"))
                print(f"{threads} thread(s): {seconds[threads][-1]:.1f} s", flush=True)
    rows = [
        {
            "threads": threads,
            "seconds_each": each,
            "particle_steps_per_s": spheres * steps / min(each),
        }
        for threads, each in seconds.items()
    ]
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "command": f"revdem run {CONFIG.relative_to(ROOT)} --no-reverse --threads T",
        "spheres": spheres,
        "steps": steps,
        "runs": rows,
        "bitwise_identical_across_threads": len(digests) == 1,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "packing.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {path}")
    if len(digests) != 1:
        sys.exit("the restarts differ between thread counts")


if __name__ == "__main__":
    main()
