"""Parameter sweeps: every combination of `--set key=v1,v2,...` values run (forward and
reversed) in parallel on a dask.distributed cluster, one table of results.

Each variant runs in its own folder under the sweep's output directory. The results table
(`sweep.csv` and `sweep.h5`) holds, per variant, its folder, the values set, its status,
the verdict of the reversal and the final kinetic and total energies of the forward run.
SIGINT or SIGTERM stops the running variants with checkpoints (`checkpoint.first_signal`
writes the stop file their runs poll) and writes the table; `--resume` goes on from it
(`_earlier_results`).

A sweep file is a TOML file with `kind = "sweep"`, the scenario it varies (a path relative
to the file) and the same `set` strings as the command line (a field is set once in each; a
`--set` given with the file replaces the file's values of its field):

    kind = "sweep"
    scenario = "../collision_shear.toml"
    set = ["contact.friction=0.1,0.3,1.0,inf"]
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import re
import time
import tomllib
import warnings
from collections.abc import Callable
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from revdem_cli.errors import InputError, check_regular, not_a_folder
from revdem_cli.io.lock import FolderHeld, sole_writer

KIND = "sweep"
LOCAL_WORKERS = 2
"""Worker processes of the local cluster a sweep starts where it is given no --workers."""
RESULTS = (
    "status",
    "reversible",
    "max_position_error_rel",
    "first_divergence_step",
    "kinetic_energy",
    "total_energy",
    "seconds",
    "error",
)
"""Result columns of the table, after the folder and the values set."""
DONE, FAILED, STOPPED, NOT_STARTED = "done", "failed", "stopped", "not started"
"""A variant's status: run to its end (or read as an earlier sweep left it, `--resume`),
failed (its `error` says why), stopped by a signal with a checkpoint in its folder, or not
begun before the sweep stopped."""
TEXT = ("status", "error")
"""The result columns of text."""
KIND_OF_TABLE = "revdem sweep"
"""The `kind` attribute of a sweep's STEM.h5, which `revdem info` summarises."""
STOP_FILE = ".stop"
"""In the sweep's folder while it stops: the variants' runs poll it (`checkpoint.polling`)."""


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
    from revdem_cli.config import dotted, read_value

    grid: dict[str, list[str]] = {}
    given: dict[str, str] = {}  # key -> the string that set it
    for index, item in enumerate(sets):
        entry = f"set[{index}] = {item!r}" if origin else f"--set {item}"
        where = f"{origin}: {entry}" if origin else entry
        key, sep, raw = item.partition("=")
        key, values = dotted(key), split_values(raw)
        if not sep or not key or "" in values:
            raise InputError(f"{where}: expected key=value or key=value1,value2,...")
        twice = next((value for k, value in enumerate(values) if value in values[:k]), None)
        if twice is not None:
            raise InputError(f"{where}: {key}: {twice} is given twice; a variant runs once")
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
    file that cannot be read: their readers say what is wrong). InputError for a file of
    another format that says it is one (`config.check_no_kind`), before it is taken for a
    scenario that sets no kind."""
    from revdem_cli.config import parse_text
    from revdem_cli.config.loader import check_no_kind

    check_regular(path, "scenario file")
    toml = path.suffix.lower() == ".toml"
    try:
        text = path.read_text()
        data = tomllib.loads(text) if toml else parse_text(text, path.suffix.lower(), str(path))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, InputError):
        return None
    if data.get("kind") != KIND:
        return None
    if not toml:
        check_no_kind(data, str(path))
    return data


def folder_name(index: int, variant: dict[str, str]) -> str:
    """`003_friction=0.3_steps=1000`: the index and the last part of each varied key with its
    value (commas as +, other characters than letters, digits and .=+- left out)."""
    parts = [f"{key.rsplit('.', 1)[-1]}={value}" for key, value in variant.items()]
    name = "_".join([f"{index:03d}", *parts]).replace(",", "+")
    return re.sub(r"[^\w.=+-]", "", name)


def run_variant(
    scenario_json: str,
    text: str,
    suffix: str,
    out_dir: Path,
    allow_unstable_dt: bool = False,
    stop_file: Path | None = None,
    threads: int | None = None,
) -> dict:
    """Run one variant (its validated scenario as JSON) forward and reversed into `out_dir`,
    or on from the checkpoint there (`allow_unstable_dt`: at a time step above the critical
    estimate too), on at most `threads` threads (`api.use_threads`: a count above the
    worker's pool fails the variant, as it does a run); its results (a row of RESULTS).
    Runs on a worker; a failure is recorded, not raised. Once `stop_file` exists, the run
    stops at its next whole step with a checkpoint, and a variant not yet begun is not
    begun. The variant holds `out_dir` while it runs (`io.lock.sole_writer`): a `revdem run`
    into it meanwhile is refused, and it fails where one holds it."""
    from revdem_cli.api import use_threads
    from revdem_cli.checkpoint import Interrupted, find_checkpoints, stop_asked
    from revdem_cli.config import Scenario
    from revdem_cli.engine import resume_run, run_scenario

    started = time.perf_counter()
    row = dict.fromkeys(RESULTS)
    if stop_asked(stop_file):
        row["status"] = NOT_STARTED
        return row
    out_dir = Path(out_dir)
    try:
        use_threads(threads)
        with sole_writer(out_dir, str(out_dir)):
            if find_checkpoints(out_dir):
                outputs = resume_run(out_dir, stop_file=stop_file)
            else:
                scenario = Scenario.model_validate_json(scenario_json)
                outputs = run_scenario(
                    scenario, text, suffix, out_dir, True, None, allow_unstable_dt, stop_file
                )
    except FolderHeld as exc:  # the files there are the other process's, not this variant's
        row["status"], row["error"] = FAILED, f"{type(exc).__name__}: {exc}"
        return row
    except Interrupted as exc:
        row["status"], row["error"] = STOPPED, f"stopped: {exc}"
        return row
    except (InputError, RuntimeError, OSError, MemoryError) as exc:
        row = _forward_row(out_dir, scenario_json, time.perf_counter() - started)
        row["status"], row["error"] = FAILED, f"{type(exc).__name__}: {exc}"
        return row
    return _done_row(outputs.forward, outputs.verdict, time.perf_counter() - started)


def _forward_row(out_dir: Path, scenario_json: str, seconds: float) -> dict:
    """The row of RESULTS of a variant that failed: where its forward run had ended (its
    restart written) and its reversal failed, the forward run's final energies and the
    seconds it took; else empty."""
    from revdem_cli.config import Scenario
    from revdem_cli.engine import output_paths

    paths = output_paths(out_dir, Scenario.model_validate_json(scenario_json).name)
    if not (paths["restart"].exists() and paths["forward"].exists()):
        return dict.fromkeys(RESULTS)
    return _done_row(paths["forward"], None, seconds)


def _done_row(forward: Path, verdict: dict | None, seconds: float | None) -> dict:
    """The row of RESULTS of a variant done: its final energies from its forward trajectory,
    its `verdict` and the `seconds` it took."""
    from revdem_cli.io.h5md import open_trajectory, read_observable

    row = dict.fromkeys(RESULTS)
    with open_trajectory(forward) as f:
        row["kinetic_energy"] = float(read_observable(f, "kinetic_energy")[1][-1])
        row["total_energy"] = float(read_observable(f, "total_energy")[1][-1])
    if verdict is not None:
        for key in ("reversible", "max_position_error_rel", "first_divergence_step"):
            row[key] = verdict[key]
    row["status"], row["seconds"] = DONE, seconds
    return row


@contextmanager
def _client(scheduler: str | None, workers: int, threads: int | None):
    """A client of the scheduler at `scheduler`, or of a new local cluster of processes with
    one single-threaded worker a process, each variant's loops on `threads` threads (default:
    the cores this process may use over the workers) (closed afterwards)."""
    from distributed import Client, LocalCluster

    from revdem_cli.threads import available

    if scheduler:
        try:
            client = Client(scheduler)
        except ValueError as exc:  # not an address; one that does not answer is an OSError
            raise InputError(f"--scheduler {scheduler}: {exc}") from None
        with client:
            yield client
        return
    with ExitStack() as stack:
        with _born_deaf(), warnings.catch_warnings():
            # its scheduler serves HTTP on 8787, else on a free port, with a warning that a
            # sweep's user has no use for: no dashboard is started (dashboard_address=None)
            warnings.filterwarnings("ignore", message=r"Port \d+ is already in use")
            cluster = stack.enter_context(
                LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    env={"NUMBA_NUM_THREADS": str(threads or max(1, available() // workers))},
                )
            )
        client = stack.enter_context(Client(cluster))
        client.register_plugin(_deaf_to_signals())
        yield client


@contextmanager
def _born_deaf():
    """SIGINT and SIGTERM blocked in this thread while a local cluster starts: the threads
    it starts and the processes they start (nannies, workers: a signal mask is inherited
    across fork and exec) are born with them blocked, so that Ctrl-C, which reaches every
    process of the terminal's group, cannot end a worker still starting (dask then failed,
    "Nanny failed to start", or waited for it for minutes). This process takes a signal
    that came meanwhile as the mask is restored: the stop file (`checkpoint.first_signal`),
    no variant started. The resource tracker of multiprocessing is started first: starting
    it unblocks both signals in the thread that starts it (`resource_tracker.ensure_running`),
    which would be the one that then starts the workers."""
    import signal
    from multiprocessing import resource_tracker

    from revdem_cli.checkpoint import SIGNALS

    resource_tracker.ensure_running()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _deaf_to_signals():
    """A plugin that has a local cluster's workers, and those that replace them, ignore
    SIGINT and SIGTERM: Ctrl-C reaches every process of the terminal's group, as SLURM's
    scancel and systemd send SIGTERM to every process of the job, and either would end each
    worker with its variant unsaved; the sweep stops them through its stop file
    (`checkpoint.first_signal`) instead. Their nanny closes them by its own queue, and kills
    them with SIGKILL, never SIGTERM. (Made here, where dask is imported; cloudpickle sends
    it.)"""
    from distributed import WorkerPlugin

    class DeafToSignals(WorkerPlugin):
        def setup(self, worker):
            import signal

            from revdem_cli.checkpoint import SIGNALS

            for kind in SIGNALS:  # on the worker's loop: its main thread
                signal.signal(kind, signal.SIG_IGN)

    return DeafToSignals()


def load_variants(sweep: Sweep, host: bool = False, allow_unstable_dt: bool = False) -> list[tuple]:
    """(scenario, text) of every variant, each validated and its time step checked (unless
    `allow_unstable_dt`); with `host`, each also checked against this machine's memory
    (`config.host`)."""
    from revdem_cli.config import load_scenario
    from revdem_cli.config.loader import read_scenario_text
    from revdem_cli.engine import check_time_step

    read_scenario_text(sweep.scenario)  # a file that cannot be read is no variant's fault
    loaded = []
    for variant in sweep.variants():
        sets = [f"{key}={value}" for key, value in variant.items()]
        try:  # a variant's error names its values: which of a list is at fault
            scenario, text = load_scenario(sweep.scenario, sets, host)
            if not allow_unstable_dt:
                check_time_step(scenario, str(sweep.scenario))
        except InputError as exc:  # a sweep of no values has one variant, the file's
            raise InputError(f"variant {', '.join(sets)}: {exc}" if sets else str(exc)) from None
        loaded.append((scenario, text))
    return loaded


def run_sweep(
    sweep: Sweep,
    out_dir: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    threads: int | None = None,
    allow_unstable_dt: bool = False,
    force: bool = False,
    resume: bool = False,
) -> tuple[list[dict], list[Path], int]:
    """Run every variant (`allow_unstable_dt`: those whose time step is above the critical
    estimate too) on the scheduler at `scheduler` or on a local cluster of `workers`
    processes (default `LOCAL_WORKERS`); returns the table's rows, the table files written
    and the signal that stopped the sweep (0 if none). An earlier sweep's tables or a
    variant's earlier outputs in `out_dir` are refused unless `force`, as `revdem run`
    refuses a run's (`api.keep_outputs`), or `resume`, which goes on with the earlier sweep:
    a variant done there is kept as its table has it, a stopped one goes on from its
    checkpoint, any other runs.

    SIGINT or SIGTERM stops the sweep: each running variant at its next whole step with a
    checkpoint, none begins after, and the table says which are done, stopped or not
    started; a second signal stops at once."""
    from revdem_cli.api import check_threads

    if resume and force:
        raise InputError(
            "--resume goes on with the sweep in --out, --force starts it over: give one"
        )
    _check_cluster(scheduler, workers)
    check_threads(threads, here=scheduler is None)  # a local cluster's workers are here
    out_dir = Path(out_dir)
    if problem := not_a_folder(out_dir):  # before its stop file is named in an error
        raise InputError(f"--out {problem}")
    variants = sweep.variants()
    # bad input stops the sweep before it starts; a local cluster runs on this machine
    loaded = load_variants(sweep, scheduler is None, allow_unstable_dt)
    varying = [key for key, values in sweep.grid.items() if len(values) > 1]
    folders = [
        folder_name(index, {key: variant[key] for key in varying})
        for index, variant in enumerate(variants)
    ]
    for folder in folders:  # as `revdem run` refuses its --out, before any variant runs
        if problem := not_a_folder(out_dir / folder):
            raise InputError(problem)
    with sole_writer(out_dir):  # another sweep's or run's writes: refused
        if resume:
            results = _earlier_results(out_dir, loaded, folders)
        else:
            _keep_earlier(out_dir, loaded, folders, force)
            results = {}
        stopped = _run_pending(
            [
                (loaded[i], out_dir / folders[i], i)
                for i in range(len(variants))
                if i not in results
            ],
            results,
            len(variants),
            out_dir / STOP_FILE,
            (scheduler, LOCAL_WORKERS if workers is None else workers, threads),
            sweep.scenario.suffix.lower(),
            allow_unstable_dt,
            progress,
        )
        rows = [{"folder": folders[i], **variants[i], **results[i]} for i in range(len(variants))]
        return rows, write_table(rows, out_dir / "sweep"), stopped


def _check_cluster(scheduler: str | None, workers: int | None) -> None:
    """A worker count is a local cluster's: a scheduler's workers are those started for it,
    as a dask Client of an address starts none, so the two together are refused."""
    if scheduler is not None and workers is not None:
        raise InputError(
            f"--workers {workers} sizes a local cluster; the variants run on the workers of "
            f"--scheduler {scheduler}, as many as were started for it (e.g. `dask worker "
            f"{scheduler} --nworkers {workers}`): leave out --workers"
        )


def _run_pending(
    pending: list[tuple],
    results: dict[int, dict],
    total: int,
    stop_file: Path,
    cluster: tuple,
    suffix: str,
    allow_unstable_dt: bool,
    progress,
) -> int:
    """Run the variants `pending` ((scenario, text), folder, index) on the cluster
    (scheduler, workers, threads), each row into `results` by index as it comes; the signal
    that stopped them, 0 if none. No cluster is started for none."""
    from distributed import as_completed

    from revdem_cli.checkpoint import ask_to_stop, first_signal, stop_asked

    def ended() -> int:  # the variants run to their end: stopped and not started are not
        return sum(row["status"] in (DONE, FAILED) for row in results.values())

    if progress is not None:
        progress("variants", ended(), total)
    if not pending:
        return 0
    threads = cluster[2]  # each variant's count, set on its worker (`run_variant`)
    stop_file.unlink(missing_ok=True)
    try:  # a signal while the cluster starts stops the sweep before any variant begins
        with (
            first_signal(lambda signum: ask_to_stop(stop_file, signum)),
            _client(*cluster) as client,
        ):
            futures = {
                client.submit(
                    run_variant,
                    scenario.model_dump_json(),
                    text,
                    suffix,
                    folder,
                    allow_unstable_dt,
                    stop_file,
                    threads,
                    key=f"variant-{folder.name}",
                ): index
                for (scenario, text), folder, index in pending
            }  # asked to stop already, each is not started
            for future in as_completed(futures):
                results[futures[future]] = _result_of(future)
                if progress is not None:
                    progress("variants", ended(), total)
        return stop_asked(stop_file)
    finally:
        stop_file.unlink(missing_ok=True)


def stop_summary(rows: list[dict]) -> str:
    """How the variants of a sweep a signal stopped stand, by their rows' status: what
    `revdem sweep` prints and `api.sweep`'s Interrupted says."""
    count = {status: sum(row["status"] == status for row in rows) for status in
             (DONE, STOPPED, NOT_STARTED)}  # fmt: skip
    return (
        f"{count[DONE]} variants done, {count[STOPPED]} stopped with a checkpoint, "
        f"{count[NOT_STARTED]} not started"
    )


