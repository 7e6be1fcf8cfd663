"""Files: H5MD trajectories and restart files.

Both carry SCHEMA_VERSION (trajectories in /parameters/revdem, restarts in /revdem) and the
validated scenario they were run from. `open_hdf5` checks a revdem file before anything reads
it: its version, its layout and its stored scenario, so that a truncated, damaged, foreign or
edited file gives one clear error instead of a failure half-way through a command.
"""

from __future__ import annotations

from functools import lru_cache

SCHEMA_VERSION = 7
"""Version of revdem's layout inside H5MD trajectories and restart files (7: restarts keep
the velocity predictor's history, particles/v_past, omega_past, v_pred, omega_pred)."""

FRAME_FIELDS = ("position", "velocity", "angular_velocity", "force")
"""Per-particle time series of a trajectory, under /particles/all."""

GRID_FIELDS = ("position_grid", "velocity_grid", "angular_velocity_grid")
"""The integer state of fixed-point arithmetic at each frame, under /particles/all."""

DAMAGE = (KeyError, OSError, RuntimeError, ValueError, TypeError, IndexError, AttributeError)
"""What h5py raises when it reads a damaged file."""


EXPORT_SUFFIXES = {"vtk": ".vtk", "gsd": ".gsd", "lammps-dump": ".dump", "lammps-data": ".data"}
"""`revdem export`'s formats, each with the suffix of its default target: the trajectory's
path with it in place of .h5 (a folder for vtk, its series and frames inside)."""


def export_target(trajectory, format: str):
    """Where `revdem export` writes `trajectory` in `format` unless --out says."""
    from pathlib import Path

    return Path(trajectory).with_suffix(EXPORT_SUFFIXES[format])


def exports_of(trajectory) -> list:
    """The default targets of `revdem export` of `trajectory` that are there (files, or
    the vtk folder), in the order of EXPORT_SUFFIXES."""
    targets = (export_target(trajectory, format) for format in EXPORT_SUFFIXES)
    return [target for target in targets if target.exists() or target.is_symlink()]


def write_text(path, text: str) -> None:
    """`write_file` of a text."""
    write_file(path, text.encode())


def refuse_overwriting(command: str, target, keep: bool, reading=None) -> None:
    """InputError where `command` (export, dt, report) would write the file --out names,
    `target`, over: a folder, one that is there or a path that ends in a separator (as
    given: `options.named_file`), which names one; the file it reads, `reading`; an HDF5
    file (a run's trajectory, restart or tape, which none of their outputs is); or, where
    `keep` (an --out given without --force), any file, a run's verdict or figure say. A
    command's default target is its own to write again."""
    import os
    from pathlib import Path

    import h5py

    from revdem_cli.errors import InputError

    given, target = str(target), Path(target)
    if given.endswith(tuple(filter(None, (os.sep, os.altsep)))) or target.is_dir():
        raise InputError(f"{command}: --out {given}: a folder; name a file")
    if not target.is_file():
        return
    read = reading is not None and target.resolve() == Path(reading).resolve()
    if read or h5py.is_hdf5(target):
        what = "the file it reads" if read else "HDF5"
        raise InputError(f"{command}: --out {target}: {what}, which {command} would overwrite")
    if keep:
        raise InputError(f"{command}: --out {target}: exists; use --force to overwrite")


def write_file(path, data: bytes) -> None:
    """Write a file under a temporary name renamed over `path`: the old file or the new one,
    whole; WriteFailed naming it if it cannot be written, the temporary removed."""
    import os
    from pathlib import Path

    from revdem_cli.errors import WriteFailed

    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise WriteFailed(path, exc) from None


def open_hdf5(path):
    """Open an HDF5 file for reading; InputError naming the file if it is not one, or if it
    is a revdem trajectory or restart that this revdem cannot read (`check_revdem_file`)."""
    from pathlib import Path

    from revdem_cli.errors import InputError, check_regular

    path = Path(path)
    check_regular(path, "it as HDF5")
    try:
        f = _open_for_reading(path)
    except OSError as exc:
        why = _why_unreadable(path, exc)
        raise InputError(f"{path}: not a readable HDF5 file ({why})") from None
    try:
        check_revdem_file(f, path)
    except InputError:
        f.close()
        raise
    except DAMAGE as exc:
        f.close()
        raise InputError(f"{path}: damaged revdem file ({one_line(exc)})") from None
    return f


