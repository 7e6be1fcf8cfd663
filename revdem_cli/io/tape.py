"""The information tape's file (`<name>.tape.h5`, named in the restart) and the buffers the
compiled loop records into and replays from (`kernels.tape`).

Entries go to disk in blocks, so the tape's memory does not grow with the run: the loop
returns TAPE_FULL when its block may have no room for one more step (it has less than the
most entries a step has made so far), and a thread of its own appends the block to the file
while the loop fills a fresh one. The block holds one entry a particle (at least
MIN_ENTRIES) and grows only for a step that needs more: that step's entries are then
recorded again (`Recorder.flush`). Blocks lie on pages mapped for them alone
(`memory.untouched`), which take memory only where entries are written and go back to the
system once written out, so that the tape holds about two steps' entries however large its
blocks.
Layout (HDF5, every dataset chunked, shuffled and compressed with Zstandard through
hdf5plugin; each column of the steps' rows in chunks of its own, `CHUNK` steps long):

    /entries/what    int8   (E,)  the array, an index into `kernels.tape.COMPARED`
    /entries/where   int64  (E,)  its place (pair arrays: (i N + j) 3 + axis)
    /entries/amount  int64  (E,)  the true value minus the reversal's
    /steps/count     int64  (S,)  entries of each step of the stage, from its first
    /steps/bits      float64 (S, M) bits of each step by mechanism (`MECHANISMS`)
    /steps/contacts  int32  (S, M) contacts (particles, edges) with entries, by mechanism
    /blocks          int64  (B, 6) each block appended: its first step (from the stage's
                                   first), steps, first entry, entries, and the CRC-32 of
                                   its steps' rows and of its entries (`_checksums`)

with the attributes `kind` = "revdem tape", `schema_version`, `first_step`, `first_time`
and `dt` (the stage's), `stage`, `particles`, `state_bytes` (the compared state of one step,
which `summary` sets the tape beside), `compared` and `mechanisms`; once its stage has ended,
`last_step` and `end_sha256` (`end_digest` of the integers there), which tie the tape to
the restart written at that step: a reversal replays only the tape of its own restart.
Going backward, `Replayer` reads it a block at a time from the end. The checksums are
verified (`_verified`) before a reversal's first step and wherever the tape is
summarised: Zstandard and HDF5 check nothing, and a flipped bit in a chunk reads back as
another entry or another count of bits.
"""

from __future__ import annotations

import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import h5py
import hdf5plugin
import numpy as np

from revdem_cli.errors import InputError, RunFailed
from revdem_cli.kernels.tape import (
    COMPARED,
    MECHANISMS,
    OFF,
    RECORD,
    REPLAY,
    Tape,
    predictable,
)
from revdem_cli.memory import release, untouched

SCHEMA_VERSION = 3
STEPS_PER_BLOCK = 4096
MIN_ENTRIES = 1 << 16
ENTRIES_PER_PARTICLE = 1
ROOM_FOR_STEPS = 1.5
"""A block that grows takes room for this many steps of the most entries a step has made:
then a step that makes about as many is written out on its own while the next fills a
fresh block, and a step is recorded again only where its entries outgrow the most by half.
More room would hold more steps in memory; less, record growing steps again more often."""
CHUNK = 1 << 14
"""Entries, or steps, a chunk of a tape's datasets holds. A column of the steps' rows is a
chunk's alone: a mechanism's bits, step after step, repeat where rows of every mechanism
interleaved do not (drop B's tape, 8e6 steps: 0.17 MB of steps' rows, where chunks of
4 096 whole rows took 16.2 MB)."""
FILTERS = dict(**hdf5plugin.Zstd(clevel=1), shuffle=True)
"""Zstandard at level 1 through hdf5plugin, after HDF5's byte shuffle: on the fcc
benchmark's entries (n = 10, with history) 3.7 times as fast as gzip at its fastest level,
for files 6 % smaller (the smoke oedometer's pour, whose entries are damped forces: 16 %
larger). Tapes written with gzip read as well."""

CHANGED = (
    ("particles", ("f", "torque", "v_drift")),
    ("pairs", ("force", "history", "moment", "overlap", "destroyed", "rolling", "rolled",
               "normal")),
    ("walls", ("point", "force", "torque", "overlap", "history", "destroyed", "rolling",
               "rolled")),
    ("cell", ("length", "rate", "mid", "force", "stress")),
    ("fixed", ("x", "v", "omega", "length", "rate", "overflow")),
)  # fmt: skip
"""The arrays a step changes (with the event log): what the shadow reversal undoes. Not the
positions' and velocities' floating-point images, which `kernels.tape.restore` makes again
from their integers, nor the normals the reversed step unwinds across (`normal_new`), which
it writes before it reads them and no forward step reads."""