def _result_of(future) -> dict:
    """A variant's row from its future; one that raised where `run_variant` records no
    failure (a worker lost, a defect) is a failed row saying so, so that the table keeps
    the other variants."""
    try:
        return future.result()
    except Exception as exc:
        row = dict.fromkeys(RESULTS)
        row["status"], row["error"] = FAILED, f"{type(exc).__name__}: {exc}"
        return row


def _keep_earlier(out_dir: Path, loaded: list[tuple], folders: list[str], force: bool) -> None:
    """Refuse an earlier sweep's tables and its variants' outputs and checkpoints in
    `out_dir` unless `force`; forced, remove them, and the runs of the earlier sweep's other
    variants (`_runs_left`)."""
    from revdem_cli.api import keep_outputs

    earlier = [out_dir / "sweep.csv", out_dir / "sweep.h5"]
    for (scenario, _), folder in zip(loaded, folders, strict=True):
        earlier += _run_files(scenario, out_dir / folder)
    left = _runs_left(out_dir, folders) if force else {}
    keep_outputs(earlier + [path for paths in left.values() for path in paths], force, "sweep")
    for folder in left:
        if not any(folder.iterdir()):  # what else is there is not the sweep's
            folder.rmdir()


def _runs_left(out_dir: Path, folders: list[str]) -> dict[Path, list[Path]]:
    """The files of the runs in each variant folder of the earlier sweep in `out_dir` (its
    table's) that is not one of `folders`, those of another sweep forced over it: each
    run's outputs and checkpoint, from the scenario its forward trajectory or checkpoint
    stores."""
    from revdem_cli.checkpoint import find_checkpoints
    from revdem_cli.config import Scenario

    table = out_dir / "sweep.h5"
    left = {}
    for name in sorted(read_table(table).keys() - set(folders)) if table.exists() else []:
        folder = out_dir / name
        runs = [*find_checkpoints(folder), *sorted(folder.glob("*.forward.h5"))]
        left[folder] = [
            path
            for run in runs
            for path in _run_files(Scenario.model_validate_json(_stored_scenario(run)), folder)
        ]
    return left


