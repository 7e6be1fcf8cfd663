"""Parameter sweeps: every combination of `--set key=v1,v2,...` values run (forward and
reversed) in parallel on a dask.distributed cluster, one table of results.

Each variant runs in its own folder under the sweep's output directory. The results table
(`sweep.csv` and `sweep.h5`) holds, per variant, its folder, the values set, the verdict of
the reversal and the final kinetic and total energies of the forward run.

A sweep file is a TOML file with `kind = "sweep"`, the scenario it varies (a path relative
to the file) and the same `set` strings as the command line (a field is set once in each; a
`--set` given with the file replaces the file's values of its field):

    kind = "sweep"
    scenario = "../collision_shear.toml"
    set = ["contact.friction=0.1,0.3,1.0,inf"]
"""

from __future__ import annotations

import csv
import itertools
import math
import re
import time
import tomllib
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from revdem_cli.errors import InputError, check_regular

KIND = "sweep"
RESULTS = (
    "reversible",
    "max_position_error_rel",
    "first_divergence_step",
    "kinetic_energy",
    "total_energy",
    "seconds",
    "error",
)
"""Result columns of the table, after the folder and the values set."""


@dataclass(frozen=True)
class Sweep:
    scenario: Path
    grid: dict[str, list[str]]  # key -> values, in the order given

    def variants(self) -> list[dict[str, str]]:
        keys = list(self.grid)
        return [
            dict(zip(keys, values, strict=True))
            for values in itertools.product(*self.grid.values())
        ]


def split_values(raw: str) -> list[str]:
    """`a,b,[c,d]` -> ['a', 'b', '[c,d]']: commas inside brackets or quotes stay."""
    values, depth, quote, current = [], 0, "", []
    for char in raw:
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            values.append("".join(current))
            current = []
            continue
        current.append(char)
    values.append("".join(current))
    return [value.strip() for value in values]


def parse_sets(sets: list[str], origin: str = "") -> dict[str, list[str]]:
    """`["a.b=1,2", "c=x"]` -> {"a.b": ["1", "2"], "c": ["x"]}, each value read as a `--set`
    value is (`config.read_value`); a key given twice is refused. `origin` is the sweep file
    whose `set` list the strings are, named with the entry in errors (FILE: set[1]), or ""
    for the command line's --set options."""
    from revdem_cli.config import read_value

    grid: dict[str, list[str]] = {}
    given: dict[str, str] = {}  # key -> the string that set it
    for index, item in enumerate(sets):
        entry = f"set[{index}] = {item!r}" if origin else f"--set {item}"
        where = f"{origin}: {entry}" if origin else entry
        key, sep, raw = item.partition("=")
        key, values = key.strip(), split_values(raw)
        if not sep or not key or "" in values:
            raise InputError(f"{where}: expected key=value or key=value1,value2,...")
        if key in grid:
            raise InputError(
                f"{where}: {key} is given twice (also in {given[key]}); give its values "
                f"together, {key}=V1,V2,..."
            )
        for value in values:
            read_value(value, where)
        grid[key], given[key] = values, entry
    return grid


def read_sweep(path: Path, sets: list[str]) -> Sweep:
    """The sweep of a sweep file (`read_sweep_file`) or of a scenario file, with `sets`."""
    return read_sweep_file(path, sets) or Sweep(Path(path), parse_sets(sets))


def read_sweep_file(path: Path, sets: list[str]) -> Sweep | None:
    """The sweep of a sweep file, its `set` list with the command line's `sets` added (a key
    set there replaces the file's values of it); None if the file is not a sweep file."""
    path = Path(path)
    data = _sweep_fields(path)
    if data is None:
        return None
    unknown = set(data) - {"kind", "scenario", "set"}
    if unknown or not isinstance(data.get("scenario"), str):
        raise InputError(
            f"{path}: a sweep file has kind, scenario (a path) and set (a list)"
            + (f"; unknown: {', '.join(sorted(unknown))}" if unknown else "")
        )
    entries = data.get("set", [])
    if not isinstance(entries, list) or not all(isinstance(item, str) for item in entries):
        raise InputError(
            f'{path}: set: expected a list of "field=v1,v2,..." strings, got {entries!r:.80}'
        )
    scenario = path.parent / data["scenario"]
    if _sweep_fields(scenario) is not None:
        raise InputError(
            f"{path}: scenario: {data['scenario']} is a sweep file; the scenario of a sweep "
            "cannot be a sweep"
        )
    return Sweep(scenario, parse_sets(entries, str(path)) | parse_sets(sets))


def _sweep_fields(path: Path) -> dict | None:
    """The fields of the sweep file at `path`; None if it is not one (a scenario, a study, a
    file that cannot be read: their readers say what is wrong)."""
    check_regular(path, "scenario file")
    if path.suffix.lower() != ".toml":
        return None
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    return data if data.get("kind") == KIND else None


def folder_name(index: int, variant: dict[str, str]) -> str:
    """`003_friction=0.3_steps=1000`: the index and the last part of each varied key with its
    value (commas as +, other characters than letters, digits and .=+- left out)."""
    parts = [f"{key.rsplit('.', 1)[-1]}={value}" for key, value in variant.items()]
    name = "_".join([f"{index:03d}", *parts]).replace(",", "+")
    return re.sub(r"[^\w.=+-]", "", name)