COMPARED_ARRAYS = {
    "cell_edges": ("fixed", "length"),
    "cell_edge_rates": ("fixed", "rate"),
    "cell_length": ("cell", "length"),
    "cell_rate": ("cell", "rate"),
    "position": ("fixed", "x"),
    "shear_history": ("pairs", "history"),
    "rolling_history": ("pairs", "rolling"),
    "wall_shear_history": ("walls", "history"),
    "wall_rolling_history": ("walls", "rolling"),
    "cell_force": ("cell", "force"),
    "cell_stress": ("cell", "stress"),
    "force": ("particles", "f"),
    "moment": ("particles", "torque"),
    "velocity": ("fixed", "v"),
    "angular_velocity": ("fixed", "omega"),
}
"""Where each array of `kernels.tape.COMPARED` is in a `State`."""
assert tuple(COMPARED_ARRAYS) == COMPARED


_NOTHING8 = np.zeros(0, dtype=np.uint8)
_NOTHING64 = np.zeros(0, dtype=np.int64)


def _flat(array: np.ndarray, dtype) -> np.ndarray:
    """`array` as a flat view of `dtype` (never a copy)."""
    if not array.flags.c_contiguous:
        raise ValueError("the information tape views only contiguous arrays")
    return array.reshape(-1).view(dtype)


def _changed(state, events) -> tuple:
    arrays = [getattr(getattr(state, bundle), name) for bundle, names in CHANGED for name in names]
    return tuple(_flat(a, np.int64) for a in arrays + [events])


def _compared(state) -> tuple:
    """The compared arrays as int64 views."""
    return tuple(
        _flat(getattr(getattr(state, bundle), name), np.int64)
        for bundle, name in COMPARED_ARRAYS.values()
    )


_UNCHANGED = tuple(_NOTHING64 for _ in range(sum(len(names) for _, names in CHANGED) + 1))
_UNCOMPARED = tuple(_NOTHING64 for _ in COMPARED)
"""What a tape that neither copies nor compares the state has in place of `_changed` and
`_compared`: without a tape, or recording by prediction."""


def no_tape() -> Tape:
    """The tape of a run without one."""
    return Tape(
        OFF, _UNCHANGED, _UNCHANGED, _UNCOMPARED, _UNCOMPARED, _NOTHING8, _NOTHING8,
        np.zeros(0, dtype=np.int8), _NOTHING64, _NOTHING64, _NOTHING64,
        np.zeros((0, len(MECHANISMS))), np.zeros((0, len(MECHANISMS)), dtype=np.int64),
        _NOTHING64, np.zeros(5, dtype=np.int64), 0,
    )  # fmt: skip