def _run_files(scenario, folder: Path) -> list[Path]:
    """Every file a variant's run of `scenario` writes into `folder`, reversed, its
    checkpoint too."""
    from revdem_cli.api import output_paths_of
    from revdem_cli.checkpoint import checkpoint_path

    outputs = output_paths_of(scenario, folder, reverse=True)
    return [*outputs, checkpoint_path(folder, scenario.name)]


def _stored_scenario(path: Path) -> str:
    """The scenario, as JSON, that the checkpoint or trajectory at `path` stores."""
    from revdem_cli.checkpoint import SUFFIX
    from revdem_cli.io.h5md import open_trajectory
    from revdem_cli.io.restart import read_restart

    if path.name.endswith(SUFFIX):
        return read_restart(path, checkpoint=True).scenario_json
    with open_trajectory(path) as f:
        return f["parameters/revdem"].attrs["scenario_json"]


def _earlier_results(out_dir: Path, loaded: list[tuple], folders: list[str]) -> dict[int, dict]:
    """The rows of the variants of the earlier sweep in `out_dir` that are done, by index:
    all their outputs there and no checkpoint (the row its table has, or else, for one
    finished apart with `revdem run --resume`, the row its files give, without seconds).
    A variant neither done nor stopped with a checkpoint has what it left removed, as it
    will run again. InputError if there is no earlier sweep, if its table lists other
    variants (a finished sweep's, which going on with these would replace), or if a
    variant's checkpoint or outputs are of another scenario than this sweep's variant."""
    from revdem_cli.api import keep_outputs, output_paths_of
    from revdem_cli.checkpoint import find_checkpoints

    table = out_dir / "sweep.h5"
    if not table.exists() and not any((out_dir / folder).is_dir() for folder in folders):
        raise InputError(f"--resume {out_dir}: no sweep there (no sweep.h5, no variant folder)")
    rows = read_table(table) if table.exists() else {}
    if rows and sorted(rows) != sorted(folders):  # another sweep's table, not to be replaced
        listed = ", ".join(sorted(rows)[:3]) + (" ..." if len(rows) > 3 else "")
        raise InputError(
            f"--resume {out_dir}: its sweep has other variants ({listed}) than these; give "
            "its --set to go on with it, or --force without --resume to start over"
        )
    results = {}
    for index, ((scenario, _), folder) in enumerate(zip(loaded, folders, strict=True)):
        checkpoints = find_checkpoints(out_dir / folder)
        outputs = output_paths_of(scenario, out_dir / folder, reverse=True)
        if checkpoints:
            path = checkpoints[0]
        elif all(p.exists() for p in outputs):
            path = outputs[0]
        else:
            keep_outputs(outputs, force=True)
            continue
        if _stored_scenario(path) != scenario.model_dump_json():
            raise InputError(
                f"--resume {out_dir}: {path} is of another scenario than this sweep's variant "
                f"{folder}; give the sweep's own file and --set options, or start over with "
                "--force"
            )
        if not checkpoints:
            results[index] = _kept_row(rows.get(folder), outputs)
    return results