def run_variant(
    scenario_json: str, text: str, suffix: str, out_dir: Path, allow_unstable_dt: bool = False
) -> dict:
    """Run one variant (its validated scenario as JSON) forward and reversed into `out_dir`
    (`allow_unstable_dt`: at a time step above the critical estimate too); its results (a
    row of RESULTS). Runs on a worker; a failure is recorded, not raised."""
    from revdem_cli.config import Scenario
    from revdem_cli.engine import run_scenario
    from revdem_cli.io.h5md import open_trajectory, read_observable

    started = time.perf_counter()
    row = dict.fromkeys(RESULTS)
    try:
        scenario = Scenario.model_validate_json(scenario_json)
        outputs = run_scenario(
            scenario, text, suffix, Path(out_dir), reverse=True, allow_unstable_dt=allow_unstable_dt
        )
    except (InputError, RuntimeError, OSError, MemoryError) as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    with open_trajectory(outputs.forward) as f:
        row["kinetic_energy"] = float(read_observable(f, "kinetic_energy")[1][-1])
        row["total_energy"] = float(read_observable(f, "total_energy")[1][-1])
    if outputs.verdict is not None:
        for key in ("reversible", "max_position_error_rel", "first_divergence_step"):
            row[key] = outputs.verdict[key]
    row["seconds"] = time.perf_counter() - started
    return row


@contextmanager
def _client(scheduler: str | None, workers: int, threads: int | None):
    """A client of the scheduler at `scheduler`, or of a new local cluster of processes with
    one single-threaded worker a process, each variant's loops on `threads` threads (default:
    the cores this process may use over the workers) (closed afterwards)."""
    from distributed import Client, LocalCluster

    from revdem_cli.threads import available

    if scheduler:
        with Client(scheduler) as client:
            yield client
        return
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env={"NUMBA_NUM_THREADS": str(threads or max(1, available() // workers))},
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def load_variants(sweep: Sweep, host: bool = False, allow_unstable_dt: bool = False) -> list[tuple]:
    """(scenario, text) of every variant, each validated and its time step checked (unless
    `allow_unstable_dt`); with `host`, each also checked against this machine's memory
    (`config.host`)."""
    from revdem_cli.config import load_scenario
    from revdem_cli.engine import check_time_step

    loaded = []
    for variant in sweep.variants():
        sets = [f"{key}={value}" for key, value in variant.items()]
        try:  # a variant's error names its values: which of a list is at fault
            scenario, text = load_scenario(sweep.scenario, sets, host)
            if not allow_unstable_dt:
                check_time_step(scenario, str(sweep.scenario))
        except InputError as exc:
            raise InputError(f"variant {', '.join(sets)}: {exc}") from None
        loaded.append((scenario, text))
    return loaded


def run_sweep(
    sweep: Sweep,
    out_dir: Path,
    scheduler: str | None = None,
    workers: int = 2,
    progress: Callable[[str, int, int], None] | None = None,
    threads: int | None = None,
    allow_unstable_dt: bool = False,
    force: bool = False,
) -> tuple[list[dict], list[Path]]:
    """Run every variant (`allow_unstable_dt`: those whose time step is above the critical
    estimate too); returns the table's rows and the table files written. An earlier sweep's
    tables or a variant's earlier outputs in `out_dir` are refused unless `force`, as
    `revdem run` refuses a run's (`api.keep_outputs`)."""
    from distributed import as_completed

    out_dir = Path(out_dir)
    variants = sweep.variants()
    # bad input stops the sweep before it starts; a local cluster runs on this machine
    loaded = load_variants(sweep, scheduler is None, allow_unstable_dt)
    varying = [key for key, values in sweep.grid.items() if len(values) > 1]
    folders = [
        folder_name(index, {key: variant[key] for key in varying})
        for index, variant in enumerate(variants)
    ]
    from revdem_cli.api import keep_outputs, output_paths_of

    earlier = [out_dir / "sweep.csv", out_dir / "sweep.h5"]
    for (scenario, _), folder in zip(loaded, folders, strict=True):
        earlier += output_paths_of(scenario, out_dir / folder, reverse=True)
    keep_outputs(earlier, force, "sweep")
    suffix = sweep.scenario.suffix.lower()
    results: dict[int, dict] = {}
    with _client(scheduler, workers, threads) as client:
        futures = {
            client.submit(
                run_variant,
                scenario.model_dump_json(),
                text,
                suffix,
                out_dir / folder,
                allow_unstable_dt,
                key=f"variant-{folder}",
            ): index
            for index, ((scenario, text), folder) in enumerate(zip(loaded, folders, strict=True))
        }
        for future in as_completed(futures):
            results[futures[future]] = future.result()
            if progress is not None:
                progress("variants", len(results), len(variants))
    rows = [{"folder": folders[i], **variants[i], **results[i]} for i in range(len(variants))]
    return rows, write_table(rows, out_dir / "sweep")


def write_table(rows: list[dict], stem: Path) -> list[Path]:
    """Write rows as STEM.csv and STEM.h5 (/sweep/<column>: text as strings; numbers as
    float64 with NaN where missing; reversible as 1, 0 or NaN)."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    columns = list(rows[0])
    csv_path, h5_path = stem.with_suffix(".csv"), stem.with_suffix(".h5")
    with csv_path.open("w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    with h5py.File(h5_path, "w") as f:
        group = f.create_group("sweep")
        group.attrs["columns"] = columns
        for column in columns:
            values = [row[column] for row in rows]
            if column in RESULTS and column != "error":
                group[column] = np.array([math.nan if v is None else float(v) for v in values])
            else:
                text = ["" if v is None else str(v) for v in values]
                group.create_dataset(column, data=text, dtype=h5py.string_dtype())
    return [csv_path, h5_path]
