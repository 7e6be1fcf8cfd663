"""What a run of a scenario needs of this machine: its memory, checked by `revdem run`
before anything is generated (a scenario is valid on any machine; whether it runs here is
this module's question)."""

from __future__ import annotations

import os
from pathlib import Path

from revdem_cli.config.checks import FieldError
from revdem_cli.kernels.observables import Layout

BYTES_PER_FRAME = 128
"""Memory the engine takes to list the step of a frame (a Python int in a list and a set)."""

BYTES_PER_SPHERE = 2048
"""Memory a sphere takes in a run, bytes, with room to spare: 0.94 kB measured at a million
spheres with shear history (benchmarks/fcc_hertz.py: its arrays, its share of the pair list
and the scenario's copy of its starting state), twice that for a pair list that grows by
a quarter as a packing densifies and for the checks of a new scenario."""

TAPE_BYTES_PER_SPHERE = 6400
"""Memory the information tape adds a sphere (`[reversal] tape = true`), bytes: 6.3 kB
measured with shear history (benchmarks/tape_cost.py, n = 6: the copy of what a step
changes for the shadow reversal, the state before the step, and a block of entries with
room for two steps in which every compared value changed)."""

PREDICTOR_BYTES_PER_ORDER = 48
"""Memory the velocity predictor adds a sphere for each order, bytes: a half-step velocity
and angular velocity kept, and with the first the predicted ones."""

BYTES_PER_SPHERE_AND_WALL = 160
"""Memory of the contact history of a sphere with a wall, bytes (5 vectors and 4 scalars)."""


CGROUP_LIMIT = Path("/sys/fs/cgroup/memory.max")
"""The memory limit of this process's control group (cgroup v2), bytes, or `max`."""


def memory_bytes() -> int:
    """Physical memory of this machine, or the memory limit of its control group if that is
    lower, bytes."""
    memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    try:
        limit = CGROUP_LIMIT.read_text().strip()
    except OSError:
        return memory
    return min(memory, int(limit)) if limit.isdigit() else memory


def _size(nbytes: float, digits: int = 3) -> str:
    """A byte count for people: 3.2 GB, 512 MB, 64 kB."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.{digits}g} {unit}"
    return f"{nbytes:.0f} bytes"


def _sizes(needed: float, available: float) -> tuple[str, str]:
    """Two byte counts with the digits it takes to tell them apart (not 25.3 GB > 25.3 GB)."""
    for digits in range(3, 10):
        shown = _size(needed, digits), _size(available, digits)
        if shown[0] != shown[1]:
            return shown
    return shown


def check_host(scenario) -> None:
    """Refuse a scenario whose run would not fit in this machine's memory: its spheres, the
    list of its frames, the observables buffered between two frames."""
    check_memory(scenario)
    check_frames(scenario)


def check_memory(scenario) -> None:
    """Refuse, before generating anything, more spheres than this machine's memory holds."""
    per_sphere = BYTES_PER_SPHERE + BYTES_PER_SPHERE_AND_WALL * len(scenario.walls)
    if scenario.reversal.tape:
        per_sphere += TAPE_BYTES_PER_SPHERE
    if scenario.integrator.predictor_order:
        per_sphere += PREDICTOR_BYTES_PER_ORDER * (scenario.integrator.predictor_order + 1)
    memory = memory_bytes()
    count = len(scenario.particles)
    generated = [(f"packings[{k}].count", p) for k, p in enumerate(scenario.packings)]
    generated += [(f"lattices[{k}].cells", g) for k, g in enumerate(scenario.lattices)]
    generated += [(f"particles_from[{k}].count", g) for k, g in enumerate(scenario.particles_from)]
    for field, source in generated:
        count += source.count
        if count * per_sphere > memory:
            needed, available = _sizes(count * per_sphere, memory)
            raise FieldError(
                field,
                f"{count} spheres would need about {needed} of memory "
                f"({per_sphere} bytes each), more than the {available} of this machine",
            )


def check_frames(scenario) -> None:
    """The steps of a stage's frames are listed, and the observables recorded between two
    frames buffered, in memory."""
    for i, stage in enumerate(scenario.stages):
        frames = stage.steps // stage.output_every + 2
        if frames * BYTES_PER_FRAME > memory_bytes() // 2:
            raise FieldError(
                f"stages[{i}].output_every",
                f"{stage.steps} steps with a frame every {stage.output_every} make {frames} "
                f"frames, whose list alone needs {_size(frames * BYTES_PER_FRAME)} of memory, "
                f"more than half of the {_size(memory_bytes())} here; write frames less often",
            )
        rows = stage.output_every // stage.observable_interval + 2
        walls = tuple(wall.name for wall in scenario.walls)
        layout = Layout(
            walls,
            scenario.cell is not None,
            scenario.solid_fraction is not None,
            scenario.reversal.tape,
        )
        needed = rows * 8 * (layout.width + 1)  # and its step
        if needed > memory_bytes() // 2:
            field = "observables_every" if stage.observables_every else "output_every"
            raise FieldError(
                f"stages[{i}].{field}",
                f"{rows} rows of observables between two frames (output_every / "
                f"observables_every) need {_size(needed)} of memory, more than half of the "
                f"{_size(memory_bytes())} here; record observables less often or write "
                "frames more often",
            )
