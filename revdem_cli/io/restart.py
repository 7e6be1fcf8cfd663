"""Restart files: everything needed to continue or reverse a run bit for bit.

Written to a temporary name and renamed, so a restart file is either complete or absent.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from revdem_cli.errors import InputError
from revdem_cli.io import (
    DAMAGE,
    SCHEMA_VERSION,
    get_dataset,
    one_line,
    open_hdf5,
    stored_scenario,
)
from revdem_cli.kernels.arrays import Cell, Fixed, Pairs, Particles, Walls
from revdem_cli.kernels.neighbours import index_by_particle
from revdem_cli.state import State, empty_pairs, pair_capacity

PAIR_FIELDS = ("i", "j", "force", "history")
"""The per-pair arrays a restart keeps: the list, the contact forces of its step (which its
observables read) and, with a tangential law, the contact history."""

WALL_FIELDS = tuple(name for name in Walls._fields if name != "normal_new")
"""The wall arrays a restart keeps; the reversed step's scratch is allocated on reading."""

CELL_ARRAYS = tuple(name for name in Cell._fields if name not in ("servo", "mass", "gain"))
"""The cell's arrays; its servo parameters come from the stored scenario."""


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


def write_restart(path: Path, restart: Restart) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    s = restart.state
    with h5py.File(tmp, "w") as f:
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
        for name in Particles._fields:
            f.create_dataset(f"particles/{name}", data=getattr(s.particles, name))
        for name in WALL_FIELDS:
            f.create_dataset(f"walls/{name}", data=getattr(s.walls, name))
        for name in CELL_ARRAYS:
            f.create_dataset(f"cell/{name}", data=getattr(s.cell, name))
        for name in Fixed._fields:
            f.create_dataset(f"fixed/{name}", data=getattr(s.fixed, name))
        n = int(s.pairs.count[0])
        shear = s.pairs.history.shape[0] > 0
        for name in PAIR_FIELDS[: 4 if shear else 3]:
            f.create_dataset(f"pairs/{name}", data=getattr(s.pairs, name)[:n])
        f.create_dataset("pairs/x_built", data=s.pairs.x_built)
    os.replace(tmp, path)


def read_restart(path: str | Path) -> Restart:
    """A restart file, checked by `open_hdf5` (schema version, layout, stored scenario);
    InputError naming the file for anything else."""
    path = Path(path)
    f = open_hdf5(path)
    with f:
        meta = f.get("revdem")
        if meta is None or meta.attrs.get("kind") != "restart":
            what = "a revdem trajectory" if "parameters/revdem" in f else "no /revdem group"
            raise InputError(f"{path}: not a revdem restart file ({what})")
        try:
            return _read(f, meta, path)
        except DAMAGE as exc:
            raise InputError(f"{path}: damaged revdem restart file ({one_line(exc)})") from None


def _read(f: h5py.File, meta: h5py.Group, path: Path) -> Restart:
    """The state of a restart, with the arrays a reversed step needs."""
    from revdem_cli.state import cell_arrays

    def read(name: str):
        return get_dataset(f, path, name)[:]

    scenario = stored_scenario(meta.attrs["scenario_json"], path)
    shear = scenario.contact.tangential != "none"
    particles = Particles(*(read(f"particles/{name}") for name in Particles._fields))
    n_particles = len(particles.x)
    stored = {name: read(f"walls/{name}") for name in WALL_FIELDS}
    unwinding = n_particles if shear else 0
    walls = Walls(**stored, normal_new=np.zeros((unwinding, len(stored["kind"]), 3)))
    cell = cell_arrays(scenario)
    for name in CELL_ARRAYS:
        getattr(cell, name)[...] = read(f"cell/{name}")
    integers = Fixed(*(read(f"fixed/{name}") for name in Fixed._fields))
    n = f["pairs/i"].shape[0]
    pairs: Pairs = empty_pairs(n_particles, pair_capacity(n), shear, reversing=True)
    for name in PAIR_FIELDS[: 4 if shear else 3]:
        getattr(pairs, name)[:n] = read(f"pairs/{name}")
    pairs.x_built[:] = read("pairs/x_built")
    pairs.count[:] = n
    index_by_particle(pairs.i, pairs.j, n, pairs.first, pairs.start, pairs.slots)
    return Restart(
        state=State(particles, pairs, walls, cell, integers, step=int(meta.attrs["step"])),
        scenario_json=str(meta.attrs["scenario_json"]),
        scenario_text=str(meta.attrs["scenario_text"]),
        scenario_suffix=str(meta.attrs["scenario_suffix"]),
        stage=str(meta.attrs["stage"]),
        trajectory=str(meta.attrs["trajectory"]),
        stage_first_step=int(meta.attrs["stage_first_step"]),
        stage_first_time=float(meta.attrs["stage_first_time"]),
    )


def restart_scenario(path: str | Path):
    """The scenario a restart file stores and the forward trajectory it names, checked as
    `read_restart` checks them, without reading its arrays."""
    path = Path(path)
    with open_hdf5(path) as f:
        meta = f.get("revdem")
        if meta is None or meta.attrs.get("kind") != "restart":
            what = "a revdem trajectory" if "parameters/revdem" in f else "no /revdem group"
            raise InputError(f"{path}: not a revdem restart file ({what})")
        return stored_scenario(meta.attrs["scenario_json"], path), Path(
            str(meta.attrs.get("trajectory", ""))
        )
