"""LAMMPS packings in and out: a data file that LAMMPS itself wrote (the fcc Hertz benchmark,
tests/data/lammps/fcc_hertz_write_data.in) runs here forward and reversed, each atom under its
id moving as it moved in LAMMPS, in either order in memory; a trajectory's last frame exported
as a data file reads back bit for bit, and its atoms keep their ids out to LAMMPS."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.config import load_scenario
from revdem_cli.io.h5md import frame_steps, open_trajectory
from revdem_cli.io.lammps_data import read_header, read_lammps_data
from tests.conftest import assert_one_line_error

DATA = Path(__file__).parents[1] / "data" / "lammps"
STEPS = 100  # what LAMMPS ran between its two write_data

SCENARIO = """
name = "fcc_from_lammps"
[materials.sphere]
density = 1000.0
shear_modulus = 2.0e6
poisson_ratio = 0.2
[contact]
model = "hertz"
[[particles_from]]
lammps_data = "{data}"
materials = {{ 1 = "sphere" }}
periodic = true
[cell]
size = [{edge!r}, {edge!r}, {edge!r}]
[integrator]
dt = 1.0e-6
[neighbours]
skin = 5.0e-4
[[stages]]
name = "run"
steps = {steps}
output_every = {steps}
reverse = true
"""


def _scenario(tmp_path: Path, data: Path, **changes) -> Path:
    edge = float(read_header(DATA / "fcc_step0.data")[2][0])  # every file here has its box
    fields = {"data": data, "edge": edge, "steps": STEPS, **changes}
    path = tmp_path / "from_lammps.toml"
    path.write_text(SCENARIO.format(**fields))
    return path


def _last_frame(trajectory: Path) -> dict[str, np.ndarray]:
    """The last frame's positions, velocities and spins, and the spheres' ids."""
    with open_trajectory(trajectory) as f:
        names = ("position", "velocity", "angular_velocity")
        frame = {name: f[f"particles/all/{name}/value"][-1] for name in names}
        return frame | {"id": f["particles/all/id"][:]}


def _rows_of(ids: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Where each id of `wanted` is in `ids` (every id there once)."""
    order = np.argsort(ids)
    rows = order[np.searchsorted(ids, wanted, sorter=order)]
    assert np.array_equal(ids[rows], wanted)
    return rows


