"""H5MD 1.1 trajectories (readable by MDAnalysis and other H5MD clients).

/h5md                               version [1, 1]; author; creator revdem
/particles/all/{position,velocity,angular_velocity,force}   step [F], time [F], value [F, N, 3]
/particles/all/{radius,mass}        time-independent [N]
/particles/all/id                   time-independent [N]: each sphere's id, the atom id of a
                                    LAMMPS data file it was read from, else its number from 1
/particles/all/species              time-independent [N]: each sphere's material, numbered in
                                    the order of [materials] from 0
/particles/all/stress               [F, N, 3, 3] each sphere's stress (Eq 22), if asked for
/particles/all/{position,velocity,angular_velocity}_grid   [F, N, 3] int64, in fixed-point
                                    arithmetic: the integer state (steps in /parameters/revdem
                                    fixed_grid, kernels/fixed.py)
/particles/all/box                  boundary "periodic" (edges: the cell's at each frame) or
                                    "none" (edges: the bounding box of the spheres); positions
                                    are unwrapped across periodic boundaries
/observables/<name>                 step, time, value [F], [F, 3] or [F, 3, 3]
/observables/events                 value [F, kinds, columns] at each frame: the log of
                                    information-destroying mechanisms (kernels/events.py),
                                    named in its attributes `kinds` and `columns`
/observables/bits_destroyed         with an information tape: value [F, mechanisms], the bits
                                    each mechanism destroyed, named in its attribute `columns`
/connectivity/contacts              with [output] contacts: every contact at every frame, its
                                    frames' rows one after another (H5MD 1.1 connectivity,
                                    particles_group /particles/all): step, time [F] (the
                                    frames'), count [F] contacts in each frame, value [C, 2]
                                    (sphere, partner: another sphere, or -1 - w on wall w),
                                    point, normal_force, tangential_force [C, 3] (N, on the
                                    sphere), overlap [C], sliding [C] (revdem_cli/contacts.py)
/parameters/revdem                  attrs: schema_version (revdem_cli.io.SCHEMA_VERSION, checked on
                                    reading), direction, dt, arithmetic, scenario, source restart
Rows are written in blocks at least every two seconds and at every checkpoint. The file is
written in HDF5's single-writer/multiple-reader mode, whose writes keep the file consistent
at every moment: a run killed at any point leaves a trajectory readable up to its last
flush (`open_hdf5` opens such a file read-only in SWMR mode).
"""

from __future__ import annotations

import getpass
import time
from pathlib import Path

import h5py
import numpy as np

from revdem_cli import __version__
from revdem_cli.errors import InputError, WriteFailed, whole_number
from revdem_cli.io import DAMAGE, FRAME_FIELDS, GRID_FIELDS, SCHEMA_VERSION, one_line, open_hdf5
from revdem_cli.kernels.events import COLUMNS as EVENT_COLUMNS
from revdem_cli.kernels.events import KINDS
from revdem_cli.kernels.tape import MECHANISMS