class _Buffers:
    """The arrays a tape bundle is made of, kept from call to call and made anew only where
    the state's arrays changed size (a pair list grown)."""

    def __init__(self):
        self.kept: tuple = ()
        self.before: tuple = ()
        self.what = np.zeros(0, dtype=np.int8)
        self.where = _NOTHING64
        self.amount = _NOTHING64
        self.counts = np.zeros(STEPS_PER_BLOCK, dtype=np.int64)
        self.bits = np.zeros((STEPS_PER_BLOCK, len(MECHANISMS)))
        self.contacts = np.zeros((STEPS_PER_BLOCK, len(MECHANISMS)), dtype=np.int64)
        self.offsets = np.zeros(STEPS_PER_BLOCK + 1, dtype=np.int64)
        self.span = np.zeros(5, dtype=np.int64)
        self.causes = _NOTHING8
        self.wall_causes = _NOTHING8

    def bundle(self, state, events, mode: int, predicting: bool = False) -> Tape:
        """The tape of the stepping loop's next call; `predicting`: recorded by
        `kernels.tape.predict` from the pairs the forward pair loop lists (`Pairs.earlier`),
        with no copy of the state before a step nor of the one after it."""
        live = _UNCHANGED if predicting else _changed(state, events)
        compared = _UNCOMPARED if predicting else _compared(state)
        self.kept = _like(self.kept, live)
        self.before = _like(self.before, compared)
        self.grow(max(MIN_ENTRIES, ENTRIES_PER_PARTICLE * state.particles.x.shape[0]))
        pairs = state.pairs.i.shape[0]
        if not predicting and self.causes.shape[0] != 2 * pairs:
            self.causes = np.zeros(2 * pairs, dtype=np.uint8)
        contacts = state.walls.overlap.size
        if not predicting and self.wall_causes.shape[0] != 2 * contacts:
            self.wall_causes = np.zeros(2 * contacts, dtype=np.uint8)
        return Tape(
            mode, live, self.kept, compared, self.before, self.causes, self.wall_causes,
            self.what, self.where, self.amount, self.counts, self.bits, self.contacts,
            self.offsets, self.span, int(predicting),
        )  # fmt: skip

    def grow(self, capacity: int) -> None:
        """Room for at least `capacity` entries, those held kept."""
        if self.what.shape[0] >= capacity:
            return
        used = min(int(self.span[2]), self.what.shape[0])
        what, where, amount = self.what, self.where, self.amount
        self.renew(capacity)
        self.what[:used], self.where[:used], self.amount[:used] = (
            what[:used],
            where[:used],
            amount[:used],
        )

    def renew(self, capacity: int) -> None:
        """A fresh block of room for `capacity` entries, the one before left to whoever holds
        it (the writer thread)."""
        self.what = untouched(capacity, np.int8)
        self.where = untouched(capacity, np.int64)
        self.amount = untouched(capacity, np.int64)


def _like(copies: tuple, arrays: tuple) -> tuple:
    """Copies with the sizes of `arrays` (those of `copies` where they fit)."""
    if len(copies) == len(arrays) and all(
        c.shape == a.shape for c, a in zip(copies, arrays, strict=True)
    ):
        return copies
    return tuple(np.zeros_like(a) for a in arrays)


