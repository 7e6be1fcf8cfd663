"""Restart files: everything needed to continue or reverse a run bit for bit.

A checkpoint is a restart file taken part-way through a run, with a /revdem/checkpoint
group saying where (`Resumption`); `revdem run --resume` continues from it. Both are written
to a temporary name and renamed, so either is complete or absent.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from revdem_cli.assembly.spheres import numbered
from revdem_cli.errors import InputError
from revdem_cli.io import (
    DAMAGE,
    SCHEMA_VERSION,
    get_dataset,
    one_line,
    open_hdf5,
    stored_scenario,
    write_file,
)
from revdem_cli.kernels.arrays import Cell, Fixed, Pairs, Particles, Walls
from revdem_cli.kernels.forces import note_normals
from revdem_cli.kernels.neighbours import index_by_particle
from revdem_cli.state import (
    State,
    cell_arrays,
    empty_pairs,
    pair_capacity,
    predicts,
    rolls,
    turns,
    wall_arrays,
)

PAIR_FIELDS = ("i", "j", "force", "history", "rolling")
"""The per-pair arrays a restart keeps: the list, the contact forces of its step (which its
observables read) and the contact histories of the laws it has (shear, rolling)."""

WALL_FIELDS = tuple(name for name in Walls._fields if name != "normal_new")
"""The wall arrays a restart keeps; the reversed step's scratch is allocated on reading."""

CELL_ARRAYS = tuple(name for name in Cell._fields if name not in ("servo", "mass", "gain"))
"""The cell's arrays; its servo parameters come from the stored scenario."""


@dataclass
class Resumption:
    """Where in a run a checkpoint was taken, besides its state."""

    phase: str  # "forward" (the stages in order) or "reverse" (the reversed stage)
    stage_index: int  # the stage being run
    events: np.ndarray  # the stage's log of information-destroying mechanisms so far
    frames: int  # frames in the trajectory being written, up to the checkpoint's step
    observables: int  # observables rows in it
    reverse: bool  # forward phase: the run reverses its marked stage afterwards
    source_restart: str  # reverse phase: the restart file it reverses from
    stop_step: int  # reverse phase: the step it reverses back to
    end_step: int  # reverse phase: the step the reversed stage ended at, going forward
    so_far: str = "{}"  # what the run's summary says of the stages before, JSON
    # (`engine.summary_so_far`); a checkpoint written before it held none: {}


@dataclass
class Restart:
    state: State
    scenario_json: str  # the validated scenario, overrides applied
    scenario_text: str  # the scenario file as written
    scenario_suffix: str
    stage: str  # name of the stage that ended here
    trajectory: str  # the forward trajectory this restart ends
    stage_first_step: int  # where that stage began
    stage_first_time: float  # s
    stage_dt: float  # the time step that stage ran at, s
    resumption: Resumption | None = None  # a checkpoint's place in its run
    tape: str = ""  # the information tape of the stage that ended here (io/tape.py), or none
    previous: str = ""  # the restart at the end of the stage before, when every stage reverses
    # the restart that ends a run: what its summary says of the stages (which stopped on
    # their condition, which did not meet it or hold their stress, the dt each 'auto' one
    # took; `engine.summary_so_far`), JSON; {} in any other, and in one written before it
    summary: str = "{}"
    # what that stage's law did at its start where it wrote its own observables row there
    # beside the end of the stage before (`stage.StageStart`), JSON; {} where it did not,
    # and in one written before restarts said
    stage_start: str = "{}"


def write_restart(path: Path, restart: Restart) -> None:
    """Write a restart (or checkpoint) to a temporary name and rename it over `path`, so
    that `path` is the old file or the new one, whole; WriteFailed naming it if it cannot be
    written, the temporary removed and the old file left as it was. The HDF5 image is made
    in memory and written as plain bytes: a write that fails then leaves HDF5 no file it
    cannot close (it would fail again, and crash, as the process exits)."""
    path = Path(path)
    with h5py.File(path.name, "w", driver="core", backing_store=False) as f:  # in memory
        _write_state(f, restart)
        f.flush()
        image = f.id.get_file_image()
    write_file(path, image)


