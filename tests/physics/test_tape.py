"""The information tape (`kernels.tape`, `io.tape`): runs whose reversal friction, damping,
contact loss, rolling resistance or a servo breaks (Hanley 2020 §4-5) reverse to their own
starting integers with it, and not without; a tape altered in one entry, or without the
entries of one mechanism, parts the reversal; the bits it recorded by mechanism."""

import json
import math
from pathlib import Path

import h5py
import numba
import numpy as np
import pytest

from revdem_cli import api as revdem
from revdem_cli.errors import InputError, RunFailed
from revdem_cli.io import tape as tape_file
from revdem_cli.io.tape import summary
from revdem_cli.kernels.information import ordered, unordered
from revdem_cli.kernels.tape import COMPARED, MECHANISMS
from revdem_cli.threads import Stepper
from tests.conftest import FLOOR, PLANE, SPHERE, crashed_after


def test_ordered_bits_count_the_doubles_between_two_values():
    rng = np.random.default_rng(5)
    values = np.concatenate(
        (
            rng.normal(size=200) * 10.0 ** rng.integers(-300, 300, 200),
            [0.0, -0.0, 5e-324, -5e-324, np.inf, -np.inf, 1.0, -1.0],
        )
    )
    numbers = np.array([ordered(b) for b in values.view(np.int64)])
    by_value = np.lexsort((~np.signbit(values), values))  # -0.0 before +0.0
    assert np.all(np.diff(numbers[by_value]) > 0)  # the order of the doubles
    assert all(unordered(n) == b for n, b in zip(numbers, values.view(np.int64), strict=True))
    assert ordered(np.float64(-0.0).view(np.int64)) == -1
    assert ordered(np.float64(0.0).view(np.int64)) == 0
    for x in (1.0, -3.5e-200, 7e300):
        after = np.nextafter(x, np.inf)
        step = ordered(np.float64(after).view(np.int64)) - ordered(np.float64(x).view(np.int64))
        assert step == 1


def _fixed(experiment: revdem.Experiment, tape: bool) -> revdem.Experiment:
    return experiment.changed({"integrator.arithmetic": "fixed", "reversal.tape": tape})


def _shear_collision(mu: float) -> revdem.Experiment:
    """Hanley 2020 Figure 5's collision: the shear force is lost at separation, and with a
    finite mu the contact slides first."""
    return revdem.load("configs/collision_shear.toml").changed(
        {"contact.friction": mu, "output.figures": []}
    )


def _resting(damping: dict) -> revdem.Experiment:
    """A sphere pressed 8 um into a plane by a linear spring of 1000 N/m, settling towards
    the 5.1 um of its weight under damping."""
    return revdem.from_dict(
        {
            "name": "resting",
            "materials": {"sphere": SPHERE, "plane": PLANE},
            "contact": {"model": "linear", "kn": 1e3, **damping.get("contact", {})},
            "damping": damping.get("damping", {}),
            "particles": [
                {"material": "sphere", "radius": 0.005, "position": [0, 0, 0.005 - 8e-6]}
            ],
            "walls": [FLOOR],
            "gravity": [0, 0, -9.81],
            "integrator": {"dt": 1e-6},
            "stages": [{"name": "settle", "steps": 3000, "output_every": 100, "reverse": True}],
        }
    )


def _servo() -> revdem.Experiment:
    """The fcc triaxial test with mu = 0.25 under the proportional servo, shortened."""
    return revdem.load("configs/fcc_triaxial.toml").changed(
        {
            "contact.tangential": "linear",
            "contact.ks": 1e11,
            "contact.friction": 0.25,
            "cell.servo": "proportional",
            "stages.0.steps": 1000,
            "stages.1.steps": 3000,
        }
    )


CASES = {
    "slip and contact loss": (
        lambda: _shear_collision(0.3),
        {"coulomb_slip", "contact_lost_with_shear_force"},
    ),
    "contact loss, no slip": (
        lambda: _shear_collision(math.inf),
        {"contact_lost_with_shear_force", "round_off"},
    ),
    "viscous damping": (lambda: _resting({"contact": {"normal_damping": 0.3}}), {"damping"}),
    "local damping": (lambda: _resting({"damping": {"local": 0.5}}), {"damping"}),
    "rolling limit": (lambda: revdem.load("configs/rolling_resistance.toml"), {"rolling_limit"}),
    "proportional servo": (_servo, {"cell_servo"}),
}


@pytest.mark.parametrize("case", CASES)
def test_the_tape_reverses_a_run_that_destroys_information_to_its_own_integers(tmp_path, case):
    make, mechanisms = CASES[case]
    try:  # without the tape the reversal parts from the forward run, or runs off its grids
        bare = revdem.run(_fixed(make(), tape=False), tmp_path / "bare").comparison
        assert not bare["bitwise_identical"]
    except RunFailed as failure:
        assert "left the range of its fixed-point grid" in str(failure)
    taped = revdem.run(_fixed(make(), tape=True), tmp_path / "taped")
    assert taped.comparison["bitwise_identical"], taped.comparison["first_divergence_step"]
    assert taped.comparison["max_velocity_error"] == 0.0
    recorded = summary(taped.outputs.restart.with_name(f"{make().name}.tape.h5"))
    assert mechanisms <= set(recorded["by_mechanism"]), recorded["by_mechanism"]
    assert recorded["bits_destroyed"] > 0.0
    _, bits = taped.observable("bits_destroyed")  # from the stage's start, by mechanism
    bits = bits[np.isfinite(bits).all(axis=1)]  # NaN before the stage with the tape
    assert bits[-1].sum() == pytest.approx(recorded["bits_destroyed"], rel=1e-12)
    assert np.all(np.diff(bits, axis=0) >= 0.0)  # summed as the run goes
    _assert_reversed_rows_are_the_forward_ones(tmp_path / "taped", make().name)