class Recorder:
    """Records the tape of a stage going forward into `path`, from the stage's `first_step`;
    resuming at `step`, the file's steps from there on are dropped and recording goes on."""

    def __init__(self, path: Path, stage: str, clock: tuple[int, float, float], state, step=None):
        """`clock`: the stage's first step, its time there (s) and its time step (s); `state`:
        the state at the stage's start (or, resuming, at `step`)."""
        self.path = Path(path)
        self.first_step = clock[0]
        self.buffers = _Buffers()
        self.written_steps = 0
        self.written_entries = 0
        self.written_bits = np.zeros(len(MECHANISMS))  # by mechanism, handed to the writer
        self.pending = None  # the block the writer thread is appending, a Future
        if step is None:  # by the writer, after any block of this file still being written
            _WRITER.submit(self._create, stage, clock, state).result()
        else:
            _WRITER.submit(self._truncate, step - self.first_step).result()
        self.buffers.span[:] = (self.first_step + self.written_steps, 0, 0, 0, 0)

    def _create(self, stage: str, clock: tuple[int, float, float], state) -> None:
        m = len(MECHANISMS)
        with _open(self.path, "w") as f:
            f.attrs.update(
                kind="revdem tape", schema_version=SCHEMA_VERSION, first_step=clock[0],
                first_time=clock[1], dt=clock[2], stage=stage, particles=len(state.particles.x),
                state_bytes=state_bytes(state), compared=list(COMPARED),
                mechanisms=list(MECHANISMS),
            )  # fmt: skip
            for name, dtype in (("what", np.int8), ("where", np.int64), ("amount", np.int64)):
                f.create_dataset(
                    f"entries/{name}", (0,), dtype, maxshape=(None,), chunks=(CHUNK,), **FILTERS
                )
            f.create_dataset(
                "steps/count", (0,), np.int64, maxshape=(None,), chunks=(CHUNK,), **FILTERS
            )
            for name, dtype in (("bits", np.float64), ("contacts", np.int32)):
                f.create_dataset(
                    f"steps/{name}", (0, m), dtype, maxshape=(None, m), chunks=(CHUNK, 1), **FILTERS
                )
            f.create_dataset("blocks", (0, 6), np.int64, maxshape=(None, 6), chunks=(256, 6))

    def _truncate(self, steps: int) -> None:
        """Keep the file's first `steps` steps (a checkpoint's), and the entries they hold."""
        with _open(self.path, "a") as f:
            if f["steps/count"].shape[0] < steps:
                raise InputError(
                    f"{self.path}: the information tape holds {f['steps/count'].shape[0]} "
                    f"steps, the checkpoint needs {steps}"
                )
            entries = int(f["steps/count"][:steps].sum())
            self.written_bits = _running(np.zeros(len(MECHANISMS)), f["steps/bits"][:steps])[-1]
            for name in ("count", "bits", "contacts"):
                f[f"steps/{name}"].resize(steps, axis=0)
            for name in ("what", "where", "amount"):
                f[f"entries/{name}"].resize((entries,))
            blocks = f["blocks"][:]  # a checkpoint is taken with every block written
            kept = int(np.searchsorted(blocks[:, 0] + blocks[:, 1], steps, side="right"))
            if kept and blocks[kept - 1, 0] + blocks[kept - 1, 1] != steps:
                raise InputError(f"{self.path}: damaged tape (no block ends at step {steps})")
            f["blocks"].resize(kept, axis=0)
            for name in ("last_step", "end_sha256"):  # it ends elsewhere now
                f.attrs.pop(name, None)
        self.written_steps, self.written_entries = steps, entries

    def bundle(self, state, events, law, dyn) -> Tape:
        """The tape the stepping loop records into, under the stage's contact law and
        dynamics: by prediction where they allow it (`kernels.tape.predictable`). The pages
        of the list of histories the reversal would miss (`Pairs.earlier`) go back to the
        system first, unless a step is to be recorded again from it, so that the list takes
        memory for the rows of one call, not for the most each chunk of the pairs has listed
        in any call: where the contacts of one part of a packing slide before another's,
        that nearly doubled it on two threads."""
        predicting = predictable(state.particles, state.pairs, state.walls, state.cell, law, dyn)
        if predicting and not self.retaking:  # the list the last call predicted from is spent
            release(state.pairs.earlier)
        return self.buffers.bundle(state, events, RECORD, predicting)

    def flush(self, wait: bool = False) -> None:
        """Hand the block recorded so far to the writer thread, which appends it to the file
        while the stepping loop goes on (it releases the GIL), and empty it; `wait`: until
        every block handed over is in the file. Where its last step made more entries than
        the block had room for, that step is left out, the block grown to ROOM_FOR_STEPS
        times the most a step has made, and the stepping loop, called next, records the
        step again before it steps on (`retaking`)."""
        b = self.buffers
        steps, entries = int(b.span[1]), int(b.span[2])
        again = entries > b.what.shape[0]
        if again:
            steps -= 1
            entries = int(b.offsets[steps])
            b.bits[steps] = 0.0
            b.contacts[steps] = 0
        self._write(steps, entries)
        if again:
            b.grow(int(ROOM_FOR_STEPS * int(b.span[3])))
            b.span[4] = 1
        if wait:
            self._written()

    def finish(self, state) -> None:
        """At the stage's end: every block written, then the step the tape ends at and the
        digest of the integers there (`end_digest`), which the restart written at that
        step holds and `Replayer` checks, so that no other run's tape is replayed."""
        self.flush(wait=True)
        _WRITER.submit(_mark_end, self.path, state.step, end_digest(state.fixed)).result()

    @property
    def retaking(self) -> bool:
        """Whether the stepping loop has a step to record again before it steps on."""
        return bool(self.buffers.span[4])

    def _write(self, steps: int, entries: int) -> None:
        """Hand the block's first `steps` steps and `entries` entries to the writer (once the
        block before is written: one at a time), and go on in a fresh block of the same room
        (the entries are not copied: the writer has the block itself)."""
        b = self.buffers
        if steps == 0:
            b.span[:3] = (self.first_step + self.written_steps, 0, 0)
            return
        block = (
            b.what[:entries], b.where[:entries], b.amount[:entries],
            b.counts[:steps].copy(), b.bits[:steps].copy(), b.contacts[:steps].astype(np.int32),
        )  # fmt: skip
        self._written()
        self.pending = _WRITER.submit(_append_block, self.path, block)
        b.renew(b.what.shape[0])
        self.written_steps += steps
        self.written_entries += entries
        self.written_bits = _running(self.written_bits, b.bits[:steps])[-1]
        b.bits[:steps] = 0.0
        b.contacts[:steps] = 0
        b.offsets[:] = 0
        b.span[:3] = (self.first_step + self.written_steps, 0, 0)

    def _written(self) -> None:
        """Wait for the block the writer has; its failure is raised here."""
        if self.pending is not None:
            pending, self.pending = self.pending, None
            pending.result()

    def destroyed_by(self, steps: np.ndarray) -> np.ndarray:
        """The bits recorded from the stage's start to each of `steps` (of the block being
        recorded or its end), by mechanism, (len(steps), len(MECHANISMS))."""
        recorded = int(self.buffers.span[1])
        so_far = _running(self.written_bits, self.buffers.bits[:recorded])
        labels = np.asarray(steps) - self.first_step - self.written_steps
        return so_far[np.clip(labels, 0, recorded)]