def _series(
    group: h5py.Group, name: str, shape: tuple, clock: h5py.Group | None, dtype=np.float64
) -> h5py.Group:
    """A time series `name` with value [F, *shape]; step and time shared with `clock`."""
    g = group.create_group(name)
    rows = max(1, 4096 // max(1, int(np.prod(shape))))
    g.create_dataset(
        "value", shape=(0, *shape), maxshape=(None, *shape), dtype=dtype, chunks=(rows, *shape)
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


CONTACTS = "connectivity/contacts"
CONTACT_COUNT = f"{CONTACTS}/count"
CONTACT_FIELDS = {  # name: (shape of a contact's row, type)
    "value": ((2,), np.int64),
    "point": ((3,), np.float64),
    "normal_force": ((3,), np.float64),
    "tangential_force": ((3,), np.float64),
    "overlap": ((), np.float64),
    "sliding": ((), np.int8),
}


def _contact_rows(f: h5py.File, particles: h5py.Group, clock: h5py.Group) -> dict:
    """The datasets of the contact list, empty, each with its appender: `count` a frame and
    the contacts of each frame one after another."""
    group = f.create_group(CONTACTS)
    group.attrs["particles_group"] = particles.ref
    group["step"], group["time"] = clock["step"], clock["time"]
    group.create_dataset("count", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(1024,))
    rows = {"count": _Appender(group["count"])}
    for name, (shape, dtype) in CONTACT_FIELDS.items():
        dataset = group.create_dataset(
            name, shape=(0, *shape), maxshape=(None, *shape), dtype=dtype, chunks=(4096, *shape)
        )
        rows[name] = _Appender(dataset)
    return rows


def bounding_box(x: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Edge lengths of the smallest axis-aligned box holding every sphere, m: the box of a
    frame whose boundaries are open."""
    return (x + radius[:, None]).max(axis=0) - (x - radius[:, None]).min(axis=0)


STUCK: list[TrajectoryWriter] = []
"""Writers whose file HDF5 could not close after a failed write, kept with their objects:
freeing them, or shutting HDF5 down, would try the file again and fail (tracebacks, then
a segmentation fault in HDF5 1.14), so the command line leaves at once instead."""


class _Appender:
    """Rows waiting to be appended to one dataset."""

    def __init__(self, dataset: h5py.Dataset):
        self.dataset = dataset
        self.rows: list[np.ndarray] = []
        self.nbytes = 0

    def add(self, values) -> None:
        values = np.asarray(values)
        self.rows.append(values)
        self.nbytes += values.nbytes

    def write(self) -> None:
        if self.rows:
            _append(self.dataset, np.concatenate(self.rows))
            self.rows, self.nbytes = [], 0


class TrajectoryWriter:
    """Appends frames and observables to a new H5MD file.

    `observables` lists (name, shape): () for a scalar, (3,) a vector, (3, 3) a tensor. Rows
    are gathered in memory and written in blocks, at least every FLUSH_SECONDS and whenever
    FLUSH_BYTES are waiting, so an interrupted run keeps all but its last moments.
    """

    FLUSH_SECONDS = 2.0
    FLUSH_BYTES = 64 * 2**20

    def __init__(
        self,
        path: Path,
        radius,
        mass,
        ids,
        species,
        periodic: bool,
        particle_stress: bool,
        fixed_point: bool,
        contacts: bool,
        observables: list[tuple[str, tuple[int, ...]]],
        events_shape: tuple[int, int],
        parameters: dict,
    ):
        self.path = Path(path)
        self.closed = False
        try:
            self.file = h5py.File(self.path, "w", libver="latest")
            self._create(radius, mass, ids, species, periodic, particle_stress, fixed_point,
                         contacts, observables, events_shape, parameters)  # fmt: skip
        except (OSError, RuntimeError) as exc:
            self._abandon(exc)

    def _create(
        self, radius, mass, ids, species, periodic, particle_stress, fixed_point, contacts,
        observables, events_shape, parameters,
    ) -> None:  # fmt: skip
        """The file's groups and datasets, empty, and its parameters."""
        f = self.file
        h5md = f.create_group("h5md")
        h5md.attrs["version"] = np.array([1, 1])
        h5md.create_group("author").attrs["name"] = getpass.getuser()
        creator = h5md.create_group("creator")
        creator.attrs["name"] = "revdem"
        creator.attrs["version"] = __version__
        # H5MD's units module: every value is SI. No dataset carries a `unit` attribute:
        # MDAnalysis' H5MD reader refuses a file whose positions say "m" (not one of its
        # lengths), even when told not to convert units
        units = h5md.create_group("modules/units")
        units.attrs["version"] = np.array([1, 0])
        units.attrs.create("system", np.bytes_("SI"))
        n = len(radius)
        everything = f.create_group("particles/all")
        box = everything.create_group("box")
        box.attrs["dimension"] = 3
        box.attrs["boundary"] = np.array([b"periodic" if periodic else b"none"] * 3)
        clock = None
        frame_groups = []
        for name in FRAME_FIELDS:
            clock = _series(everything, name, (n, 3), clock)
            frame_groups.append(clock)
        everything.create_dataset("radius", data=radius)
        everything.create_dataset("mass", data=mass)
        everything.create_dataset("id", data=np.asarray(ids, dtype=np.int64))
        everything.create_dataset("species", data=np.asarray(species, dtype=np.int64))
        events = _series(f, "observables/events", events_shape, clock)
        events["value"].attrs["kinds"] = np.array(KINDS, dtype=h5py.string_dtype())
        events["value"].attrs["columns"] = np.array(EVENT_COLUMNS, dtype=h5py.string_dtype())
        edges = _series(box, "edges", (3,), clock)
        self.frame_rows = [_Appender(clock["step"]), _Appender(clock["time"])]
        self.frame_rows += [_Appender(g["value"]) for g in frame_groups + [events, edges]]
        self.stress_rows = None
        if particle_stress:
            self.stress_rows = _Appender(_series(everything, "stress", (n, 3, 3), clock)["value"])
            self.frame_rows.append(self.stress_rows)
        self.grid_rows = []
        if fixed_point:
            for name in GRID_FIELDS:
                values = _series(everything, name, (n, 3), clock, np.int64)["value"]
                self.grid_rows.append(_Appender(values))
            self.frame_rows += self.grid_rows
        self.contact_rows = _contact_rows(f, everything, clock) if contacts else None
        clock = None
        widths = []
        for name, shape in observables:
            clock = _series(f, f"observables/{name}", shape, clock)
            if name == "bits_destroyed":  # its columns: the mechanisms charged
                clock["value"].attrs["columns"] = np.array(MECHANISMS, dtype=h5py.string_dtype())
            widths.append((_Appender(clock["value"]), shape))
        self.observable_clock = [_Appender(clock["step"]), _Appender(clock["time"])]
        self.observable_rows = widths
        revdem = f.create_group("parameters/revdem")
        revdem.attrs["schema_version"] = SCHEMA_VERSION
        for key, value in parameters.items():
            revdem.attrs[key] = value
        self.ended = revdem.create_dataset(ENDED, data=np.int8(0))  # `ended`: 1
        self.last_step: int | None = None
        self.last_observable: int | None = None
        self.file.swmr_mode = True  # everything is created: from here on only appended to
        self.flushed = time.monotonic()

    def copy_rows(self, source: h5py.File, frames: int, observables: int) -> None:
        """Append the first `frames` frames and `observables` observables rows of `source`, a
        trajectory of the same layout (a run continued from a checkpoint)."""
        for appender in self.frame_rows:
            appender.add(source[appender.dataset.name][:frames])
        for appender in self._observable_appenders():
            appender.add(source[appender.dataset.name][:observables])
        if self.contact_rows is not None:
            rows = int(source[CONTACT_COUNT][:frames].sum())
            for appender in self.contact_rows.values():
                appender.add(source[appender.dataset.name][:rows])
        steps = source[self.frame_rows[0].dataset.name][:frames]
        self.last_step = int(steps[-1]) if frames else None
        steps = source[self.observable_clock[0].dataset.name][:observables]
        self.last_observable = int(steps[-1]) if observables else None
        self.flush()

    def rows(self) -> tuple[int, int]:
        """(frames, observables rows) in the file: all of them just after a flush."""
        return self.frame_rows[0].dataset.shape[0], self.observable_clock[0].dataset.shape[0]

    def _phases(self) -> tuple[list[_Appender], list[_Appender]]:
        """The appenders in the two phases of a flush: every value and time, then the steps.
        The file is flushed after each phase, so HDF5 has written the values' and times' new
        extents before any step grows: a run killed at any moment leaves rows of values past
        the last step (which readers ignore), never a step short of its values (which
        `io._check_trajectory` calls damage). Without the flush between, HDF5's metadata
        cache may write one dataset's extent before another's, in any order."""
        values = (
            self.frame_rows[1:]
            + [self.observable_clock[1]]
            + [appender for appender, _ in self.observable_rows]
        )
        values += list((self.contact_rows or {}).values())
        return values, [self.observable_clock[0], self.frame_rows[0]]

    def _appenders(self):
        for phase in self._phases():
            yield from phase

    def _observable_appenders(self):
        yield from self.observable_clock
        yield from (appender for appender, _ in self.observable_rows)

    def frame(
        self,
        step: int,
        time: float,
        particles,
        events: np.ndarray,
        box=None,
        stress=None,
        integers=None,
        contacts=None,
    ) -> None:
        """Append one frame; a frame at the step already written last is skipped. `box`: the
        edges of the periodic cell; None, the bounding box of the spheres. `stress`: each
        sphere's stress, when the writer keeps it; `integers`: the fixed-point state, in
        fixed-point arithmetic; `contacts`: the contact list (`contacts.ContactList`), when
        the writer keeps it."""
        if step == self.last_step:
            return
        self.last_step = step
        values = (
            [step],
            [time],
            particles.x[None],
            particles.v[None],
            particles.omega[None],
            particles.f[None],
            events[None],
            (bounding_box(particles.x, particles.radius) if box is None else box)[None],
        ) + (() if self.stress_rows is None else (stress[None],))
        if self.grid_rows:
            values += tuple(getattr(integers, name)[None] for name in ("x", "v", "omega"))
        for appender, value in zip(self.frame_rows, values, strict=True):
            appender.add(np.array(value))
        if self.contact_rows is not None:
            self.contact_rows["count"].add(np.array([len(contacts)], dtype=np.int64))
            self.contact_rows["value"].add(np.column_stack([contacts.particle, contacts.partner]))
            for name in contacts.FIELDS:
                self.contact_rows[name].add(getattr(contacts, name))
        self._flush_if_due()

    def last_observable_step(self) -> int | None:
        return self.last_observable

    def observables(self, steps, times, values) -> None:
        """Append rows of observables; values has the columns of the layout side by side."""
        if len(steps) == 0:
            return
        self.last_observable = int(steps[-1])
        self.observable_clock[0].add(np.array(steps, dtype=np.int64))  # a copy: callers reuse
        self.observable_clock[1].add(np.array(times, dtype=np.float64))  # their buffers
        column = 0
        for appender, shape in self.observable_rows:
            columns = int(np.prod(shape, dtype=np.int64))
            block = values[:, column : column + columns].reshape(-1, *shape)
            appender.add(block.copy())
            column += columns

    def _flush_if_due(self) -> None:
        waiting = sum(appender.nbytes for appender in self._appenders())
        if waiting > self.FLUSH_BYTES or time.monotonic() - self.flushed > self.FLUSH_SECONDS:
            self.flush()

    def flush(self) -> None:
        """Write everything waiting and flush the file to disk; WriteFailed naming the file
        if it cannot be written."""
        try:
            for phase in self._phases():
                for appender in phase:
                    appender.write()
                self.file.flush()
        except (OSError, RuntimeError) as exc:
            self._abandon(exc)
        self.flushed = time.monotonic()

    def _abandon(self, exc: BaseException):
        """Close a file that can no longer be written (HDF5 then closes every object in it,
        so none is left to fail as the process exits) and raise WriteFailed."""
        self.closed = True
        file = getattr(self, "file", None)
        try:
            if file is not None:
                file.close()
        except (OSError, RuntimeError):  # HDF5 keeps it open, to flush it as it shuts down
            STUCK.append(self)  # its objects kept: each would fail again as it is freed
        raise WriteFailed(self.path, exc) from None

    def end(self) -> None:
        """Mark the trajectory whole: its run reached the step it was to end at (a dataset, as
        SWMR lets no attribute change). One stopped, failed or killed keeps 0 there."""
        self.ended[()] = 1

    def close(self) -> None:
        if self.closed:
            return
        self.flush()
        self.closed = True
        try:
            self.file.close()
        except (OSError, RuntimeError) as exc:
            self._abandon(exc)

    def __enter__(self) -> TrajectoryWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


ENDED = "ended"
"""parameters/revdem/ENDED of a trajectory: 1 once its run reached its end, 0 before
(`TrajectoryWriter.end`); absent in one written before it existed."""


def ended(f: h5py.File) -> bool | None:
    """Whether a trajectory's run reached its end; None where the file does not say."""
    marker = f["parameters/revdem"].get(ENDED)
    return None if marker is None else bool(marker[()])


def open_trajectory(path: str | Path) -> h5py.File:
    """Open a revdem trajectory for reading, checked by `open_hdf5` (schema version, layout,
    stored scenario), with a clear error for anything else."""
    path = Path(path)
    f = open_hdf5(path)
    if "parameters/revdem" not in f:
        what = _what_else(f)
        f.close()
        raise InputError(f"{path}: not a revdem trajectory ({what})")
    return f


def _what_else(f: h5py.File) -> str:
    """What an HDF5 file that is not a revdem trajectory is, in a few words."""
    meta = f.get("revdem")
    if meta is not None and meta.attrs.get("kind") == "restart":
        return "a revdem restart file"
    creator = f.get("h5md/creator")
    if creator is not None and "particles/all/position" in f:
        return f"an H5MD file written by {creator.attrs.get('name', 'another program')}"
    return "no /parameters/revdem"


def _read(f: h5py.File, name: str, index=slice(None)) -> np.ndarray:
    """Rows of a dataset; InputError naming the file if they cannot be read."""
    try:
        return f[name][index]
    except DAMAGE as exc:
        raise InputError(
            f"{f.filename}: damaged revdem trajectory: cannot read {name} ({one_line(exc)})"
        ) from None


def frame_steps(f: h5py.File) -> np.ndarray:
    return _read(f, "particles/all/position/step")


def read_frame(f: h5py.File, field: str, index: int) -> np.ndarray:
    return _finite(f, field, _read(f, f"particles/all/{field}/value", index)[None], [index])[0]


def _finite(f: h5py.File, field: str, rows: np.ndarray, indices) -> np.ndarray:
    """Rows of a field at frames `indices`, refused where a value is not finite: a run
    writes none (`kernels.health` stops it at the last sound state), so one is damage,
    which a comparison would otherwise pass (NaN exceeds no tolerance) and an export
    carry into every frame's box."""
    if rows.dtype.kind != "f" or np.isfinite(rows).all():
        return rows
    frame, *where = np.argwhere(~np.isfinite(rows))[0]
    step = int(_read(f, f"particles/all/{field}/step", int(indices[frame])))
    of = ""
    if rows.ndim == 3:  # (frames, particles, 3)
        from revdem_cli.state import particle_named

        of = f" of {particle_named(int(where[0]), _read(f, 'particles/all/id'))}"
    raise InputError(
        f"{f.filename}: damaged revdem trajectory: {field}{of} at step {step} is not finite"
    )


BLOCK_VALUES = 1 << 20
"""Values of a per-sphere field read at once (8 MB): a reader of every frame takes them a
block at a time (`frames_per_block`), where one by one cost 24 s for the 30 001 frames of a
two-sphere collision."""


def frames_per_block(particles: int) -> int:
    """Frames of a per-sphere field of `particles` spheres in BLOCK_VALUES."""
    return max(1, BLOCK_VALUES // (3 * max(1, particles)))


def read_frames(f: h5py.File, field: str, indices: np.ndarray) -> np.ndarray:
    """The frames `indices` (in any order, each once) of a field in one read: the rows
    between the first and the last where they are dense, else those rows alone (a frame a
    read costs about 150 us of h5py whatever its size)."""
    indices = np.asarray(indices)
    if len(indices) == 0:
        return _read(f, f"particles/all/{field}/value", slice(0, 0))
    ascending = np.sort(indices)
    low, high = int(ascending[0]), int(ascending[-1])
    if high - low + 1 <= 2 * len(indices):
        rows = _read(f, f"particles/all/{field}/value", slice(low, high + 1))[ascending - low]
    else:
        rows = _read(f, f"particles/all/{field}/value", ascending)
    return _finite(f, field, rows[np.searchsorted(ascending, indices)], indices)


def observable_names(f: h5py.File) -> list[str]:
    """The observables a trajectory holds, as `read_observable` takes them: each group with
    a value under /observables, by its path there ("kinetic_energy", "wall_force/top": one
    group a wall), but for the event log."""
    names = set()
    f["observables"].visit(lambda name: names.add(name.removesuffix("/value")))
    return sorted(
        name
        for name in names
        if f"observables/{name}/value" in f and f"observables/{name}/step" in f and name != "events"
    )


def read_observable(f: h5py.File, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(time, value) of an observable."""
    rows = slice(len(_read(f, f"observables/{name}/step")))
    return _read(f, f"observables/{name}/time", rows), _read(f, f"observables/{name}/value", rows)


def observable_steps(f: h5py.File, name: str) -> np.ndarray:
    """The steps of an observable's rows, as `read_observable` gives their times and values."""
    return _read(f, f"observables/{name}/step")


def rows_by_step(steps: np.ndarray, reverse: bool = False) -> dict[int, list[int]]:
    """The observables rows of each step of a trajectory (`observable_steps`), in the order
    the forward run wrote them: one a step, but two where a stage began at the step the
    stage before ended at and its law changed the contacts there (`stage.StageStart`): that
    stage's end, then the later stage's own start. A reversed run (`reverse`) wrote them in
    the other order, which is turned."""
    rows: dict[int, list[int]] = {}
    for row, step in enumerate(steps.tolist()):
        rows.setdefault(step, []).append(row)
    if reverse:
        rows = {step: there[::-1] for step, there in rows.items()}
    return rows


def from_stage_start(steps: np.ndarray, first: int, reverse: bool = False) -> np.ndarray:
    """Which observables rows of a trajectory (`observable_steps`) are of the stage that began
    at step `first` or after it: those of later steps and, at `first`, the stage's own start
    (the last in the forward run's order, `rows_by_step`), not the end of the stage before
    written beside it."""
    within = steps >= first
    within[rows_by_step(steps, reverse).get(first, [])[:-1]] = False
    return within


def read_contacts(f: h5py.File, index: int) -> dict[str, np.ndarray] | None:
    """The contacts of frame `index` by name (value: sphere and partner, point, ...), or
    None if the trajectory has none."""
    if not whole_number(index):
        raise InputError(f"frame {index!r}: must be a whole number, a frame's index (-1: the last)")
    if CONTACTS not in f:
        return None
    frames = len(frame_steps(f))
    if not -frames <= index < frames:
        raise InputError(
            f"frame {index!r}: the trajectory has {frames} frames, 0 to {frames - 1} (-1: the last)"
        )
    index %= frames  # -1: the last frame
    counts = _read(f, CONTACT_COUNT, slice(index + 1))
    rows = slice(int(counts[:-1].sum()), int(counts.sum()))
    return {name: _read(f, f"{CONTACTS}/{name}", rows) for name in CONTACT_FIELDS}