def _bits_rows(trajectory) -> tuple[np.ndarray, np.ndarray]:
    """The steps of a trajectory's observables rows and their bits_destroyed."""
    from revdem_cli.io.h5md import open_trajectory

    with open_trajectory(trajectory) as f:
        steps = f["observables/bits_destroyed/step"][:]
        return steps, f["observables/bits_destroyed/value"][: len(steps)]


def _assert_reversed_rows_are_the_forward_ones(out, name: str) -> dict[int, np.ndarray]:
    """Every reversed row of bits_destroyed in the folder `out` is the forward row of the
    state it holds (`compare.paired_rows`: at a stage's start, the stage's own row where it
    wrote one beside the end of the stage before), to the last digit (NaN where the forward
    row is, before the stage with the tape); the reversed rows by step (of two at a step,
    the end of the stage before)."""
    from revdem_cli.compare import paired_rows
    from revdem_cli.engine import output_paths

    paths = output_paths(out, name)
    (forward, bits), (back, reverse) = _bits_rows(paths["forward"]), _bits_rows(paths["reverse"])
    pairs = paired_rows(forward, back)
    assert len(back) and sorted(row for _, row in pairs) == list(range(len(back)))
    for row, reversed_row in pairs:
        same = np.array_equal(reverse[reversed_row].view(np.int64), bits[row].view(np.int64))
        assert same, back[reversed_row]
    return dict(zip(back.tolist(), reverse, strict=True))


def test_a_reversed_run_gives_back_the_bits_the_forward_run_recorded(tmp_path):
    """Going backward, bits_destroyed holds the bits the forward run recorded from the
    stage's start to each step, those the reversal has yet to give back: the forward row of
    the step, bit for bit, falling to zero at the stage's start."""
    taped = revdem.run(_fixed(_resting({"contact": {"normal_damping": 0.3}}), True), tmp_path)
    assert taped.comparison["bitwise_identical"]
    reverse = _assert_reversed_rows_are_the_forward_ones(tmp_path, "resting")
    assert len(reverse) == len(_bits_rows(taped.trajectory())[0])  # the whole stage back
    rows = np.array([reverse[step] for step in sorted(reverse)])
    assert np.isfinite(rows).all()
    assert rows[:, MECHANISMS.index("damping")].any()
    assert np.all(rows[0] == 0.0)  # the stage's start: nothing recorded yet


def _entries(path):
    with h5py.File(path) as f:
        return {name: f[f"entries/{name}"][:] for name in ("what", "where", "amount")} | {
            "count": f["steps/count"][:]
        }


def _rewrite(path, entries) -> None:
    """Write `entries` (what, where, amount, and the count of each step) over the tape's."""
    with h5py.File(path, "a") as f:
        for name in ("what", "where", "amount"):
            f[f"entries/{name}"].resize((len(entries[name]),))
            f[f"entries/{name}"][:] = entries[name]
        f["steps/count"][:] = entries["count"]
        block = tuple(f[name][:] for name in tape_file.BLOCK_DATASETS)  # checksummed anew
        steps, total = len(entries["count"]), len(entries["what"])
        f["blocks"].resize(1, axis=0)
        f["blocks"][0] = (0, steps, 0, total, *tape_file._checksums(block))


def _labels(entries) -> np.ndarray:
    """The step (from the stage's first) each entry restores."""
    return np.repeat(np.arange(len(entries["count"])), entries["count"])


def _frame_errors(result) -> dict[int, float]:
    frames = result.comparison["frames"]
    return dict(zip(frames["step"], frames["velocity_error"], strict=True))


def test_histories_on_their_grids_need_the_tape_in_few_contact_steps(tmp_path):
    """With mu = inf the shear collision destroys its shear force at separation only; on
    their grids its histories come back from the reversed remap and turn in almost every
    step, and the tape records round-off at fewer than 1 % of its 15 000 steps (in doubles,
    the history missed its value at most of them). Counted on the contact's grid, such an
    entry is a step or two off in each component: a few bits, not the 12 or more of the
    doubles between two steps of the grid."""
    taped = revdem.run(_fixed(_shear_collision(math.inf), tape=True), tmp_path)
    assert taped.comparison["bitwise_identical"]
    recorded = summary(taped.outputs.restart.with_name("collision_shear.tape.h5"))
    assert recorded["by_mechanism"]["contact_lost_with_shear_force"]["with_entries"] == 1
    round_off = recorded["by_mechanism"]["round_off"]
    assert round_off["with_entries"] < 150, recorded["by_mechanism"]
    assert round_off["bits"] / round_off["with_entries"] < 3 * math.log2(5), round_off


def test_the_proportional_servo_costs_its_rate_alone(tmp_path):
    """A reversed step moves the cell back with the rate the forward step moved with, so the
    tape records only the rate of the step before (one entry a step, charged to the servo).
    It once recomputed the rate from the later stress and moved otherwise: positions and
    then histories parted, 341 400 history entries in a 6 000-step shear (7.4 % of its
    contact-steps, charged to round-off), where the cell's edges were not on their grid."""
    taped = revdem.run(_fixed(_servo(), tape=True), tmp_path)
    assert taped.comparison["bitwise_identical"]
    recorded = summary(taped.outputs.restart.with_name("fcc_triaxial.tape.h5"))
    by = recorded["by_mechanism"]
    steps = _servo().scenario.stages[-1].steps
    assert by["cell_servo"]["with_entries"] <= steps, by
    contact_steps = 768 * steps  # the fcc lattice's 128 spheres, 6 contacts each
    assert by.get("round_off", {"with_entries": 0})["with_entries"] < 1e-4 * contact_steps, by