class Replayer:
    """Gives the reversed run the tape's entries, a block at a time from the end, and the bits
    the forward run recorded up to each step (`destroyed_by`)."""

    def __init__(
        self, path: Path, stage: str, clock: tuple[int, int], particles: int, restart,
        end=None, before=None,
    ):  # fmt: skip
        """`clock`: the stage's first step and the step it ended at; `restart`: the file the
        reversal reverses from, named where the tape is not its; `end`: the integers there
        (`State.fixed`) where the reversal starts from them (not a checkpoint of it), which
        must be those the tape ends with; `before`: the bits the forward run wrote at the
        stage's first step where a stage before it ended there (that stage's, by mechanism:
        `recorded`, or NaN without a tape); None for the run's first stage, whose first step
        holds zero."""
        self.path = Path(path)
        first_step, last_step = clock
        with _open(self.path, "r") as f:
            attrs = dict(f.attrs)
            if attrs.get("kind") != "revdem tape":
                raise InputError(f"{self.path}: not a revdem information tape")
            if int(attrs.get("schema_version", -1)) != SCHEMA_VERSION:
                raise InputError(
                    f"{self.path}: information tape schema {attrs.get('schema_version')}, "
                    f"this revdem reads {SCHEMA_VERSION}"
                )
            if (attrs["stage"], int(attrs["first_step"]), int(attrs["particles"])) != (
                stage,
                first_step,
                particles,
            ):
                raise InputError(
                    f"{self.path}: the information tape of stage {attrs['stage']} from step "
                    f"{attrs['first_step']} with {attrs['particles']} particles, not of stage "
                    f"{stage} from step {first_step} with {particles}"
                )
            _check_end(self.path, attrs, restart, last_step, end)
            held = _verified(f, self.path, entries=True)
            counts = held.counts
            if counts.shape[0] != last_step - first_step:  # refused before the first step
                raise InputError(
                    f"{self.path}: the information tape holds steps {first_step} to "
                    f"{first_step + counts.shape[0] - 1}, the reversal needs steps {first_step} "
                    f"to {last_step - 1}"
                )
            self.sums = held.sums
            self.summary = _summary(f, self.path, held)  # what `summary` would read again
        self.first_step = first_step
        self.starts = np.concatenate(([0], np.cumsum(counts)))
        self.buffers = _Buffers()
        self.before = before

    @property
    def steps(self) -> int:
        return self.starts.shape[0] - 1

    @property
    def recorded(self) -> np.ndarray:
        """The bits the tape recorded over its whole stage, by mechanism (`recorded`)."""
        return self.sums[-1]

    def bundle(self, state, events, law=None, dyn=None) -> Tape:
        """The tape the stepping loop replays from (`law` and `dyn` are `Recorder.bundle`'s,
        which a replay does not need)."""
        return self.buffers.bundle(state, events, REPLAY)

    def destroyed_by(self, steps: np.ndarray) -> np.ndarray:
        """The bits the forward run recorded from the stage's start to each of `steps`, by
        mechanism, (len(steps), len(MECHANISMS)): those the reversal has yet to give back,
        the same to the last digit as the forward run's `Recorder.destroyed_by` there. At
        the stage's first step, where the stage before ended, `before` where given (the
        forward run's row there is that stage's)."""
        labels = np.clip(np.asarray(steps) - self.first_step, 0, self.steps)
        bits = np.zeros((labels.shape[0], len(MECHANISMS)))
        blocks = labels // STEPS_PER_BLOCK
        with _open(self.path, "r") as f:
            for k in np.unique(blocks):  # summed on from the block's first step, as forward
                start = k * STEPS_PER_BLOCK
                block = f["steps/bits"][start : start + STEPS_PER_BLOCK]
                bits[blocks == k] = _running(self.sums[k], block)[labels[blocks == k] - start]
        if self.before is not None:
            bits[labels == 0] = self.before
        return bits

    def load(self, step: int) -> None:
        """Fill the block with the entries of the steps up to `step` - 1 (the next the
        reversed run steps to), as many as it holds."""
        b = self.buffers
        high = step - 1 - self.first_step  # the last label, counted from the stage's start
        if not 0 <= high < self.steps:
            raise RunFailed(
                f"{self.path}: the information tape holds steps {self.first_step} to "
                f"{self.first_step + self.steps - 1}, the reversal needs step {step - 1}"
            )
        b.grow(int(self.starts[high + 1] - self.starts[high]))
        room = b.what.shape[0]
        low = high
        while (
            low > 0
            and high - low + 1 < STEPS_PER_BLOCK
            and self.starts[high + 1] - self.starts[low - 1] <= room
        ):
            low -= 1
        begin, end = int(self.starts[low]), int(self.starts[high + 1])
        with _open(self.path, "r") as f:
            b.what[: end - begin] = f["entries/what"][begin:end]
            b.where[: end - begin] = f["entries/where"][begin:end]
            b.amount[: end - begin] = f["entries/amount"][begin:end]
        b.offsets[: high - low + 2] = self.starts[low : high + 2] - begin
        b.span[:3] = (self.first_step + low, high - low + 1, end - begin)