def _open_for_reading(path):
    """h5py.File(path, "r"); a trajectory still being written, or left by a run that was
    killed, is marked open for writing, and is opened in SWMR mode instead."""
    import h5py

    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if "already open for write" not in str(exc):
            raise
    return h5py.File(path, "r", swmr=True)


def _why_unreadable(path, exc: OSError) -> str:
    """Why h5py could not open `path`, in a few words."""
    import re

    if not path.exists():
        return "no such file"
    if path.is_dir():
        return "a directory"
    stored = re.search(r"eof = (\d+).*stored_eof = (\d+)", str(exc))
    if stored:
        return f"truncated: {stored[1]} of its {stored[2]} bytes"
    try:
        with path.open("rb") as f:
            start = f.read(8)
    except OSError as error:
        return error.strerror or "cannot be read"
    if start == b"\x89HDF\r\n\x1a\n":
        return f"damaged HDF5: {one_line(exc)}"
    return "not HDF5"


def one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def check_revdem_file(f, path) -> None:
    """Check a revdem restart or trajectory; leave any other HDF5 file to the caller."""
    meta = f.get("revdem")
    if meta is not None and meta.attrs.get("kind") == "restart":
        _check_restart(f, path)
    elif "parameters/revdem" in f:
        _check_trajectory(f, path)


def check_version(attrs, path, kind: str) -> None:
    """The file's schema version must be this revdem's."""
    from revdem_cli.errors import InputError

    version = attrs.get("schema_version")
    if version is None:
        raise InputError(f"{path}: damaged revdem file (a {kind} without a schema version)")
    if int(version) != SCHEMA_VERSION:
        raise InputError(
            f"{path}: {kind} schema version {int(version)}, this revdem reads {SCHEMA_VERSION}"
        )


def _check_trajectory(f, path) -> None:
    from revdem_cli.errors import InputError

    attrs = f["parameters/revdem"].attrs
    check_version(attrs, path, "trajectory")
    everything = f.get("particles/all")
    if everything is None or "position" not in everything:
        raise InputError(f"{path}: damaged revdem trajectory (no /particles/all/position)")
    n = _rows(f, path, "particles/all/radius")
    for name in ("mass", "id"):
        if _rows(f, path, f"particles/all/{name}") != n:
            raise InputError(
                f"{path}: damaged revdem trajectory (particles/all/{name} is not {n} long)"
            )
    frames = _rows(f, path, "particles/all/position/step")
    for name in FRAME_FIELDS:
        value = get_dataset(f, path, f"particles/all/{name}/value")
        if value.shape[1:] != (n, 3) or value.shape[0] < frames:
            raise InputError(
                f"{path}: damaged revdem trajectory (particles/all/{name}/value holds "
                f"{value.shape}, expected {frames} frames of {n} x 3)"
            )
        if _rows(f, path, f"particles/all/{name}/time") < frames:
            raise InputError(f"{path}: damaged revdem trajectory (particles/all/{name}/time)")
    if "connectivity/contacts" in f:
        _check_contacts(f, path, frames)
    for name in _series_in(f.get("observables")):
        rows = _rows(f, path, f"observables/{name}/step")
        for part in ("time", "value"):
            if _rows(f, path, f"observables/{name}/{part}") < rows:
                raise InputError(
                    f"{path}: damaged revdem trajectory (observables/{name}/{part} is shorter "
                    f"than its {rows} steps)"
                )
    scenario = stored_scenario(attrs.get("scenario_json", ""), path)
    if scenario.sphere_count != n:
        raise InputError(
            f"{path}: particles/all/radius: {n} spheres, but the stored scenario has "
            f"{scenario.sphere_count}"
        )