def _write_state(f: h5py.File, restart: Restart) -> None:
    s = restart.state
    meta = f.create_group("revdem")
    meta.attrs["kind"] = "restart"
    meta.attrs["schema_version"] = SCHEMA_VERSION
    meta.attrs["step"] = s.step
    meta.attrs["stage"] = restart.stage
    meta.attrs["scenario_json"] = restart.scenario_json
    meta.attrs["scenario_text"] = restart.scenario_text
    meta.attrs["scenario_suffix"] = restart.scenario_suffix
    meta.attrs["trajectory"] = restart.trajectory
    meta.attrs["stage_first_step"] = restart.stage_first_step
    meta.attrs["stage_first_time"] = restart.stage_first_time
    meta.attrs["stage_dt"] = restart.stage_dt
    meta.attrs["tape"] = restart.tape
    meta.attrs["previous"] = restart.previous
    meta.attrs["summary"] = restart.summary
    meta.attrs["stage_start"] = restart.stage_start
    for name in Particles._fields:
        _put(f, f"particles/{name}", getattr(s.particles, name))
    _put(f, "particles/id", s.ids)
    for name in WALL_FIELDS:
        _put(f, f"walls/{name}", getattr(s.walls, name))
    for name in CELL_ARRAYS:
        _put(f, f"cell/{name}", getattr(s.cell, name))
    for name in Fixed._fields:
        _put(f, f"fixed/{name}", getattr(s.fixed, name))
    n = int(s.pairs.count[0])
    for name in PAIR_FIELDS:
        if getattr(s.pairs, name).shape[0] > 0:  # arrays of the laws it has
            _put(f, f"pairs/{name}", getattr(s.pairs, name)[:n])
    _put(f, "pairs/x_built", s.pairs.x_built)
    if restart.resumption is not None:
        _write_resumption(meta.create_group("checkpoint"), restart.resumption)
    seal(meta)


def _write_resumption(group: h5py.Group, resumption: Resumption) -> None:
    for name, value in vars(resumption).items():
        if name == "events":
            _put(group, name, value)
        else:
            group.attrs[name] = value
    seal(group)


def digest(data: np.ndarray) -> str:
    """SHA-256 of an array's type, shape and bytes."""
    a = np.ascontiguousarray(data)
    return hashlib.sha256(f"{a.dtype.str} {a.shape} ".encode() + a.tobytes()).hexdigest()


def _put(group: h5py.Group, name: str, data: np.ndarray) -> None:
    """A dataset with the digest of its contents, which `_verified` checks on reading."""
    group.create_dataset(name, data=data).attrs["sha256"] = digest(np.asarray(data))


def _attributes_digest(group: h5py.Group) -> str:
    """SHA-256 of a group's attributes but its own digest, by name."""
    plain = {k: np.asarray(v).tolist() for k, v in group.attrs.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(plain, sort_keys=True).encode()).hexdigest()


def seal(group: h5py.Group) -> None:
    """Store the digest of a group's attributes, once they are all written."""
    group.attrs["sha256"] = _attributes_digest(group)


def _check_seal(group: h5py.Group, path: Path) -> None:
    if group.attrs.get("sha256") != _attributes_digest(group):
        raise InputError(
            f"{path}: damaged revdem restart (the attributes of {group.name} fail their checksum)"
        )


def _verified(f: h5py.File, path: Path, name: str) -> np.ndarray:
    """Dataset `name` read, its digest checked: InputError naming it if a bit changed."""
    dataset = get_dataset(f, path, name)
    data = dataset[()]
    if dataset.attrs.get("sha256") != digest(np.asarray(data)):
        raise InputError(f"{path}: damaged revdem restart ({name} fails its checksum)")
    return data


def _read_resumption(f: h5py.File, path: Path) -> Resumption:
    group = f["revdem/checkpoint"]
    attrs = group.attrs
    return Resumption(
        phase=str(attrs["phase"]),
        stage_index=int(attrs["stage_index"]),
        events=_verified(f, path, "revdem/checkpoint/events"),
        frames=int(attrs["frames"]),
        observables=int(attrs["observables"]),
        reverse=bool(attrs["reverse"]),
        source_restart=str(attrs["source_restart"]),
        stop_step=int(attrs["stop_step"]),
        end_step=int(attrs["end_step"]),
        so_far=str(attrs.get("so_far", "{}")),
    )


def read_restart(path: str | Path, checkpoint: bool | None = False) -> Restart:
    """A restart file (or with `checkpoint`, a checkpoint; with None, either), checked by
    `open_hdf5` (schema version, layout, stored scenario); InputError naming the file for
    anything else."""
    path = Path(path)
    f = open_hdf5(path)
    with f:
        try:
            return _read(f, _meta(f, path, checkpoint), path)
        except DAMAGE as exc:
            raise InputError(f"{path}: damaged revdem restart file ({one_line(exc)})") from None