def end_digest(fixed) -> str:
    """SHA-256 of the integers of a state (`State.fixed`: positions, velocities, angular
    velocities, the cell's edges and their rates), each as the restart's `digest`: what the
    state at a tape's last step and the restart's must share."""
    import hashlib

    from revdem_cli.io.restart import digest

    parts = (digest(getattr(fixed, name)) for name in ("x", "v", "omega", "length", "rate"))
    return hashlib.sha256(" ".join(parts).encode()).hexdigest()


def _mark_end(path: Path, step: int, sha256: str) -> None:
    with _open(path, "a") as f:
        f.attrs.update(last_step=step, end_sha256=sha256)


def _check_end(path: Path, attrs: dict, restart, last_step: int, end) -> None:
    """InputError naming the tape and the restart unless the tape ends where the restart
    was written (`last_step`), with its integers (`end`, where given): a tape copied
    from another run, or from a longer or shorter run of the same one, is not replayed."""
    why = None
    if "last_step" not in attrs:
        why = "its stage never ended (the run recording it stopped part-way)"
    elif int(attrs["last_step"]) != last_step:
        why = f"it ends at step {int(attrs['last_step'])}, the restart's stage at step {last_step}"
    elif end is not None and str(attrs.get("end_sha256")) != end_digest(end):
        why = f"at step {last_step} it ends with other integers than the restart holds"
    if why:
        raise InputError(f"{path}: not the information tape of {restart}: {why}")


def _running(total: np.ndarray, bits: np.ndarray) -> np.ndarray:
    """`total`, then `total` plus each row of `bits` in turn: one sum, step by step in the
    same order however the rows came in blocks, so that a run resumed from a checkpoint
    reports the bits of an uninterrupted one to the last digit."""
    return np.cumsum(np.vstack((total, bits)), axis=0)


def recorded(path: Path) -> np.ndarray:
    """The bits a tape recorded over its whole stage, by mechanism, summed as `Recorder`
    sums them (its rows of the stage's last step)."""
    with _open(Path(path), "r") as f:
        return _verified(f, Path(path), entries=False).sums[-1]


def state_bytes(state) -> int:
    """The bytes of the arrays the tape compares, the listed pairs' only: what storing the
    whole state at every step would take, step by step."""
    listed = int(state.pairs.count[0])
    total = 0
    for bundle, name in COMPARED_ARRAYS.values():
        array = getattr(getattr(state, bundle), name)
        total += array[:listed].nbytes if bundle == "pairs" else array.nbytes
    return total


_WRITER = ThreadPoolExecutor(max_workers=1, thread_name_prefix="revdem-tape")
"""Appends the blocks of every tape recorded, one at a time (`Recorder.flush`)."""


BLOCK_DATASETS = ("entries/what", "entries/where", "entries/amount", "steps/count", "steps/bits",
                  "steps/contacts")  # fmt: skip
"""A block's arrays, in the order `Recorder._write` hands them over."""


def _append_block(path: Path, block: tuple) -> None:
    """Append a block (`Recorder._write`) to the tape at `path`, with its row of /blocks."""
    with _open(path, "a") as f:
        row = (f["steps/count"].shape[0], block[3].shape[0], f["entries/what"].shape[0])
        for name, values in zip(BLOCK_DATASETS, block, strict=True):
            _append(f[name], values)
        _append(f["blocks"], np.array([[*row, block[0].shape[0], *_checksums(block)]]))