def test_drag_costs_the_bits_it_destroys(tmp_path):
    """Drag maps the velocity integers n to n gamma_d (Hanley 2020 Eq 25): 1 / gamma_d of
    them onto one, -log2 gamma_d bits a value a step, so the tape's entries fall at a
    fraction 1 - gamma_d of a moving component's steps. Rounding n gamma_d itself near
    n ~ 2^51, where a double holds only halves, merged about one velocity in eight: a free
    glide recorded hundreds of times the bits drag destroys."""
    gamma, steps = 0.999, 2000
    glide = revdem.from_dict(
        {
            "name": "glide",
            "materials": {"sphere": SPHERE},
            "contact": {"model": "linear", "kn": 1e3},
            "damping": {"drag": gamma},
            "particles": [
                {
                    "material": "sphere",
                    "radius": 0.005,
                    "position": [0, 0, 0],
                    "velocity": [1.0, -2.0, 0.5],
                }
            ],  # fmt: skip
            "integrator": {"dt": 1e-6},
            "stages": [{"name": "glide", "steps": steps, "output_every": 100, "reverse": True}],
        }
    )
    taped = revdem.run(_fixed(glide, tape=True), tmp_path)
    assert taped.comparison["bitwise_identical"]
    recorded = summary(taped.outputs.restart.with_name("glide.tape.h5"))
    assert set(recorded["by_mechanism"]) == {"drag"}, recorded["by_mechanism"]
    drag = recorded["by_mechanism"]["drag"]
    merged = 3 * steps * (1.0 - gamma)  # entries expected: 6, each log2 3 bits
    assert 0 < drag["with_entries"] <= 3 * merged, drag
    assert drag["bits"] <= 3 * merged * math.log2(3), drag