def _kept_row(row: dict | None, outputs: list[Path]) -> dict:
    """The row of a variant done before --resume: its table's, or where the table does not
    have it done, the one its outputs (forward trajectory, comparison) give."""
    from revdem_cli.compare import read_verdict

    if row is not None and row["status"] == DONE:
        return row
    forward, compare = outputs[0], next((p for p in outputs if p.suffix == ".json"), None)
    verdict = read_verdict(compare) if compare is not None else None
    return _done_row(forward, verdict, None)


def write_table(rows: list[dict], stem: Path) -> list[Path]:
    """Write rows as STEM.csv and STEM.h5, each under a temporary name renamed over the old.
    In STEM.h5, /sweep/<column>: a column of values set as float64 where every value is a
    number (inf too), else as strings; results as float64 with NaN where missing
    (reversible as 1, 0 or NaN), their text (TEXT) as strings."""
    from revdem_cli.config import read_value
    from revdem_cli.io import write_text

    columns = list(rows[0])
    csv_path, h5_path = stem.with_suffix(".csv"), stem.with_suffix(".h5")
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, columns)
    writer.writeheader()
    writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    write_text(csv_path, text.getvalue())
    tmp = h5_path.with_name(h5_path.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs["kind"] = KIND_OF_TABLE
        group = f.create_group("sweep")
        group.attrs["columns"] = columns
        for column in columns:
            values = [row[column] for row in rows]
            if column in RESULTS and column not in TEXT:
                group[column] = np.array([math.nan if v is None else float(v) for v in values])
            elif column in RESULTS or column == "folder":
                strings = ["" if v is None else str(v) for v in values]
                group.create_dataset(column, data=strings, dtype=h5py.string_dtype())
            else:
                read = [read_value(v, column) for v in values]
                number = all(isinstance(v, int | float) and not isinstance(v, bool) for v in read)
                data = np.array(read, dtype=np.float64) if number else values
                group.create_dataset(
                    column, data=data, dtype=None if number else h5py.string_dtype()
                )
    tmp.replace(h5_path)
    return [csv_path, h5_path]


def table_rows(path: Path) -> list[dict]:
    """The rows of the table STEM.h5 at `path`: each variant's folder, the values it set
    (`values`, `read_values`) and its results (RESULTS, `read_table`)."""
    values = read_values(path)
    return [
        {"folder": folder, "values": values[folder], **row}
        for folder, row in read_table(path).items()
    ]


def read_values(path: Path) -> dict[str, dict]:
    """The values each variant of the table STEM.h5 at `path` set, by folder: {field: value}
    as Python's, the values the variant's scenario took (`_plain`)."""
    try:
        with h5py.File(path, "r") as f:
            table = f["sweep"]
            folders = list(table["folder"].asstr()[:])
            fields = [c for c in table.attrs["columns"] if c != "folder" and c not in RESULTS]
            columns = {
                field: table[field].asstr()[:]
                if table[field].dtype.kind == "O"
                else table[field][:]
                for field in fields
            }
    except (OSError, KeyError) as exc:
        raise InputError(f"{path}: cannot read the sweep's table ({exc})") from None
    return {
        folder: {field: _plain(columns[field][k], f"{path}: {field}") for field in fields}
        for k, folder in enumerate(folders)
    }


def _plain(value, where: str):
    """A value of a table's column as Python's: a text column holds each value as `--set`
    was given it, read back as `--set` reads it (`config.read_value`: true, [0.9, 0.1, 0.0],
    "a, b" as a bool, a list, the text a, b; hertz as the text), not left as that text; in
    a column of numbers, a whole number as an int (a table's number columns are float64:
    700000.0 steps), else a float."""
    from revdem_cli.config import read_value

    if isinstance(value, str):
        return read_value(value, where)
    number = float(value)
    return int(number) if number.is_integer() else number


def read_table(path: Path) -> dict[str, dict]:
    """The results (RESULTS) of each variant of the table STEM.h5 at `path`, by folder, as
    `run_variant` gave them."""
    try:
        with h5py.File(path, "r") as f:
            table = f["sweep"]
            columns = {name: table[name] for name in ("folder", *RESULTS)}
            folders = list(columns["folder"].asstr()[:])
            stored = {
                name: column.asstr()[:] if name in TEXT else column[:]
                for name, column in columns.items()
            }
    except (OSError, KeyError) as exc:
        raise InputError(f"{path}: cannot read the sweep's table ({exc})") from None
    return {
        folder: {name: _result(name, stored[name][k]) for name in RESULTS}
        for k, folder in enumerate(folders)
    }


def _result(name: str, value):
    """A stored result as `run_variant` gives it: None where missing."""
    if name in TEXT:
        return value or None
    if math.isnan(value):
        return None
    if name == "reversible":
        return bool(value)
    return int(value) if name == "first_divergence_step" else float(value)