def _checksums(block: tuple) -> tuple[int, int]:
    """CRC-32 of a block's steps' rows (count, bits, contacts) and of its entries (what,
    where, amount), each over the arrays' bytes in turn, as `BLOCK_DATASETS` stores them:
    zlib's, some 1 GB/s, in the writer thread while the loop steps on."""
    steps = entries = 0
    for name, values in zip(BLOCK_DATASETS, block, strict=True):
        data = np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("<"))
        if name.startswith("steps/"):
            steps = zlib.crc32(data, steps)
        else:
            entries = zlib.crc32(data, entries)
    return steps, entries


@dataclass
class _Held:
    """What a tape's blocks hold, read once and checked against their checksums (`_verified`):
    the entries of each step (`counts`), the bits recorded before every STEPS_PER_BLOCK-th
    step and over all the steps last, by mechanism (`sums`: `Replayer.destroyed_by` sums on
    from them), and the contacts with entries over all the steps, by mechanism."""

    counts: np.ndarray
    sums: list[np.ndarray]
    contacts: np.ndarray


def _verified(f: h5py.File, path: Path, entries: bool) -> _Held:
    """What the open tape `f` holds, each block read once and checked against its checksums
    (`_checksums`): its steps' rows, and with `entries` its entries too, so that a check
    and what is taken from the tape come from one read. InputError "damaged tape" naming
    the file and the first block (its steps) that fails them, cannot be read, or does not
    start where the blocks before end, or where the blocks do not cover the datasets end to
    end."""
    first = int(f.attrs["first_step"])
    counts, sums = [], _Sums()
    contacts = np.zeros(len(MECHANISMS), dtype=np.int64)
    try:
        blocks = f["blocks"][:]
        sizes = (f["steps/count"].shape[0], f["entries/what"].shape[0])
        ends = (0, 0)
        for k, (step, steps, entry, count, crc_steps, crc_entries) in enumerate(blocks):
            where = f"block {k}, steps {first + step} to {first + step + steps - 1}"
            if (step, entry) != ends or steps <= 0 or count < 0:
                raise InputError(f"{path}: damaged tape ({where}: not where the blocks before end)")
            ends = (step + steps, entry + count)
            names = BLOCK_DATASETS if entries else BLOCK_DATASETS[3:]
            block = [
                f[name][step : step + steps] if name.startswith("steps/") else
                f[name][entry : entry + count] for name in names
            ]  # fmt: skip
            block = [np.zeros(0, np.int8)] * (6 - len(block)) + block
            found = _checksums(tuple(block))
            if found[0] != crc_steps or entries and found[1] != crc_entries:
                raise InputError(f"{path}: damaged tape ({where} fail their checksum)")
            if int(block[3].sum()) != count:
                raise InputError(f"{path}: damaged tape ({where}: entries miscounted)")
            counts.append(block[3])
            sums.add(step, block[4])
            contacts += block[5].sum(axis=0, dtype=np.int64)
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: damaged tape (cannot be read: {exc})") from None
    if ends != sizes if entries else ends[0] != sizes[0]:
        raise InputError(
            f"{path}: damaged tape ({sizes[0]} steps and {sizes[1]} entries, its blocks cover "
            f"{ends[0]} and {ends[1]})"
        )
    counts = np.concatenate(counts) if counts else np.zeros(0, dtype=np.int64)
    return _Held(counts, sums.ended(ends[0]), contacts)


class _Sums:
    """The bits recorded before every STEPS_PER_BLOCK-th step of a tape, by mechanism, summed
    on from its blocks' rows of /steps/bits in turn as `Recorder` sums them (`_running`:
    one sum, step by step, however the rows came in blocks)."""

    def __init__(self):
        self.total = np.zeros(len(MECHANISMS))
        self.sums = [self.total]

    def add(self, step: int, bits: np.ndarray) -> None:
        """The rows of the steps from `step` (counted from the stage's start) on."""
        running = _running(self.total, bits)
        first = STEPS_PER_BLOCK - step % STEPS_PER_BLOCK  # the next boundary, from `step`
        self.sums.extend(running[first : bits.shape[0] + 1 : STEPS_PER_BLOCK])
        self.total = running[-1]

    def ended(self, steps: int) -> list[np.ndarray]:
        """The sums, with the bits over all `steps` steps last."""
        return self.sums + ([self.total] if steps % STEPS_PER_BLOCK else [])