def _meta(f: h5py.File, path: Path, checkpoint: bool | None) -> h5py.Group:
    """The /revdem group of a restart file, or with `checkpoint`, of a checkpoint (None:
    of either); InputError if the file is something else."""
    meta = f.get("revdem")
    if meta is None or meta.attrs.get("kind") != "restart":
        what = "a revdem trajectory" if "parameters/revdem" in f else "no /revdem group"
        raise InputError(f"{path}: not a revdem restart file ({what})")
    _check_seal(meta, path)
    if "checkpoint" in meta:
        _check_seal(meta["checkpoint"], path)
    if checkpoint is None:
        return meta
    if checkpoint and "checkpoint" not in meta:
        raise InputError(f"{path}: a restart file, not a checkpoint")
    if not checkpoint and "checkpoint" in meta:
        raise InputError(
            f"{path}: a checkpoint of an unfinished run; continue it with "
            f"revdem run --resume {path.parent}"
        )
    return meta


def _read(f: h5py.File, meta: h5py.Group, path: Path) -> Restart:
    """The state of a restart, with the arrays a reversed step needs (a checkpoint of a
    forward phase: those a forward step needs)."""

    def read(name: str):
        return _verified(f, path, name)

    scenario = stored_scenario(meta.attrs["scenario_json"], path)
    shear = scenario.contact.tangential != "none"
    resumption = _read_resumption(f, path) if "checkpoint" in meta else None
    taped = scenario.reversal.tape  # a forward step then takes a reversed one in its shadow
    reversing = resumption is None or resumption.phase == "reverse" or taped
    particles = Particles(*(read(f"particles/{name}") for name in Particles._fields))
    n_particles = len(particles.x)
    ids = read("particles/id") if "particles/id" in f else numbered(n_particles)  # before ids
    walls = wall_arrays(scenario, n_particles, reversing)
    for name in WALL_FIELDS:
        getattr(walls, name)[...] = read(f"walls/{name}")
    cell = cell_arrays(scenario)
    for name in CELL_ARRAYS:
        getattr(cell, name)[...] = read(f"cell/{name}")
    integers = Fixed(*(read(f"fixed/{name}") for name in Fixed._fields))
    n = f["pairs/i"].shape[0]
    pairs: Pairs = empty_pairs(
        n_particles,
        pair_capacity(n),
        shear,
        reversing,
        rolls(scenario),
        turns(scenario),
        predicts(scenario),
    )
    for name in PAIR_FIELDS:
        if getattr(pairs, name).shape[0] > 0:
            getattr(pairs, name)[:n] = read(f"pairs/{name}")
    pairs.x_built[:] = read("pairs/x_built")
    pairs.count[:] = n
    step = int(meta.attrs["step"])
    first_step = int(meta.attrs["stage_first_step"])
    _check_state(path, scenario, particles, ids, pairs, walls, step, first_step)
    index_by_particle(pairs.i, pairs.j, n, pairs.first, pairs.start, pairs.slots)
    note_normals(particles, pairs, cell)  # as the step's pair loop left them
    return Restart(
        state=State(particles, pairs, walls, cell, integers, ids, step=step),
        scenario_json=str(meta.attrs["scenario_json"]),
        scenario_text=str(meta.attrs["scenario_text"]),
        scenario_suffix=str(meta.attrs["scenario_suffix"]),
        stage=str(meta.attrs["stage"]),
        trajectory=str(meta.attrs["trajectory"]),
        stage_first_step=first_step,
        stage_first_time=float(meta.attrs["stage_first_time"]),
        stage_dt=float(meta.attrs["stage_dt"]),
        resumption=resumption,
        tape=str(meta.attrs.get("tape", "")),
        previous=str(meta.attrs.get("previous", "")),
        summary=str(meta.attrs.get("summary", "{}")),
        stage_start=str(meta.attrs.get("stage_start", "{}")),
    )