@pytest.fixture(scope="module")
def lammps_run(tmp_path_factory) -> Path:
    """The packing LAMMPS wrote at step 0, run here 100 steps forward and reversed."""
    out = tmp_path_factory.mktemp("lammps")
    scenario = _scenario(out, DATA / "fcc_step0.data")
    result = CliRunner().invoke(app, ["run", str(scenario), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    return out


def test_a_lammps_packing_moves_here_as_it_moved_in_lammps(lammps_run):
    """LAMMPS' Hertz (hertz/material, the same E, ν, ρ) and revdem's are the same law
    (Hanley 2020 Eq 6), both velocity Verlet: after 100 steps every sphere is where LAMMPS
    put the atom of its id, to a few units in the last place of a coordinate (1e-15 of the
    box, 4e-17 m; measured 3.5e-18 m, of the 1e-6 m they moved), and at its velocity to 1e-9
    of it. The spheres are numbered in space (the default order), not in the ids' order."""
    start = read_lammps_data(DATA / "fcc_step0.data")
    lammps = read_lammps_data(DATA / "fcc_step100.data")
    here = _last_frame(lammps_run / "fcc_from_lammps.forward.h5")
    moved = np.abs(lammps.unwrapped - start.unwrapped).max()
    assert 1e-7 < moved < 1e-5  # the spheres moved: the comparison can fail
    assert np.abs(lammps.image).max() == 1  # some crossed the box: unwrapped as revdem has them
    assert sorted(here["id"]) == list(lammps.id) and np.any(np.diff(here["id"]) < 0)
    _assert_where_lammps_put(here, _rows_of(lammps.id, here["id"]))
    assert np.abs(here["angular_velocity"]).max() == 0.0  # frictionless: no spin in either


def _assert_where_lammps_put(here: dict[str, np.ndarray], atom: np.ndarray) -> None:
    """Each sphere of the last frame `here` (the atom `atom[k]` of the data file for sphere
    k) where LAMMPS put that atom after STEPS steps, to a few units in the last place of a
    coordinate, and at its velocity to 1e-9 of the largest."""
    lammps = read_lammps_data(DATA / "fcc_step100.data")
    assert np.abs(here["position"] - lammps.unwrapped[atom]).max() < 1e-15 * lammps.upper[0]
    speed = np.abs(lammps.velocity).max()
    assert np.abs(here["velocity"] - lammps.velocity[atom]).max() < 1e-9 * speed


def test_a_lammps_packing_reverses_to_its_start(lammps_run, tmp_path):
    """Frictionless, undamped: the reversed run retraces the forward one (compare.json). Its
    spheres keep their ids through the restart: in the reversed trajectory, and in a
    reversal of that restart run again by `revdem reverse`."""
    verdict = json.loads((lammps_run / "fcc_from_lammps.compare.json").read_text())
    assert verdict["reversible"] is True
    assert verdict["max_position_error_rel"] < 1e-9
    restart = lammps_run / "fcc_from_lammps.restart.h5"
    result = CliRunner().invoke(app, ["reverse", str(restart), "--out", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    ids = _last_frame(lammps_run / "fcc_from_lammps.forward.h5")["id"]
    assert np.any(np.diff(ids) < 0)  # numbered in space: ids that are not 1 to N
    for trajectory in (lammps_run, tmp_path):
        assert np.array_equal(_last_frame(trajectory / "fcc_from_lammps.reverse.h5")["id"], ids)


def test_a_lammps_packing_in_the_order_of_its_ids_moves_as_each_atom_moved_in_lammps(tmp_path):
    """order = "ids" keeps the atoms in the order of their ids; the default numbers them cell
    by cell, the first axis slowest in this cubic box: the same spheres, each with its atom's
    id, position and velocity. In the ids' order too, after 100 steps each is where LAMMPS
    put its atom."""
    scenario = _scenario(tmp_path, DATA / "fcc_step0.data")
    spheres = load_scenario(scenario)[0].spheres
    text = scenario.read_text().replace("periodic = true", 'periodic = true\norder = "ids"')
    scenario.write_text(text)
    by_id = load_scenario(scenario)[0].spheres
    assert np.array_equal(by_id.id, read_lammps_data(DATA / "fcc_step0.data").id)
    atom = _rows_of(by_id.id, spheres.id)  # the atom each sphere came from
    assert sorted(atom) == list(range(len(atom))) and not np.array_equal(atom, np.sort(atom))
    planes = np.floor(spheres.position[:, 0] / (2.0 * spheres.radius.max()))
    assert np.all(np.diff(planes) >= 0)
    assert np.array_equal(spheres.position, by_id.position[atom])
    assert np.array_equal(spheres.velocity, by_id.velocity[atom])
    result = CliRunner().invoke(app, ["run", str(scenario), "--out", str(tmp_path), "-q",
                                      "--no-reverse"])  # fmt: skip
    assert result.exit_code == 0, result.output
    here = _last_frame(tmp_path / "fcc_from_lammps.forward.h5")
    assert np.array_equal(here["id"], by_id.id)
    _assert_where_lammps_put(here, np.arange(len(atom)))


def test_a_frame_exported_as_a_data_file_reads_back_bit_for_bit(lammps_run, tmp_path):
    """export --format lammps-data writes 17 digits and the ids: the scenario that reads it
    starts each sphere from the last frame's position, velocity, angular velocity and radius
    of its id, to the bit."""
    trajectory = lammps_run / "fcc_from_lammps.forward.h5"
    exported = tmp_path / "last.data"
    result = CliRunner().invoke(
        app, ["export", str(trajectory), "--format", "lammps-data", "--out", str(exported)]
    )
    assert result.exit_code == 0, result.output
    frame = _last_frame(trajectory)
    read = load_scenario(_scenario(tmp_path, exported))[0].spheres
    spheres = read.taken(_rows_of(read.id, frame["id"]))
    edge = read_lammps_data(exported).upper
    inside = ((frame["position"] >= 0.0) & (frame["position"] < edge)).all(axis=1)
    assert 0 < inside.sum() < len(inside)  # some spheres left the box, to be wrapped back
    assert np.array_equal(spheres.position[inside], frame["position"][inside])
    shift = spheres.position[~inside] - frame["position"][~inside]  # whole box edges
    assert np.allclose(shift / edge, np.round(shift / edge), rtol=0.0, atol=1e-12)
    assert ((spheres.position >= 0.0) & (spheres.position < edge)).all()
    assert np.array_equal(spheres.velocity, frame["velocity"])
    assert np.array_equal(spheres.angular_velocity, frame["angular_velocity"])
    with open_trajectory(trajectory) as f:
        assert np.array_equal(spheres.radius, f["particles/all/radius"][:])


def test_a_data_file_of_any_frame_is_exported_with_step(lammps_run, tmp_path):
    """A data file was the last frame's alone; `--step N` takes the frame at step N (here
    the first, LAMMPS' own starting state), named in its header, and a step with no frame is
    refused naming those there are."""
    trajectory = lammps_run / "fcc_from_lammps.forward.h5"
    with open_trajectory(trajectory) as f:
        steps = frame_steps(f)
        velocity = f["particles/all/velocity/value"][0]
        ids = f["particles/all/id"][:]
    exported = tmp_path / "first.data"
    args = ["export", str(trajectory), "--format", "lammps-data", "--out", str(exported)]
    result = CliRunner().invoke(app, [*args, "--step", str(steps[0])])
    assert result.exit_code == 0, result.output
    assert f"at step {steps[0]}," in exported.read_text().splitlines()[0]
    data = read_lammps_data(exported)
    assert np.array_equal(data.velocity, velocity[np.argsort(ids)])  # the file by ids
    there = ", ".join(str(step) for step in steps)
    assert_one_line_error(
        CliRunner().invoke(app, [*args, "--step", str(steps[0] + 1), "--force"]),
        f"--step {steps[0] + 1}: fcc_from_lammps.forward.h5 has no frame there; its frames "
        f"are at steps {there}",
    )
    gsd = ["export", str(trajectory), "--format", "gsd", "--out", str(tmp_path / "t.gsd")]
    assert_one_line_error(CliRunner().invoke(app, [*gsd, "--step", "0"]), "--step picks")


def test_exported_atoms_keep_their_lammps_ids(lammps_run, tmp_path):
    """The packing numbered in space, exported: the dump's atoms and the data file's carry
    the ids LAMMPS gave them, and each atom of the data file is where LAMMPS put the atom of
    that id after the same 100 steps (unwrapped by its image flags, to 1e-15 of the box)."""
    trajectory = lammps_run / "fcc_from_lammps.forward.h5"
    frame = _last_frame(trajectory)
    dump, data = tmp_path / "last.dump", tmp_path / "last.data"
    for path, kind in ((dump, "lammps-dump"), (data, "lammps-data")):
        result = CliRunner().invoke(app, ["export", str(trajectory), "--format", kind,
                                          "--out", str(path)])  # fmt: skip
        assert result.exit_code == 0, result.output
    lines = dump.read_text().splitlines()
    atoms = lines[len(lines) - len(frame["id"]) :]
    assert [int(line.split()[0]) for line in atoms] == list(frame["id"])
    exported, lammps = read_lammps_data(data), read_lammps_data(DATA / "fcc_step100.data")
    assert np.array_equal(exported.id, lammps.id)
    assert np.abs(exported.unwrapped - lammps.unwrapped).max() < 1e-15 * lammps.upper[0]


def test_a_data_file_round_trip_keeps_every_number(tmp_path):
    """Ids, numbers with all 17 digits, spins and two materials survive the writer and
    reader."""
    from revdem_cli.io.lammps_data import lammps_data_text

    rng = np.random.default_rng(3)
    n = 7
    radius = rng.uniform(1e-3, 2e-3, n)
    density = np.where(np.arange(n) % 2, 2500.0, 1000.0)
    mass = density * 4.0 / 3.0 * math.pi * radius**3
    x, v, w = (scale * rng.normal(size=(n, 3)) for scale in (1e-2, 1e-1, 1e1))
    image = rng.integers(-2, 3, size=(n, 3))
    ids = 10 + 3 * np.arange(n)
    text = lammps_data_text(ids, radius, mass, x, image, v, w, 1 + np.arange(n) % 2,
                            x.min(0) - 1, x.max(0) + 1, 5, "test")  # fmt: skip
    path = tmp_path / "t.data"
    path.write_text(text)
    data = read_lammps_data(path)
    assert np.array_equal(data.id, ids)
    assert np.array_equal(data.position, x) and np.array_equal(data.image, image)
    assert np.array_equal(data.velocity, v)
    assert np.array_equal(data.angular_velocity, w) and np.array_equal(data.radius, radius)
    assert np.allclose(data.density, density, rtol=1e-15) and list(data.type) == [1, 2] * 3 + [1]


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (lambda t: t.replace("Atoms # sphere", "Atoms # atomic"), ["line 10", "atom_style atomic"]),
        (lambda t: t.replace("units = si", "units = lj"), ["line 1", "units lj"]),
        (lambda t: t.replace("108 atoms", "109 atoms"), ["bad.data: the header gives 109 atoms"]),
        (lambda t: t.replace("1 1 0.01 1000 0 0 0", "1 1 0.01 2000 0 0 0"), ["density 2000"]),
        (lambda t: t.replace("1 1 0.01 1000 0 0 0", "1 2 0.01 1000 0 0 0"), ["atom type 2"]),
        (lambda t: t.replace("1 1 0.01 1000 0 0 0", "1 1 -0.01 1000 0 0 0"), ["line 12"]),
        (lambda t: t.replace("1 1 0.01 1000 0 0 0", "0 1 0.01 1000 0 0 0"), ["line 12", "id 0"]),
        # every velocity was lost without a word: a section LAMMPS does not know was skipped
        (
            lambda t: t.replace("Velocities", "velocities"),
            ["line 121", "section 'velocities' (did you mean Velocities?)"],
        ),
        (lambda t: t + "\nBonds\n\n1 1 1 2\n", ["section 'Bonds'", "atom_style sphere"]),
        (  # atom 1's velocity line given as atom 5's again: atom 1 started at rest
            lambda t: t.replace("\n1 -0.004893302917480469 ", "\n5 -0.004893302917480469 "),
            ["line 124", "a second velocity of atom 5"],
        ),
        (
            lambda t: t.replace(
                "17 1 0.01 1000 0.0141279934881072 0.0141279934881072 0",
                "17 1 0.01 1000 0.0141279934881072 0.001 0",
            ),
            ["atom 17 of", "overlaps atom 2 of"],
        ),  # fmt: skip
    ],
)
def test_a_bad_data_file_is_one_line_naming_it(tmp_path, edit, fragments):
    data = tmp_path / "bad.data"
    data.write_text(edit((DATA / "fcc_step0.data").read_text()))
    scenario = _scenario(tmp_path, data)
    result = CliRunner().invoke(app, ["validate", str(scenario)])
    assert_one_line_error(result, "particles_from[0]", *fragments)


def test_a_loaded_packing_reads_back_with_the_overlaps_its_file_allows(tmp_path):
    """The fcc packing squeezed by 2 %, its contacts overlapping by 4.2 % of a radius, as a
    compressed packing's do (LAMMPS' read_data takes any): refused at the 1 % that catches
    two spheres placed at one point, naming how deep and the field that allows it; read with
    `max_overlap = 0.05`."""
    squeeze = 0.98
    lines = (DATA / "fcc_step0.data").read_text().splitlines()
    atoms = lines.index("Atoms # sphere") + 2
    for k, line in enumerate(lines):
        words = line.split()
        if line.endswith(("xlo xhi", "ylo yhi", "zlo zhi")):
            lines[k] = f"0 {float(words[1]) * squeeze!r} {' '.join(words[2:])}"
        elif atoms <= k < atoms + 108:
            words[4:7] = (repr(float(w) * squeeze) for w in words[4:7])
            lines[k] = " ".join(words)
    data = tmp_path / "squeezed.data"
    data.write_text("\n".join(lines) + "\n")
    edge = float(read_header(DATA / "fcc_step0.data")[2][0]) * squeeze
    scenario = _scenario(tmp_path, data, edge=edge)
    assert_one_line_error(
        CliRunner().invoke(app, ["validate", str(scenario)]),
        "particles_from[0]: atom ", "by 0.00021 m, 4.2 % of the smaller radius (at most 1 %; "
        "a loaded packing: particles_from[0].max_overlap)",
    )  # fmt: skip
    text = scenario.read_text().replace("periodic = true", "periodic = true\nmax_overlap = 0.05")
    scenario.write_text(text)
    result = CliRunner().invoke(app, ["validate", str(scenario)])
    assert result.exit_code == 0, result.output


def test_a_periodic_box_must_be_the_cell(tmp_path):
    scenario = _scenario(tmp_path, DATA / "fcc_step0.data")
    text = scenario.read_text().replace("size = [0.04", "size = [0.05", 1)
    scenario.write_text(text)
    result = CliRunner().invoke(app, ["validate", str(scenario)])
    assert_one_line_error(result, "cell.size", "periodic box")


def _open_box(tmp_path: Path, x: float, image) -> Path:
    """A scenario reading two spheres of 5 mm in the open box 0 to 40 mm of a data file,
    the second at (x, 10 mm, 10 mm) with the image flags `image`, without periodic = true."""
    from revdem_cli.io.lammps_data import lammps_data_text

    radius = np.array([0.005, 0.005])
    mass = 1000.0 * 4.0 / 3.0 * math.pi * radius**3
    position = np.array([[0.01, 0.01, 0.01], [x, 0.01, 0.01]])
    zeros, box = np.zeros((2, 3)), (np.zeros(3), np.full(3, 0.04))
    images = np.array([[0, 0, 0], image], dtype=np.int64)
    text = lammps_data_text([1, 2], radius, mass, position, images, zeros, zeros, [1, 1], *box,
                            0, "open box")  # fmt: skip
    data = tmp_path / "open.data"
    data.write_text(text)
    scenario = _scenario(tmp_path, data)
    text = scenario.read_text().replace("periodic = true\n", "")
    scenario.write_text(text[: text.index("[cell]")] + text[text.index("[integrator]") :])
    return scenario


@pytest.mark.parametrize("x", [0.02, 0.05], ids=["inside", "outside"])
def test_an_open_box_must_hold_its_atoms_as_lammps_read_data_demands(tmp_path, x):
    """periodic = false: no axis wraps, so an atom past the file's box is an error in the
    file, which LAMMPS' read_data refuses too; one inside is read."""
    result = CliRunner().invoke(app, ["validate", str(_open_box(tmp_path, x, [0, 0, 0]))])
    if x < 0.04:
        assert result.exit_code == 0, result.output
        return
    assert_one_line_error(
        result, "particles_from[0].lammps_data", "atom 2 of", "lies at [0.05, 0.01, 0.01]",
        "outside its box [0.0, 0.0, 0.0] to [0.04, 0.04, 0.04]",
    )  # fmt: skip


def test_an_open_box_refuses_image_flags(tmp_path):
    """periodic = false: an atom with an image flag was unwrapped by it to outside the box
    the file gives, which the check of that box, reading the wrapped position, let through
    (LAMMPS would have reset the flag to 0, moving the atom back)."""
    assert_one_line_error(
        CliRunner().invoke(app, ["validate", str(_open_box(tmp_path, 0.03, [1, 0, 0]))]),
        "particles_from[0].lammps_data", "atom 2 of", "has image flags [1, 0, 0], but "
        "periodic = false",
    )  # fmt: skip


def test_atom_types_written_as_yaml_numbers_name_their_materials(tmp_path):
    """YAML's `materials: {1: sphere}` gives the atom type as a number, as LAMMPS numbers
    types; it was refused ('[key]: Input should be a valid string')."""
    import yaml

    toml = tomllib.loads(_scenario(tmp_path, DATA / "fcc_step0.data").read_text())
    toml["particles_from"][0]["materials"] = {1: "sphere"}
    path = tmp_path / "from_lammps.yaml"
    path.write_text(yaml.safe_dump(toml))
    assert "1: sphere" in path.read_text()
    scenario, _ = load_scenario(path, [])
    assert scenario.particles_from[0].materials == {"1": "sphere"}
    assert scenario.sphere_count == read_header(DATA / "fcc_step0.data")[0]