def _append(dataset, values: np.ndarray) -> None:
    old = dataset.shape[0]
    dataset.resize(old + values.shape[0], axis=0)
    dataset[old:] = values


def _open(path: Path, mode: str) -> h5py.File:
    """The tape at `path`; InputError "not there" where reading finds no file (h5py's own
    words name errno and HDF5's internals), and naming the file for any other failure."""
    if mode == "r" and not Path(path).is_file():
        raise InputError(f"{path}: not there")
    try:
        return h5py.File(path, mode)
    except OSError as exc:
        if mode == "r":
            raise InputError(f"{path}: cannot read the information tape ({exc})") from None
        raise RunFailed(f"{path}: cannot write the information tape ({exc})") from None


def by_step(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """A tape's steps, their times (s), the bits of each by mechanism, and the mechanisms'
    names."""
    with _open(Path(path), "r") as f:
        _verified(f, Path(path), entries=False)
        bits = f["steps/bits"][:].astype(np.float64)
        first, time, dt = int(f.attrs["first_step"]), float(f.attrs["first_time"]), f.attrs["dt"]
        names = [str(name) for name in f.attrs["mechanisms"]]
    labels = np.arange(bits.shape[0])
    return first + labels, time + labels * float(dt), bits, names


def summary(path: Path) -> dict:
    """What a tape holds (`_summary`), its blocks checked against their checksums."""
    with _open(Path(path), "r") as f:
        return _summary(f, Path(path), _verified(f, Path(path), entries=True))


def _summary(f: h5py.File, path: Path, held: _Held) -> dict:
    """What the open tape `f` holds (`held`, as `_verified` read it): the bytes its datasets
    take, compressed, against storing the compared state at every step, and the bits it
    recorded, in all and by mechanism (summed as `Recorder` sums them, so that they are the
    last row of the trajectory's bits_destroyed to the last digit), with the contacts,
    particles or edges that had entries, counted once a step. The bytes are every
    dataset's, the entries, the steps' rows and the blocks' checksums; the file adds
    HDF5's headers and, after a resumed run cut the tape back, the space the cut freed: a
    resumed run's tape holds the same bytes in a larger file."""
    steps = int(held.counts.shape[0])
    full = int(f.attrs["state_bytes"]) * steps
    size = _stored_bytes(f)
    total = held.sums[-1]
    return {
        "file": path.name,
        "steps": steps,
        "entries": int(f["entries/what"].shape[0]),
        "bytes": size,
        "full_state_bytes": full,
        "size_over_full_state": size / full if full else None,
        "bits_destroyed": float(total.sum()),
        "bits_per_step": float(total.sum() / steps) if steps else 0.0,
        "by_mechanism": {
            name: {"bits": float(total[k]), "with_entries": int(held.contacts[k])}
            for k, name in enumerate(MECHANISMS)
            if total[k] > 0
        },
    }


def _stored_bytes(f: h5py.File) -> int:
    """The bytes every dataset of the open tape `f` takes in the file, compressed: the
    entries, the steps' rows and /blocks, without HDF5's headers."""
    datasets = []
    f.visititems(lambda _, item: datasets.append(item) if isinstance(item, h5py.Dataset) else None)
    return sum(dataset.id.get_storage_size() for dataset in datasets)


def combined(summaries: list[dict]) -> dict:
    """The `summary` of several tapes (a reversal of every stage) taken together."""
    total = {"file": ", ".join(part["file"] for part in summaries)}
    for key in ("steps", "entries", "bytes", "full_state_bytes", "bits_destroyed"):
        total[key] = sum(part[key] for part in summaries)
    full = total["full_state_bytes"]
    total["size_over_full_state"] = total["bytes"] / full if full else None
    total["bits_per_step"] = total["bits_destroyed"] / total["steps"] if total["steps"] else 0.0
    mechanisms: dict[str, dict] = {}
    for part in summaries:
        for name, amount in part["by_mechanism"].items():
            into = mechanisms.setdefault(name, {"bits": 0.0, "with_entries": 0})
            into["bits"] += amount["bits"]
            into["with_entries"] += amount["with_entries"]
    total["by_mechanism"] = {name: mechanisms[name] for name in MECHANISMS if name in mechanisms}
    return total