def _check_state(path, scenario, particles, ids, pairs, walls, step, stage_first_step) -> None:
    """What the compiled kernels index memory with, and what they divide by, in range: an
    InputError naming the first value that is not (a restart edited with its checksums
    recomputed, or written by something else)."""
    import math

    from revdem_cli import wall_shapes

    def refuse(what: str):
        raise InputError(f"{path}: damaged revdem restart ({what})")

    if not 0 <= stage_first_step <= step:
        refuse(f"revdem/step {step} is not at or after its stage's first step {stage_first_step}")
    n, materials = len(particles.x), len(scenario.materials)
    if ids.shape != (n,):
        refuse(f"particles/id has shape {ids.shape}, not {(n,)}")
    for name in ("x", "v", "omega", "f", "torque"):
        bad = np.flatnonzero(~np.isfinite(getattr(particles, name)).all(axis=1))
        if len(bad):
            refuse(f"particles/{name} of particle {bad[0]} is not finite")
    order = scenario.integrator.predictor_order  # the velocity predictor's arrays
    shapes = {"v_past": (order, n, 3), "v_pred": (n if order else 0, 3)}
    for name in ("v_past", "omega_past", "v_pred", "omega_pred"):
        values, shape = getattr(particles, name), shapes[name.replace("omega", "v")]
        if values.shape != shape:
            refuse(f"particles/{name} has shape {values.shape}, not {shape}")
        if not np.isfinite(values).all():
            refuse(f"particles/{name} is not finite")
    for name in ("radius", "mass", "inertia"):
        bad = np.flatnonzero(
            ~(getattr(particles, name) > 0.0) | ~np.isfinite(getattr(particles, name))
        )
        if len(bad):
            refuse(f"particles/{name} of particle {bad[0]} is not a positive number")
    for group, values in (("particles", particles.material), ("walls", walls.material)):
        bad = np.flatnonzero((values < 0) | (values >= materials))
        if len(bad):
            k = bad[0]
            refuse(
                f"{group}/material {values[k]} of entry {k} is none of the {materials} materials"
            )
    bad = np.flatnonzero((walls.kind < 1) | (walls.kind > len(wall_shapes.SHAPES)))
    if len(bad):
        refuse(f"walls/kind {walls.kind[bad[0]]} of wall {bad[0]} is no wall shape")
    count = int(pairs.count[0])
    i, j = pairs.i[:count].astype(np.int64), pairs.j[:count].astype(np.int64)
    order = i * n + j  # strictly increasing: sorted by (i, j), each pair once
    bad = np.flatnonzero((i < 0) | (i >= j) | (j >= n))
    if len(bad):
        refuse(f"pairs/i, pairs/j: pair {bad[0]} is ({i[bad[0]]}, {j[bad[0]]}), not i < j < {n}")
    bad = np.flatnonzero(np.diff(order) <= 0)
    if len(bad):
        refuse(f"pairs/i, pairs/j: pair {bad[0] + 1} is not after pair {bad[0]} in (i, j) order")
    if not math.isfinite(float(np.abs(pairs.x_built).max(initial=0.0))):
        refuse("pairs/x_built is not finite")


def restart_stage(path: str | Path) -> tuple[int, int]:
    """(first, last) step of the stage a restart file ends (the reversed stage, whose
    reversal, with `[reversal] all_stages`, goes on through the stages before), the last
    the restart's own, checked as `read_restart` checks them, without reading its arrays."""
    path = Path(path)
    with open_hdf5(path) as f:
        attrs = _meta(f, path, checkpoint=False).attrs
        return int(attrs["stage_first_step"]), int(attrs["step"])


def restart_summary(path: str | Path) -> str:
    """What the run a restart ends said of its stages (`Restart.summary`), as `read_restart`
    checks it, without its arrays."""
    path = Path(path)
    with open_hdf5(path) as f:
        return str(_meta(f, path, checkpoint=None).attrs.get("summary", "{}"))


def restart_links(path: str | Path) -> tuple[str, str, int]:
    """(its information tape's name, the restart of the stage before's name, the first step
    of its stage) of a restart file, as `read_restart` checks them, without its arrays:
    the chain a reversal of every stage goes back along."""
    path = Path(path)
    with open_hdf5(path) as f:
        attrs = _meta(f, path, checkpoint=False).attrs
        return (
            str(attrs.get("tape", "")),
            str(attrs.get("previous", "")),
            int(attrs["stage_first_step"]),
        )


def checkpoint_phase(path: str | Path) -> str:
    """The phase a checkpoint stopped in, "forward" or "reverse" (`Resumption.phase`),
    checked as `read_restart` checks it, without reading its arrays."""
    path = Path(path)
    with open_hdf5(path) as f:
        return str(_meta(f, path, checkpoint=True)["checkpoint"].attrs["phase"])


def restart_positions(path: str | Path) -> tuple[int, np.ndarray]:
    """(step, positions) of the state a restart file holds, checked as `read_restart`
    checks them: what the last frame of the forward run it ends holds, wherever its files
    were moved or copied."""
    path = Path(path)
    with open_hdf5(path) as f:
        meta = _meta(f, path, checkpoint=False)
        return int(meta.attrs["step"]), _verified(f, path, "particles/x")


def restart_scenario(path: str | Path):
    """The scenario a restart file stores and the forward trajectory it names, checked as
    `read_restart` checks them, without reading its arrays."""
    path = Path(path)
    with open_hdf5(path) as f:
        meta = _meta(f, path, checkpoint=False)
        return stored_scenario(meta.attrs["scenario_json"], path), Path(
            str(meta.attrs.get("trajectory", ""))
        )
