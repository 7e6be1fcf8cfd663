"""Restarts and checkpoints carry a SHA-256 digest of every dataset and of their attributes
(`io.restart`), checked on reading: one flipped bit anywhere in the state is exit 2 naming
the dataset. What the kernels index memory with is range-checked too, for a restart edited
with its digests recomputed."""

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.io.restart import digest, read_restart, seal, write_restart
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()


@pytest.fixture(scope="module")
def restart(tmp_path_factory) -> Path:
    """The shear collision, 2 000 steps (a pair with shear history), forward only."""
    out = tmp_path_factory.mktemp("shear")
    args = ["run", CONFIGS / "collision_shear.toml", "--out", out, "-q", "--no-reverse"]
    result = runner.invoke(app, [str(a) for a in [*args, "--set", "stages.0.steps=2000"]])
    assert result.exit_code == 0, result.output
    return out / "collision_shear.restart.h5"


@pytest.fixture(scope="module")
def checkpoint(restart, tmp_path_factory) -> Path:
    """A checkpoint of the same state, part-way through the reversal."""
    from revdem_cli.io.restart import Resumption
    from revdem_cli.state import empty_events

    path = tmp_path_factory.mktemp("checkpoint") / "collision_shear.checkpoint.h5"
    state = read_restart(restart)
    state.resumption = Resumption("reverse", -1, empty_events(), 3, 3, False, str(restart), 0, 2000)
    write_restart(path, state)
    return path


def datasets(path: Path) -> list[str]:
    names = []
    with h5py.File(path) as f:
        f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
    return [n for n in names if h5py.File(path)[n].size > 0]


def flipped(source: Path, folder: Path, name: str) -> Path:
    """A copy of `source` with one bit of dataset `name` flipped where it lies in the file
    (the high bit of the middle value's last byte: an exponent bit of a little-endian
    float), or through HDF5 where the dataset is stored inside its header."""
    path = folder / source.name
    shutil.copy(source, path)
    with h5py.File(path, "r") as f:
        dataset = f[name]
        offset, size = dataset.id.get_offset(), dataset.dtype.itemsize
        middle = dataset.size // 2
    if offset is not None:
        with open(path, "r+b") as raw:
            raw.seek(offset + middle * size + size - 1)
            byte = raw.read(1)[0]
            raw.seek(-1, 1)
            raw.write(bytes([byte ^ 0x40]))
    else:
        with h5py.File(path, "r+") as f:
            values = f[name][()]
            flat = values.reshape(-1).view(np.uint8)
            flat[middle * size + size - 1] ^= 0x40
            f[name][...] = values
    return path


def reverse(path: Path, out: Path):
    return runner.invoke(app, ["reverse", str(path), "--out", str(out), "-q"])


def test_every_dataset_of_a_restart_is_checked(restart, tmp_path):
    names = datasets(restart)
    assert {"particles/x", "particles/v", "pairs/i", "pairs/history", "particles/material"} <= set(
        names
    )
    for name in names:
        folder = tmp_path / name.replace("/", "_")
        folder.mkdir()
        damaged = flipped(restart, folder, name)
        result = reverse(damaged, folder / "out")
        assert_one_line_error(result, f"damaged revdem restart ({name} fails its checksum)")
        assert not (folder / "out").exists()
        result = runner.invoke(app, ["info", str(damaged)])  # read as `reverse` reads it
        assert_one_line_error(result, f"damaged revdem restart ({name} fails its checksum)")


def test_every_dataset_of_a_checkpoint_is_checked(checkpoint, tmp_path):
    from revdem_cli.errors import InputError

    names = datasets(checkpoint)
    assert "revdem/checkpoint/events" in names
    for name in names:
        folder = tmp_path / name.replace("/", "_")
        folder.mkdir()
        with pytest.raises(InputError, match=f"{name} fails its checksum"):
            read_restart(flipped(checkpoint, folder, name), checkpoint=True)


@pytest.mark.parametrize(
    ("attribute", "value"),
    [("step", -1), ("stage_first_time", 1.0), ("stage_dt", 2e-7), ("trajectory", "/elsewhere")],
)
def test_an_attribute_changed_is_caught(restart, tmp_path, attribute, value):
    path = tmp_path / restart.name
    shutil.copy(restart, path)
    with h5py.File(path, "r+") as f:
        f["revdem"].attrs[attribute] = value
    result = reverse(path, tmp_path / "out")
    assert_one_line_error(result, "the attributes of /revdem fail their checksum")


def resealed(restart: Path, folder: Path, name: str, change) -> Path:
    """A copy of the restart with dataset `name` changed by change(array) and its digest
    recomputed: damage that no checksum sees."""
    path = folder / restart.name
    shutil.copy(restart, path)
    with h5py.File(path, "r+") as f:
        values = f[name][()]
        change(values)
        f[name][...] = values
        f[name].attrs["sha256"] = digest(values)
    return path


@pytest.mark.parametrize(
    ("name", "change", "message"),
    [
        ("pairs/j", lambda a: a.__setitem__(0, 7), "pair 0 is (0, 7), not i < j < 2"),
        ("pairs/i", lambda a: a.__setitem__(0, 1), "pair 0 is (1, 1), not i < j < 2"),
        ("particles/material", lambda a: a.__setitem__(1, 5), "particles/material 5 of entry 1"),
        ("particles/x", lambda a: a.__setitem__((1, 0), np.nan), "particles/x of particle 1"),
        ("particles/mass", lambda a: a.__setitem__(0, -1.0), "particles/mass of particle 0"),
    ],
)
def test_what_the_kernels_index_with_is_checked_in_range(restart, tmp_path, name, change, message):
    result = reverse(resealed(restart, tmp_path, name, change), tmp_path / "out")
    assert_one_line_error(result, "damaged revdem restart", message)


def test_a_step_before_its_stage_is_refused(restart, tmp_path):
    path = tmp_path / restart.name
    shutil.copy(restart, path)
    with h5py.File(path, "r+") as f:
        f["revdem"].attrs["step"] = -3
        seal(f["revdem"])
    result = reverse(path, tmp_path / "out")
    assert_one_line_error(result, "revdem/step -3 is not at or after its stage's first step 0")
