"""H5MD 1.1 trajectories (readable by MDAnalysis and other H5MD clients).

/h5md                               version [1, 1]; author; creator revdem
/particles/all/{position,velocity,angular_velocity,force}   step [F], time [F], value [F, N, 3]
/particles/all/{radius,mass,id}     time-independent [N]
/observables/<name>                 step, time, value [F] or [F, 3]
/observables/events                 value [F, kinds, columns] at each frame: the log of
                                    information-destroying mechanisms (kernels/events.py)
/parameters/revdem                  attrs: direction, dt, arithmetic, scenario, source restart
Frames are flushed as they are written, so an interrupted run keeps what it wrote.
"""

from __future__ import annotations

import getpass
from pathlib import Path

import h5py
import numpy as np

from revdem_cli import __version__
from revdem_cli.errors import InputError
from revdem_cli.io import SCHEMA_VERSION

FRAME_FIELDS = ("position", "velocity", "angular_velocity", "force")


def _series(group: h5py.Group, name: str, shape: tuple, clock: h5py.Group | None) -> h5py.Group:
    """A time series `name` with value [F, *shape]; step and time shared with `clock`."""
    g = group.create_group(name)
    rows = max(1, 4096 // max(1, int(np.prod(shape))))
    g.create_dataset(
        "value", shape=(0, *shape), maxshape=(None, *shape), dtype=np.float64, chunks=(rows, *shape)
    )
    if clock is None:
        g.create_dataset("step", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(1024,))
        g.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(1024,))
    else:
        g["step"] = clock["step"]
        g["time"] = clock["time"]
    return g


def _append(dataset: h5py.Dataset, values) -> None:
    values = np.asarray(values)
    n = dataset.shape[0]
    dataset.resize(n + values.shape[0], axis=0)
    dataset[n:] = values


class TrajectoryWriter:
    """Appends frames and observables to a new H5MD file.

    `observables` lists (name, columns): a scalar observable has 1 column, a vector 3.
    """

    def __init__(
        self,
        path: Path,
        radius,
        mass,
        observables: list[tuple[str, int]],
        events_shape: tuple[int, int],
        parameters: dict,
    ):
        self.path = Path(path)
        self.file = h5py.File(self.path, "w")
        f = self.file
        h5md = f.create_group("h5md")
        h5md.attrs["version"] = np.array([1, 1])
        h5md.create_group("author").attrs["name"] = getpass.getuser()
        creator = h5md.create_group("creator")
        creator.attrs["name"] = "revdem"
        creator.attrs["version"] = __version__
        n = len(radius)
        everything = f.create_group("particles/all")
        box = everything.create_group("box")
        box.attrs["dimension"] = 3
        box.attrs["boundary"] = np.array([b"none"] * 3)
        clock = None
        for name in FRAME_FIELDS:
            clock = _series(everything, name, (n, 3), clock)
        self.frame_clock = clock
        everything.create_dataset("radius", data=radius)
        everything.create_dataset("mass", data=mass)
        everything.create_dataset("id", data=np.arange(n, dtype=np.int64))
        self.events = _series(f, "observables/events", events_shape, self.frame_clock)["value"]
        self.observables_layout = observables
        clock = None
        for name, columns in observables:
            clock = _series(f, f"observables/{name}", () if columns == 1 else (columns,), clock)
        self.observable_clock = clock
        revdem = f.create_group("parameters/revdem")
        revdem.attrs["schema_version"] = SCHEMA_VERSION
        for key, value in parameters.items():
            revdem.attrs[key] = value
        self.last_step: int | None = None

    def frame(self, step: int, time: float, particles, events: np.ndarray) -> None:
        """Append one frame; a frame at the step already written last is skipped."""
        if step == self.last_step:
            return
        self.last_step = step
        group = self.file["particles/all"]
        _append(self.frame_clock["step"], [step])
        _append(self.frame_clock["time"], [time])
        for name, values in zip(
            FRAME_FIELDS, (particles.x, particles.v, particles.omega, particles.f), strict=True
        ):
            _append(group[name]["value"], values[None])
        _append(self.events, events[None])
        self.file.flush()

    def last_observable_step(self) -> int | None:
        steps = self.observable_clock["step"]
        return int(steps[-1]) if steps.shape[0] else None

    def observables(self, steps, times, values) -> None:
        """Append rows of observables; values has the columns of the layout side by side."""
        if len(steps) == 0:
            return
        _append(self.observable_clock["step"], steps)
        _append(self.observable_clock["time"], times)
        column = 0
        for name, columns in self.observables_layout:
            block = values[:, column] if columns == 1 else values[:, column : column + columns]
            _append(self.file[f"observables/{name}/value"], block)
            column += columns

    def close(self) -> None:
        self.file.close()

    def __enter__(self) -> TrajectoryWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_trajectory(path: str | Path) -> h5py.File:
    """Open a revdem trajectory for reading, with a clear error for anything else."""
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, FileNotFoundError):
        raise InputError(f"{path}: not a readable HDF5 file") from None
    if "particles/all/position" not in f or "parameters/revdem" not in f:
        f.close()
        raise InputError(f"{path}: not a revdem trajectory (no /particles/all/position)")
    return f


def frame_steps(f: h5py.File) -> np.ndarray:
    return f["particles/all/position/step"][:]


def read_frame(f: h5py.File, field: str, index: int) -> np.ndarray:
    return f[f"particles/all/{field}/value"][index]


def read_observable(f: h5py.File, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(time, value) of an observable."""
    g = f[f"observables/{name}"]
    return g["time"][:], g["value"][:]