def _check_contacts(f, path, frames: int) -> None:
    """The contact list holds a count for each frame and the rows those counts add up to."""
    from revdem_cli.errors import InputError
    from revdem_cli.io.h5md import CONTACT_COUNT, CONTACT_FIELDS, CONTACTS

    if _rows(f, path, CONTACT_COUNT) < frames:
        raise InputError(f"{path}: damaged revdem trajectory ({CONTACT_COUNT})")
    rows = int(get_dataset(f, path, CONTACT_COUNT)[:frames].sum())
    for name in CONTACT_FIELDS:
        if _rows(f, path, f"{CONTACTS}/{name}") < rows:
            raise InputError(
                f"{path}: damaged revdem trajectory (connectivity/contacts/{name} is shorter "
                f"than the {rows} contacts of its frames)"
            )


def _check_restart(f, path) -> None:
    from revdem_cli.errors import InputError

    meta = f["revdem"]
    check_version(meta.attrs, path, "restart")
    for name in ("step", "stage", "scenario_json", "scenario_text", "scenario_suffix"):
        if name not in meta.attrs:
            raise InputError(f"{path}: damaged revdem restart (no attribute revdem/{name})")
    scenario = stored_scenario(meta.attrs["scenario_json"], path)
    n = _rows(f, path, "particles/x")
    if n != scenario.sphere_count:
        raise InputError(
            f"{path}: particles/x: {n} spheres, but the stored scenario has {scenario.sphere_count}"
        )
    for name, dataset in f["particles"].items():
        if name in ("v_past", "omega_past"):  # the velocity predictor's half steps: k x n
            continue  # their shapes are checked with the scenario's order on reading
        optional = name in ("s", "v_drift", "v_pred", "omega_pred")  # empty where not needed
        if dataset.shape[:1] != (n,) and not (optional and dataset.shape[:1] == (0,)):
            raise InputError(f"{path}: damaged revdem restart (particles/{name} is not {n} long)")
    for name in ("length", "rate", "stress"):
        get_dataset(f, path, f"cell/{name}")
    walls = len(scenario.walls)
    for name, expected in (("kind", (walls,)), ("history", (n, walls))):
        shape = get_dataset(f, path, f"walls/{name}").shape
        if shape[: len(expected)] != expected:
            raise InputError(
                f"{path}: walls/{name} holds {shape}, expected {expected} for the {walls} walls "
                "of its stored scenario"
            )
    pairs = _rows(f, path, "pairs/i")
    for name, dataset in f["pairs"].items():
        expected = (n, 3) if name == "x_built" else (pairs,)
        if dataset.shape[: len(expected)] != expected:
            raise InputError(f"{path}: damaged revdem restart (pairs/{name} holds {dataset.shape})")
    stage = str(meta.attrs["stage"])
    if stage not in [s.name for s in scenario.stages]:
        raise InputError(f"{path}: revdem/stage: its stored scenario has no stage named '{stage}'")


def _series_in(group) -> list[str]:
    """Names, under `group`, of the time series (groups holding a `value`) in it."""
    import h5py

    found = []
    if isinstance(group, h5py.Group):
        group.visititems(
            lambda name, item: (
                found.append(name) if isinstance(item, h5py.Group) and "value" in item else None
            )
        )
    return found


def get_dataset(f, path, name: str):
    """The dataset `name` of the revdem file `f` at `path`; InputError if it has none."""
    import h5py

    from revdem_cli.errors import InputError

    dataset = f.get(name)
    if not isinstance(dataset, h5py.Dataset):
        raise InputError(f"{path}: damaged revdem file (no dataset {name})")
    return dataset


def _rows(f, path, name: str) -> int:
    dataset = get_dataset(f, path, name)
    return dataset.shape[0] if dataset.shape else 0


def stored_scenario(text, path):
    """The scenario a file stores (JSON of a validated scenario), validated again; an
    InputError naming the file and the field if it no longer validates (edited, or written by
    a revdem with other rules)."""
    from pydantic import ValidationError

    from revdem_cli.config import describe_validation_error
    from revdem_cli.errors import InputError

    try:
        return _validated(str(text))
    except ValidationError as exc:
        raise InputError(f"{path}: stored scenario: {describe_validation_error(exc)}") from None


@lru_cache(maxsize=2)
def _validated(text: str):
    """Scenarios validated from their JSON (their schema and cross-field checks, nothing
    generated); a run reads the same one several times (restart, trajectories, figures), and
    the one object keeps its spheres once they are generated."""
    from revdem_cli.config import Scenario

    return Scenario.model_validate_json(text)