def test_an_altered_entry_parts_the_reversal_where_it_stands(tmp_path):
    taped = revdem.run(_fixed(_shear_collision(0.3), tape=True), tmp_path / "taped")
    restart = taped.outputs.restart
    path = restart.with_name("collision_shear.tape.h5")
    entries = _entries(path)
    labels = _labels(entries)
    shear = np.flatnonzero(entries["what"] == COMPARED.index("shear_history"))
    altered = shear[len(shear) // 2]  # a slipping contact's history, part-way through
    entries["amount"][altered] += 1 << 40  # 2^40 doubles: about a part in 4000 of it
    _rewrite(path, entries)
    parted = revdem.reverse(restart, tmp_path / "parted")
    errors = _frame_errors(parted)
    step = int(labels[altered])
    assert all(error == 0.0 for frame, error in errors.items() if frame > step)
    first_below = max(frame for frame in errors if frame <= step)
    assert errors[first_below] > 0.0
    assert not parted.comparison["bitwise_identical"]


def _flip_bytes(path: Path, dataset: str, chunk: int = 0) -> None:
    """XOR bytes in the middle of a compressed chunk of `dataset`, HDF5's headers left whole."""
    with h5py.File(path) as f:
        info = f[dataset].id.get_chunk_info(chunk)
    with open(path, "r+b") as file:
        file.seek(info.byte_offset + info.size // 2)
        data = bytearray(file.read(4))
        file.seek(info.byte_offset + info.size // 2)
        file.write(bytes(b ^ 0x5A for b in data))


@pytest.mark.parametrize("dataset", ["entries/amount", "steps/bits"])
def test_a_damaged_tape_is_refused_by_info_and_the_reversal(tmp_path, dataset):
    """Zstandard and HDF5 check nothing: bytes changed inside a compressed chunk read back
    as other entries (a reversal then ran to a wrong verdict, `revdem info` unchanged) or
    other bits (info said 4.3e-318). The blocks' checksums refuse it, naming the block."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import assert_one_line_error

    experiment = _fixed(_shear_collision(0.3), tape=True).changed({"stages.0.reverse": False})
    restart = revdem.run(experiment, tmp_path / "run").outputs.restart
    path = restart.with_name("collision_shear.tape.h5")
    _flip_bytes(path, dataset)
    damaged = f"{path}: damaged tape"
    with pytest.raises(InputError, match=damaged):
        revdem.reverse(restart, tmp_path / "reversed")
    assert_one_line_error(CliRunner().invoke(app, ["info", str(path)]), damaged)


def test_a_reversal_reads_its_tape_to_check_it_and_to_replay_it_alone(tmp_path, monkeypatch):
    """A reversal read its whole tape three times: to check every block before its first
    step, to replay it, and again for the verdict's summary, which checked every block
    again. The summary is that of the check's read now (the same as `summary` reads), and a
    flipped byte is refused before the first step all the same
    (`test_a_damaged_tape_is_refused_by_info_and_the_reversal`)."""
    experiment = _fixed(_shear_collision(0.3), tape=True).changed({"stages.0.reverse": False})
    restart = revdem.run(experiment, tmp_path / "run").outputs.restart
    path = restart.with_name("collision_shear.tape.h5")
    with h5py.File(path) as f:
        sizes = {name: f[name].size for name in tape_file.BLOCK_DATASETS}
    reads = _tape_reads(monkeypatch)
    reversed_ = revdem.reverse(restart, tmp_path / "reversed")
    assert reversed_.comparison["bitwise_identical"]
    for name in ("entries/what", "entries/where", "entries/amount"):
        assert reads[name] == 2 * sizes[name], name
    for name in ("steps/count", "steps/contacts"):  # the replay's bits read apart, by row
        assert reads[name] == sizes[name], name
    assert reversed_.comparison["information_tape"] == summary(path)


@pytest.mark.parametrize(
    ("changes", "why"),
    [
        ({"contact.friction": 0.3}, "at step 15000 it ends with other integers than the restart"),
        ({"stages.0.steps": 16000}, "it ends at step 16000, the restart's stage at step 15000"),
    ],
    ids=["another run", "a longer run"],
)
def test_a_tape_of_another_run_is_refused_before_the_first_step(tmp_path, changes, why):
    """A tape copied beside a restart it was not recorded with, of another scenario or of a
    longer run of the same stage, once reversed it silently (stage, first step and spheres
    alike) to a wrong verdict: it ends at another step, or with other integers than the
    restart, and the reversal names both files and steps nowhere."""
    experiment = _fixed(_shear_collision(math.inf), tape=True).changed({"stages.0.reverse": False})
    own = revdem.run(experiment, tmp_path / "own").outputs.restart
    other = revdem.run(experiment.changed(changes), tmp_path / "other").outputs.restart
    tape = own.with_name("collision_shear.tape.h5")
    tape.write_bytes(other.with_name(tape.name).read_bytes())
    with pytest.raises(InputError, match=f"{tape}: not the information tape of {own}: {why}"):
        revdem.reverse(own, tmp_path / "reversed")
    assert not (tmp_path / "reversed" / "collision_shear.reverse.h5").exists()


@pytest.mark.parametrize("tape", ["missing", "shorter"])
def test_a_tape_that_cannot_serve_is_refused_before_the_reversed_trajectory(tmp_path, tape):
    """A missing tape (its line once carried h5py's errno), or one shorter than the restart's
    stage (refused only when the reversal reached the steps it lacks, exit 1), is refused
    in one line before the reversed trajectory is made: no stub is left for --force."""
    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import assert_one_line_error

    experiment = _fixed(_shear_collision(0.3), tape=True).changed({"stages.0.reverse": False})
    restart = revdem.run(experiment, tmp_path / "run").outputs.restart
    path = restart.with_name("collision_shear.tape.h5")
    if tape == "missing":
        path.unlink()
        why = f"{path}: not there"
    else:
        with h5py.File(path, "a") as f:  # its whole blocks up to step 14 000
            ends = f["blocks"][:, 0] + f["blocks"][:, 1]
            f["blocks"].resize(int(np.searchsorted(ends, 14000, side="right")), axis=0)
            steps = int(f["blocks"][-1, 0] + f["blocks"][-1, 1])
            entries = int(f["blocks"][-1, 2] + f["blocks"][-1, 3])
            for name in tape_file.BLOCK_DATASETS:
                f[name].resize(steps if name.startswith("steps/") else entries, axis=0)
        why = f"holds steps 0 to {steps - 1}, the reversal needs steps 0 to 14999"
    out = tmp_path / "reversed"
    result = CliRunner().invoke(app, ["reverse", str(restart), "--out", str(out)])
    assert_one_line_error(result, why)
    assert not (out / "collision_shear.reverse.h5").exists()


@pytest.mark.parametrize(
    ("case", "array"),
    [
        ("slip and contact loss", "shear_history"),
        ("viscous damping", "force"),
        ("local damping", "force"),
        ("rolling limit", "wall_rolling_history"),
        ("proportional servo", "cell_rate"),
    ],
)
def test_a_mechanism_left_off_the_tape_breaks_the_reversal(tmp_path, case, array):
    make, _ = CASES[case]
    taped = revdem.run(_fixed(make(), tape=True), tmp_path / "taped")
    assert taped.comparison["bitwise_identical"]
    path = taped.outputs.restart.with_name(f"{make().name}.tape.h5")
    entries = _entries(path)
    kept = entries["what"] != COMPARED.index(array)
    assert not kept.all(), f"the tape holds no {array} entry"
    labels = _labels(entries)[kept]
    _rewrite(
        path,
        {name: entries[name][kept] for name in ("what", "where", "amount")}
        | {"count": np.bincount(labels, minlength=len(entries["count"]))},
    )
    try:
        without = revdem.reverse(taped.outputs.restart, tmp_path / "without")
    except RunFailed as failure:  # parted so far that a value ran off its grid
        assert "left the range of its fixed-point grid" in str(failure)
    else:
        assert not without.comparison["bitwise_identical"]


def _fcc_jostled(friction: float) -> revdem.Experiment:
    """108 Hertz-Mindlin spheres on a periodic fcc lattice, all but touching and jostled at
    random (the fcc Hertz benchmark at n = 3, 400 steps): a fixed cell, no damping, contacts
    made, slid and lost across periodic images."""
    spacing = 1.0001e-3 * 2**0.5
    return revdem.from_dict(
        {
            "name": "fcc_jostled",
            "materials": {"m": {"density": 1000.0, "shear_modulus": 2.0e6, "poisson_ratio": 0.2}},
            "contact": {"model": "hertz", "tangential": "mindlin", "friction": friction},
            "lattices": [
                {
                    "material": "m",
                    "radius": 5e-4,
                    "cells": [3, 3, 3],
                    "spacing": spacing,
                    "random_velocity": 0.05,
                    "seed": 3,
                }
            ],  # fmt: skip
            "cell": {"size": [3 * spacing] * 3},
            "integrator": {"dt": 1.0e-6},
            "neighbours": {"skin": 5.0e-4},
            "stages": [{"name": "run", "steps": 400, "output_every": 100, "reverse": True}],
        }
    )


@pytest.mark.parametrize(
    "make, threads",
    [(lambda: _shear_collision(0.3), 1), (lambda: _fcc_jostled(0.05), 1),
     (lambda: _fcc_jostled(0.05), 2)],
    ids=["collision", "fcc", "fcc on two threads"],
)  # fmt: skip
def test_the_predicted_tape_is_the_shadow_reversal_s_entry_for_entry(
    tmp_path, make, threads, monkeypatch, request
):
    """Where the reversal finds all but the pairs' histories again (no damping, drag, moving
    cell or wall contact with history), the forward step predicts the histories the reversal
    would find instead of taking a shadow reversal; the tape is the same to the last entry
    and bit, and reverses the run as exactly. On two threads the pair loop lists them in two
    chunks, which the tape reads one after the other."""
    if threads > 1:
        if numba.config.NUMBA_NUM_THREADS < threads:
            pytest.skip(f"needs NUMBA_NUM_THREADS >= {threads}")
        monkeypatch.setattr(Stepper, "_counts", staticmethod(lambda particles: (threads,)))
        request.getfixturevalue("every_loop_parallel")
    chosen = []
    predictable = tape_file.predictable

    def spied(*bundles):
        chosen.append(predictable(*bundles))
        return chosen[-1]

    monkeypatch.setattr(tape_file, "predictable", spied)
    predicted = revdem.run(_fixed(make(), tape=True), tmp_path / "predicted")
    assert chosen and all(chosen)
    monkeypatch.setattr(tape_file, "predictable", lambda *bundles: False)
    shadowed = revdem.run(_fixed(make(), tape=True), tmp_path / "shadowed")
    name = make().name
    tapes = [r.outputs.restart.with_name(f"{name}.tape.h5") for r in (predicted, shadowed)]
    entries = [_entries(path) for path in tapes]
    assert len(entries[0]["what"]) > 0
    for key in entries[0]:
        assert np.array_equal(entries[0][key], entries[1][key]), key
    bits = []
    for path in tapes:
        with h5py.File(path) as f:
            bits.append((f["steps/bits"][:], f["steps/contacts"][:]))
    assert np.array_equal(bits[0][0], bits[1][0]) and np.array_equal(bits[0][1], bits[1][1])
    assert predicted.comparison["bitwise_identical"] and shadowed.comparison["bitwise_identical"]


def test_a_tape_in_small_blocks_streams_to_disk_and_back(tmp_path, monkeypatch):
    """Blocks of 64 steps: the recording is written out 235 times and read back block by
    block from the end, and the reversal is still exact."""
    monkeypatch.setattr(tape_file, "STEPS_PER_BLOCK", 64)
    written, read = [], []  # the steps of each block appended; each load's last step and span
    append, load = tape_file._append_block, tape_file.Replayer.load

    def appended(path, block):
        written.append(block[3].shape[0])  # the block's counts: one a step
        append(path, block)

    def loaded(replayer, step):
        load(replayer, step)
        read.append((step, int(replayer.buffers.span[1])))

    monkeypatch.setattr(tape_file, "_append_block", appended)
    monkeypatch.setattr(tape_file.Replayer, "load", loaded)
    experiment = _fixed(_shear_collision(0.3), tape=True)
    taped = revdem.run(experiment, tmp_path)
    assert taped.comparison["bitwise_identical"]
    steps = experiment.scenario.stages[0].steps
    assert written == [64] * (steps // 64) + [steps % 64] and len(written) == 235
    assert [step for step, _ in read] == list(range(steps, 0, -64))  # from the end
    assert [span for _, span in read] == written  # 64 steps a load, the rest at the start


def test_a_step_with_more_entries_than_the_block_holds_is_recorded_again(tmp_path, monkeypatch):
    """A block with room for 2 entries: the first step that makes more overflows it, is
    left out of the block written, and is recorded again once the block has grown (to room
    for 64 steps of the most entries a step has made, not 1.5: the collision would then
    write a block every step); the tape is the one a block with room to spare records,
    entry for entry, and still exact."""
    experiment = _fixed(_shear_collision(0.3), tape=True).changed({"stages.0.output_every": 1000})
    roomy = revdem.run(experiment, tmp_path / "roomy")
    monkeypatch.setattr(tape_file, "MIN_ENTRIES", 2)
    monkeypatch.setattr(tape_file, "ENTRIES_PER_PARTICLE", 0)
    monkeypatch.setattr(tape_file, "ROOM_FOR_STEPS", 64)
    retaken = []
    flush = tape_file.Recorder.flush
    monkeypatch.setattr(
        tape_file.Recorder,
        "flush",
        lambda r, **wait: flush(r, **wait) or retaken.append(r.retaking),
    )
    cramped = revdem.run(experiment, tmp_path / "cramped")
    assert cramped.comparison["bitwise_identical"]
    assert any(retaken)  # a step was recorded again
    name = "collision_shear.tape.h5"
    one, other = (
        _entries(roomy.outputs.restart.with_name(name)),
        _entries(cramped.outputs.restart.with_name(name)),
    )
    assert all(np.array_equal(one[key], other[key]) for key in one)


def test_the_tape_needs_fixed_point_arithmetic_and_velocity_verlet():
    with pytest.raises(InputError, match="reversal.tape: needs integrator.arithmetic = 'fixed'"):
        _shear_collision(0.3).changed({"reversal.tape": True})
    with pytest.raises(InputError, match="output.figures: 'information' needs reversal.tape"):
        _shear_collision(0.3).changed({"output.figures": ["information"]})
    with pytest.raises(InputError, match="reversal.tape: needs integrator.scheme = 'verlet'"):
        _fixed(_resting({"contact": {"normal_damping": 0.3}}), True).changed(
            {"integrator.scheme": "trvp"}
        )
    both = "reversal.tape: needs integrator.arithmetic = 'fixed' and integrator.scheme = 'verlet'"
    with pytest.raises(InputError, match=both):  # at once, not one refusal after the other
        _shear_collision(0.3).changed({"reversal.tape": True, "integrator.scheme": "trvp"})


@pytest.mark.parametrize("frames", [6, 40], ids=["forward", "reversed"])
def test_a_taped_run_resumed_from_a_checkpoint_is_the_uninterrupted_run(
    tmp_path, frames, monkeypatch
):
    """The tape is cut back to the checkpoint's step and recorded on, or replayed on from
    there: a run stopped part-way through either phase resumes to the same tape and the
    same exact reversal and verdict, the tape's size in it too (blocks of 256 steps, so
    that the cut falls after blocks already written)."""
    from revdem_cli.engine import output_paths

    monkeypatch.setattr("revdem_cli.io.tape.STEPS_PER_BLOCK", 256)

    experiment = _fixed(_resting({"contact": {"normal_damping": 0.3}}), True).changed(
        {"output.checkpoint_interval": 0.0}
    )
    whole = revdem.run(experiment, tmp_path / "whole")
    shown = crashed_after(experiment, tmp_path / "cut", frames)
    assert ("reversed" in shown[-1]) == (frames == 40)
    resumed = revdem.resume(tmp_path / "cut")
    assert resumed.comparison["bitwise_identical"]
    a = _entries(output_paths(tmp_path / "whole", "resting")["tape"])
    b = _entries(output_paths(tmp_path / "cut", "resting")["tape"])
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    assert whole.comparison["bitwise_identical"]
    assert resumed.comparison == whole.comparison  # the tape's size among it
    _assert_reversed_rows_are_the_forward_ones(tmp_path / "cut", "resting")


def _blocks(count: int, steps: int) -> list[tuple]:
    """`count` blocks of `steps` steps of random entries, as `Recorder` hands the writer."""
    rng = np.random.default_rng(7)
    blocks = []
    for _ in range(count):
        counts = rng.integers(0, 40, steps)
        entries = int(counts.sum())
        blocks.append(
            (
                rng.integers(0, len(COMPARED), entries).astype(np.int8),
                rng.integers(0, 10**6, entries),
                rng.integers(-(10**9), 10**9, entries),
                counts,
                rng.random((steps, len(MECHANISMS))),
                rng.integers(0, 5, (steps, len(MECHANISMS))).astype(np.int32),
            )
        )
    return blocks


def test_a_tape_cut_back_and_written_on_holds_the_bytes_of_one_written_straight(tmp_path):
    """A resumed run cuts its tape back to the checkpoint's step and writes on: the size the
    verdict gives (`summary`'s bytes) is that of the tape written straight through, though
    the file, whose cut chunks leave space behind, is larger."""
    from revdem_cli.state import initial_state

    state = initial_state(_resting({}).scenario)
    clock = (0, 0.0, 1e-6)
    blocks = _blocks(6, 3000)
    straight, cut = tmp_path / "straight.tape.h5", tmp_path / "cut.tape.h5"
    tape_file.Recorder(straight, "settle", clock, state)
    for block in blocks:
        tape_file._append_block(straight, block)
    tape_file.Recorder(cut, "settle", clock, state)
    for block in blocks[:4]:
        tape_file._append_block(cut, block)
    tape_file.Recorder(cut, "settle", clock, state, step=2 * 3000)
    for block in blocks[2:]:
        tape_file._append_block(cut, block)
    assert _entries(cut).keys() == _entries(straight).keys()
    for name, values in _entries(straight).items():
        assert np.array_equal(_entries(cut)[name], values), name
    assert cut.stat().st_size > straight.stat().st_size
    assert summary(cut) == summary(straight) | {"file": cut.name}


def _written_tape(path: Path, blocks: list[tuple]) -> Path:
    """A tape of the resting sphere's stage "settle" holding `blocks` (`_blocks`), ended at
    its last step."""
    from revdem_cli.state import initial_state

    tape_file.Recorder(path, "settle", (0, 0.0, 1e-6), initial_state(_resting({}).scenario))
    for block in blocks:
        tape_file._append_block(path, block)
    tape_file._mark_end(path, sum(len(block[3]) for block in blocks), "")
    return path


def _tape_reads(monkeypatch) -> dict[str, int]:
    """The values read from each dataset of the information tapes from here on, by name."""
    reads: dict[str, int] = {}
    read = h5py.Dataset.__getitem__

    def counted(dataset, key):
        values = read(dataset, key)
        if dataset.file.filename.endswith(".tape.h5"):
            name = dataset.name.lstrip("/")
            reads[name] = reads.get(name, 0) + np.size(values)
        return values

    monkeypatch.setattr(h5py.Dataset, "__getitem__", counted)
    return reads


def test_a_tape_s_bytes_count_every_dataset_it_stores(tmp_path):
    """`summary`'s bytes (compare.json's information_tape.bytes and its ratio, `revdem
    info`) counted the entries and the steps' rows, and left out /blocks, the table of the
    blocks' checksums the tape stores beside them."""
    path = _written_tape(tmp_path / "resting.tape.h5", _blocks(3, 3000))
    with h5py.File(path) as f:
        stored = {
            name: f[name].id.get_storage_size() for name in (*tape_file.BLOCK_DATASETS, "blocks")
        }
    assert stored["blocks"] > 0
    said = summary(path)
    assert said["bytes"] == sum(stored.values())
    assert said["size_over_full_state"] == said["bytes"] / said["full_state_bytes"]


def test_one_read_of_a_tape_checks_it_and_gives_its_summary_or_its_replay(tmp_path, monkeypatch):
    """`summary` read the steps' bits and contacts again once it had checked every block, and
    a `Replayer` the steps' counts and bits: each dataset is read once now, the check and
    what is taken from the tape from the same read, and the bits summed on from it are
    those of one sum over the whole stage, step by step, to the last digit."""
    blocks = _blocks(3, 3000)  # blocks that end off the replay's 4096-step boundaries
    path = _written_tape(tmp_path / "resting.tape.h5", blocks)
    with h5py.File(path) as f:
        sizes = {name: f[name].size for name in (*tape_file.BLOCK_DATASETS, "blocks")}
    reads = _tape_reads(monkeypatch)
    said = summary(path)
    assert reads == sizes
    reads.clear()
    replayer = tape_file.Replayer(path, "settle", (0, 9000), 1, "its restart")
    assert reads == sizes
    assert replayer.summary == said
    bits = np.vstack([block[4] for block in blocks])
    running = np.cumsum(np.vstack((np.zeros(len(MECHANISMS)), bits)), axis=0)
    steps = np.array([1, 2999, 3000, 3001, 4095, 4096, 4097, 6000, 8192, 8193, 8999, 9000])
    assert np.array_equal(replayer.destroyed_by(steps), running[steps])
    assert np.array_equal(replayer.recorded, running[-1])
    assert said["bits_destroyed"] == float(running[-1].sum())
    assert said["by_mechanism"]["damping"]["bits"] == running[-1, MECHANISMS.index("damping")]
    contacts = np.vstack([block[5] for block in blocks]).sum(axis=0)
    assert said["by_mechanism"]["damping"]["with_entries"] == contacts[MECHANISMS.index("damping")]


def test_observing_a_state_leaves_the_stress_a_servo_reads():
    """The observables take the cell's stress from the contact forces as they are; the
    servo's own stress, which the next step reads (and the tape restores), is left alone."""
    from revdem_cli.stage import Model
    from revdem_cli.state import initial_state

    scenario = _servo().scenario
    state = initial_state(scenario)
    state.cell.stress[:] = 7.0
    Model.of(scenario).observe(state, Model.of(scenario).dynamics)
    assert np.all(state.cell.stress == 7.0)


def _three_stages() -> revdem.Experiment:
    """A sphere pressed under local damping, let go undamped, then held by a viscous contact,
    every stage reversed."""
    return _fixed(_resting({}), True).changed(
        {
            "reversal.all_stages": True,
            "stages": [
                {"name": "press", "steps": 1000, "output_every": 100, "damping": {"local": 0.5}},
                {"name": "free", "steps": 1000, "output_every": 100},
                {
                    "name": "held",
                    "steps": 1000,
                    "output_every": 100,
                    "contact": {"normal_damping": 0.3},
                    "reverse": True,
                },
            ],
        }
    )


def test_every_stage_reverses_to_the_start_of_the_run(tmp_path):
    """[reversal] all_stages: the reversal goes back through all three stages, each with its
    own damping and tape, and ends at step 0 on the starting integers."""
    experiment = _three_stages()
    result = revdem.run(experiment, tmp_path)
    verdict = result.comparison
    assert verdict["bitwise_identical"]
    assert verdict["frames_compared"] == 31 and min(verdict["frames"]["step"]) == 0
    assert [tape["file"] for tape in verdict["information_tapes"]] == [
        "resting.tape.h5", "resting.stage-1.tape.h5", "resting.stage-0.tape.h5",
    ]  # fmt: skip
    assert verdict["information_tapes"][2]["by_mechanism"]["damping"]["bits"] > 0.0
    total = sum(tape["bits_destroyed"] for tape in verdict["information_tapes"])
    assert verdict["information_tape"]["bits_destroyed"] == pytest.approx(total)
    reverse = _assert_reversed_rows_are_the_forward_ones(tmp_path, "resting")  # a stage's end,
    assert reverse[1000].sum() > 0.0  # where the row is the stage's that ended there
    # the summary lists every file the run wrote: the stages' tapes and restarts too
    assert [(what, path.name) for what, path in result.outputs.stage_files] == [
        ("information tape", "resting.stage-0.tape.h5"),
        ("restart of press", "resting.stage-0.restart.h5"),
        ("information tape", "resting.stage-1.tape.h5"),
        ("restart of free", "resting.stage-1.restart.h5"),
        ("information tape", "resting.tape.h5"),
    ]
    with pytest.raises(InputError, match="reversal.all_stages: needs reversal.tape = true"):
        experiment.changed({"reversal.tape": False})
    # `revdem compare` finds the tapes from the reversal's restart, as the run did: it left
    # them out, and a verdict made again lost the information it counted
    from typer.testing import CliRunner

    from revdem_cli.cli import app

    pair = [str(result.trajectory()), str(result.trajectory("reverse"))]
    again = CliRunner().invoke(app, ["compare", *pair, "--json"])
    assert again.exit_code == 0, again.output
    assert json.loads(again.stdout) == json.loads(json.dumps(verdict))
    partial = revdem.reverse(result.outputs.restart, out=tmp_path / "part", steps=500)
    assert partial.comparison["information_tape"]["file"] == "resting.tape.h5"
    assert "information_tapes" not in partial.comparison


@pytest.fixture(scope="module")
def three_stages_run(tmp_path_factory) -> Path:
    """The folder of `_three_stages` run forward: a restart and a tape at each stage's end."""
    out = tmp_path_factory.mktemp("three_stages")
    revdem.run(_three_stages(), out, reverse=False)
    return out


EARLIER_DAMAGE = {
    "flipped entry": (
        lambda out: _flip_bytes(out / "resting.stage-0.tape.h5", "entries/amount"),
        "resting.stage-0.tape.h5: damaged tape (block 0, steps 0 to 999 fail their checksum)",
    ),
    "missing tape": (
        lambda out: (out / "resting.stage-0.tape.h5").unlink(),
        "resting.stage-0.tape.h5: not there",
    ),
    "another run's end": (
        lambda out: _set_attributes(out / "resting.stage-0.tape.h5", end_sha256="0" * 64),
        "resting.stage-0.tape.h5: not the information tape of ",
    ),
    "another schema": (
        lambda out: _set_attributes(out / "resting.stage-0.tape.h5", schema_version=2),
        "resting.stage-0.tape.h5: information tape schema 2, this revdem reads 3",
    ),
    "missing restart": (
        lambda out: (out / "resting.stage-0.restart.h5").unlink(),
        "resting.stage-0.restart.h5",
    ),
}


def _set_attributes(path: Path, **attributes) -> None:
    with h5py.File(path, "a") as f:
        f.attrs.update(attributes)


@pytest.mark.parametrize("damage", EARLIER_DAMAGE)
def test_every_tape_a_reversal_of_every_stage_needs_is_checked_before_its_first_step(
    three_stages_run, tmp_path, damage
):
    """With every stage reversed, the tape of the first stage was checked only when the
    reversal reached it, after the two stages after it (hours, in a long run), and the
    refusal left a partial reversed trajectory: it is refused in one line before the
    reversed trajectory is made, as the last stage's own tape is."""
    import shutil

    from typer.testing import CliRunner

    from revdem_cli.cli import app
    from tests.conftest import assert_one_line_error

    out = tmp_path / "run"
    shutil.copytree(three_stages_run, out)
    harm, why = EARLIER_DAMAGE[damage]
    harm(out)
    result = CliRunner().invoke(app, ["reverse", str(out / "resting.restart.h5"), "--threads", "1"])
    assert_one_line_error(result, str(out / why.split(":")[0]), why)
    assert not (out / "resting.reverse.h5").exists()


def test_a_reversal_of_every_stage_resumes_in_an_earlier_stage(tmp_path):
    """Stopped while reversing the middle stage (frame 45 of 60), the run resumes from its
    checkpoint there and goes on through the first stage to the same exact end."""
    experiment = _three_stages().changed({"output.checkpoint_interval": 0.0})
    shown = crashed_after(experiment, tmp_path / "cut", 45)
    assert shown[-1] == "free (reversed)"
    resumed = revdem.resume(tmp_path / "cut")
    assert resumed.comparison["bitwise_identical"]
    assert resumed.comparison["frames_compared"] == 31
    _assert_reversed_rows_are_the_forward_ones(tmp_path / "cut", "resting")
    # the verdict and the reversed trajectory are the uninterrupted run's: they counted only
    # the tapes reversed after the checkpoint, and named the middle stage's restart as the
    # one the reversal began from
    whole = revdem.run(experiment, tmp_path / "whole")
    assert resumed.comparison == whole.comparison
    assert len(resumed.comparison["information_tapes"]) == 3
    for run in (resumed, whole):
        with h5py.File(run.trajectory("reverse")) as f:
            assert Path(str(f["parameters/revdem"].attrs["source_restart"])).name == (
                "resting.restart.h5"
            )
    assert resumed.outputs.restart.name == "resting.restart.h5"


def test_the_information_figure_averages_each_stage_apart():
    """The figure's bits a step are a moving mean within each stage: a stage that destroys
    nothing stays at zero beside one that destroys much, and a steady rate stays steady up
    to its stage's ends, a stage shorter than the window included."""
    from revdem_cli.report.figures import moving_mean

    values = np.r_[np.zeros(100), np.full(100, 10.0), np.full(7, 3.0)]
    np.testing.assert_allclose(moving_mean(values, 20, [100, 200]), values, rtol=1e-12, atol=0)
    smeared = moving_mean(values, 20, [])  # one stretch: the jump spreads over the window
    assert smeared[95] > 0.0 and smeared[105] < 10.0


def test_the_information_figure_of_a_run_that_destroys_nothing_says_so(tmp_path):
    """The resting sphere without damping destroys no information: the figure was empty axes
    over 0 to 1 ms with an empty legend, and matplotlib warned that no artist had a label."""
    import warnings

    from revdem_cli.report.figures import information_by_step, information_figure

    result = revdem.run(_fixed(_resting({}), True), tmp_path, reverse=False)
    _, _, _, bits, _ = information_by_step(result.trajectory())
    assert len(bits) == 3000 and not bits.any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        png = information_figure(result.trajectory(), None, tmp_path / "information.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_the_trajectory_names_the_columns_of_its_bits_and_events(tmp_path):
    """`bits_destroyed` [F, 8] and `events` [F, kinds, columns] were bare numbers: which
    column is which mechanism lived only in the source."""
    import h5py

    from revdem_cli.kernels import events
    from revdem_cli.kernels.tape import MECHANISMS

    result = revdem.run(_fixed(_resting({}), True), tmp_path, reverse=False)
    with h5py.File(result.trajectory()) as f:
        bits = f["observables/bits_destroyed/value"]
        assert list(bits.attrs["columns"]) == list(MECHANISMS) and bits.shape[1] == 8
        log = f["observables/events/value"]
        assert list(log.attrs["kinds"]) == list(events.KINDS)
        assert list(log.attrs["columns"]) == list(events.COLUMNS)
        assert log.shape[1:] == (len(events.KINDS), len(events.COLUMNS))


def test_the_information_figure_reads_the_tape_of_every_stage(tmp_path):
    """With every stage reversed each stage leaves its own tape: the figure `information`
    reads them end to end, from step 0 to the run's last, each stage's start marked."""
    from revdem_cli.report.figures import information_by_step

    experiment = _three_stages().changed({"output.figures": ["information"]})
    result = revdem.run(experiment, tmp_path, reverse=False)
    assert result.outputs.figures == (tmp_path / "resting.information.png",)
    assert result.outputs.figures[0].read_bytes()[:4] == b"\x89PNG"
    stages, steps, times, bits, names = information_by_step(result.trajectory())
    tapes = ["resting.stage-0.tape.h5", "resting.stage-1.tape.h5", "resting.tape.h5"]
    assert len(steps) == len(bits) == sum(summary(tmp_path / tape)["steps"] for tape in tapes)
    assert steps[0] == 0 and np.all(np.diff(steps) == 1) and np.all(np.diff(times) > 0.0)
    assert [stage[:2] for stage in stages] == [("press", 0), ("free", 1000), ("held", 2000)]
    damping = names.index("damping")
    assert bits[:1000, damping].any() and bits[2000:, damping].any()  # local, then viscous
