"""The Python API: the README's example run as it is written there, and bad input raised
as the one line the command line prints."""

from __future__ import annotations

import copy
import os
import re
from pathlib import Path

import numpy as np
import pytest

from revdem_cli import api as revdem
from revdem_cli.errors import InputError, RunFailed
from tests.conftest import CONFIGS

README = Path(__file__).parents[2] / "README.md"


def _example() -> str:
    section = README.read_text().split("## Python\n", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_example_runs_as_written(tmp_path, capsys):
    """The example reverses the frictionless collision and not the sliding one, and its
    arrays are the trajectory's."""
    code = _example().replace('"configs/', f'"{CONFIGS}/')
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        scope: dict = {}
        exec(compile(code, "README.md", "exec"), scope)
    finally:
        os.chdir(here)
    assert capsys.readouterr().out.startswith("False [")
    verdict = scope["verdict"]
    assert verdict["reversible"] is False and verdict["divergence_causes"]
    time, energy = scope["time"], scope["energy"]
    assert len(time) == len(energy) > 10 and np.all(np.diff(time) > 0)
    mass = 1000.0 * 4.0 / 3.0 * np.pi * 0.005**3  # configs/collision.toml's spheres
    assert energy[0] == pytest.approx(0.5 * mass * (0.9**2 + 0.1**2 + 0.1**2), rel=1e-12)
    assert scope["position"].shape == (len(scope["steps"]), 2, 3)
    assert (tmp_path / "out" / "api" / "collision.compare.json").is_file()


def test_a_changed_field_is_checked_as_a_file_is():
    collision = revdem.load(CONFIGS / "collision.toml")
    with pytest.raises(InputError, match=r"collision.toml: integrator.dt: .*greater than 0"):
        collision.changed({"integrator.dt": -1.0})
    with pytest.raises(InputError, match=r"^<dict>: particles\[0\].radius"):
        revdem.from_dict(collision.fields, changes={"particles.0.radius": "big"})
    with pytest.raises(InputError, match="stages.5.steps: '5' is not an index of a list of 1"):
        collision.changed({"stages.5.steps": 10})
    fields = copy.deepcopy(collision.fields)
    fields["materials"]["sphere"]["poisson_ration"] = fields["materials"]["sphere"].pop(
        "poisson_ratio"
    )
    with pytest.raises(InputError) as misspelt:  # was missing poisson_ratio, one more problem
        revdem.from_dict(fields)
    assert str(misspelt.value) == (
        "<dict>: materials.sphere.poisson_ration: unknown field (did you mean poisson_ratio?)"
    )


def test_numpy_values_anywhere_in_the_fields_are_taken_as_python_values():
    """numpy's numbers and arrays inside the fields of `from_dict`, or inside a table that
    `changed` sets, raised yaml's RepresenterError from writing the experiment's text; they
    are now the Python values they hold, in the scenario and in its text."""
    import yaml

    fields = copy.deepcopy(revdem.load(CONFIGS / "collision.toml").fields)
    fields["particles"][1]["velocity"] = np.array([-0.5, 0.0, 0.0])
    fields["stages"][0]["steps"] = np.int64(3000)
    fields["output"]["contacts"] = np.bool_(True)
    experiment = revdem.from_dict(fields)
    assert experiment.scenario.stages[0].steps == 3000
    assert yaml.safe_load(experiment.text)["particles"][1]["velocity"] == [-0.5, 0.0, 0.0]
    stage = {**experiment.fields["stages"][0], "steps": np.int32(200)}
    changed = experiment.changed({"stages.0": stage})
    assert yaml.safe_load(changed.text)["stages"][0]["steps"] == 200
    assert changed.scenario.stages[0].steps == 200


def test_changes_that_are_not_a_mapping_of_dotted_paths_are_refused():
    """Changes given as a list of pairs, or keyed by a number, raised AttributeError from
    deep inside; each is an InputError naming what `changes` must be."""
    collision = CONFIGS / "collision.toml"
    experiment = revdem.load(collision)
    for call in (
        lambda: experiment.changed([("stages.0.steps", 100)]),
        lambda: revdem.load(collision, changes=[("stages.0.steps", 100)]),
        lambda: revdem.from_dict(experiment.fields, changes=[("stages.0.steps", 100)]),
    ):
        with pytest.raises(InputError) as raised:
            call()
        assert str(raised.value) == (
            "changes: a mapping of dotted paths to values, {'stages.0.steps': 100}, not list"
        )
    with pytest.raises(InputError) as raised:
        experiment.changed({5: 1})
    assert str(raised.value) == (
        "changes: the key 5: a dotted path as text, 'stages.0.steps', not int"
    )


def test_a_field_given_twice_is_refused_as_set_refuses_it():
    """A field in both `changes` and `overrides`, or twice in `changes` under two spellings
    of its path, took the last value given where `--set` refuses it; each names both."""
    collision = CONFIGS / "collision.toml"
    with pytest.raises(InputError) as raised:
        revdem.load(collision, {"integrator.dt": 1e-8}, overrides=["integrator.dt=5e-8"])
    assert str(raised.value) == (
        "changes['integrator.dt']: integrator.dt is given twice "
        "(also overrides 'integrator.dt=5e-8')"
    )
    with pytest.raises(InputError) as raised:
        revdem.load(collision).changed({"stages.0.steps": 100, " stages[0].steps": 200})
    assert str(raised.value) == (
        "changes[' stages[0].steps']: stages.0.steps is given twice "
        "(also changes['stages.0.steps'])"
    )
    both = revdem.load(collision, {"stages[0].steps": 100}, overrides=["integrator.dt=5e-8"])
    assert (both.scenario.stages[0].steps, both.scenario.integrator.dt) == (100, 5e-8)


def test_what_is_run_and_each_switch_must_be_of_its_kind(tmp_path):
    """A dict or None given as the experiment raised AttributeError, and a switch given as
    text ran as True (`reverse="no"` reversed): each is refused, naming the argument and
    what it may be, before anything runs."""
    for experiment, kind in (({"name": "x"}, "dict"), (None, "NoneType")):
        with pytest.raises(InputError) as raised:
            revdem.run(experiment, tmp_path / "x")
        assert str(raised.value) == (
            "experiment: an Experiment (load, from_dict) or a scenario file's path (str or "
            f"Path), not {kind}"
        )
    short = revdem.load(CONFIGS / "collision.toml", {"stages.0.steps": 200})
    for switch in ("reverse", "force", "allow_unstable_dt", "progress"):
        with pytest.raises(InputError, match=f"^{switch}='no': True or False, not str$"):
            revdem.run(short, tmp_path / "x", **{switch: "no"})
    assert not (tmp_path / "x").exists()
    restart = revdem.run(short, tmp_path / "run", reverse=np.bool_(False)).outputs.restart
    with pytest.raises(InputError, match="^force=1: True or False, not int$"):
        revdem.reverse(restart, force=1)
    with pytest.raises(InputError, match="^progress=None: True or False, not NoneType$"):
        revdem.resume(tmp_path / "run", progress=None)
    with pytest.raises(InputError, match="^host='yes': True or False, not str$"):
        short.changed({"stages.0.steps": 100}, host="yes")


def test_threads_are_chosen_as_threads_chooses_them(tmp_path):
    """`run`, `reverse` and `resume` took no thread count (only `revdem_cli.threads.use`
    did); `threads=N` is `--threads N`: at most N threads, and a count that is not a whole
    number from 1 to the pool's is refused as the command line refuses it."""
    import numba

    from revdem_cli import threads

    short = revdem.load(CONFIGS / "collision.toml", {"stages.0.steps": 200})
    try:
        result = revdem.run(short, tmp_path / "run", reverse=False, threads=1)
        assert numba.get_num_threads() == 1
        threads.use()
        revdem.reverse(result.outputs.restart, tmp_path / "back", steps=100, threads=1)
        assert numba.get_num_threads() == 1
        for count, problem in [
            (threads.most() + 1, "NUMBA_NUM_THREADS"),
            (0, "0 threads: between 1"),
            (2.5, "must be a whole number"),
            ("2", "must be a whole number"),
            (True, "must be a whole number"),
        ]:
            with pytest.raises(InputError, match=rf"^--threads {count!r}: .*{problem}"):
                revdem.run(short, tmp_path / "run", reverse=False, force=True, threads=count)
            with pytest.raises(InputError, match=rf"^--threads {count!r}: .*{problem}"):
                revdem.resume(tmp_path / "run", threads=count)
    finally:
        threads.use()


def test_results_name_what_they_do_not_have(tmp_path):
    result = revdem.run(revdem.load(CONFIGS / "collision.toml"), tmp_path, reverse=False)
    assert result.comparison is None
    with pytest.raises(InputError, match="no reverse trajectory"):
        result.observable("kinetic_energy", run="reverse")
    with pytest.raises(InputError, match="no observable 'entropy'.*kinetic_energy"):
        result.observable("entropy")
    assert set(result.observables()) >= {"kinetic_energy", "total_energy"}


def test_what_a_script_gives_wrongly_is_refused_before_anything_runs(tmp_path):
    """The checks the command line's options have, for the API's arguments: a reversal of
    2.5 steps crashed or hung the compiled loop, a frame out of range wrapped round, an
    empty folder was the working one."""
    collision = CONFIGS / "collision.toml"
    with pytest.raises(InputError, match="^out: an empty path"):
        revdem.run(collision, "")
    short = revdem.load(collision, overrides=["stages.0.steps=200", "output.contacts=true"])
    result = revdem.run(short, tmp_path / "run", reverse=False)
    for steps in (2.5, "100", True, 0, 201):
        with pytest.raises(InputError, match=f"^--steps {steps!r}: must be a whole number"):
            revdem.reverse(result.outputs.restart, tmp_path / "back", steps=steps)
    assert not list(tmp_path.glob("back/*"))  # nothing written before the refusal
    frames = len(result.frames("position")[0])
    assert result.contacts(frames - 1) is not None and result.contacts(-frames) is not None
    for frame in (frames, -frames - 1):
        with pytest.raises(InputError, match=f"^frame {frame!r}: the trajectory has {frames}"):
            result.contacts(frame)
    for frame in (1.5, "3", None):  # said only how many frames there are
        with pytest.raises(InputError, match=f"^frame {frame!r}: must be a whole number"):
            result.contacts(frame)
    assert revdem.run(collision, tmp_path / "path", reverse=False, force=True).comparison is None


def test_an_empty_folder_is_refused_wherever_one_is_taken(tmp_path, monkeypatch):
    """`reverse(restart, out="")` wrote into the working folder, and `read("")` and
    `resume("")` read it, as `Path("")` is "."; each is refused as `run(..., "")` is."""
    folder = tmp_path / "run"
    short = revdem.load(CONFIGS / "collision.toml", {"stages.0.steps": 200})
    restart = revdem.run(short, folder, reverse=False).outputs.restart.absolute()
    written = sorted(folder.iterdir())
    monkeypatch.chdir(folder)  # where "" would read and write
    for call in (
        lambda: revdem.reverse(restart, out="", force=True),
        lambda: revdem.read(""),
        lambda: revdem.resume(" "),
    ):
        with pytest.raises(InputError, match=r"^out: an empty path; give a folder \('\.' for"):
            call()
    assert sorted(folder.iterdir()) == written


def test_paths_and_arguments_of_the_wrong_kind_are_input_errors(tmp_path):
    """A file given as the folder of a run raised FileExistsError or NotADirectoryError, None
    or a list TypeError, and overrides given as one text were read letter by letter (`--set
    i: expected key=value`). Each is now the InputError with the command line's line."""
    short = revdem.load(CONFIGS / "collision.toml", {"stages.0.steps": 200})
    afile = tmp_path / "afile"
    afile.write_text("mine")
    for out, line in [
        (afile, f"{afile}: a file, not a folder"),
        (afile / "sub", f"{afile / 'sub'}: {afile} is a file, not a folder"),
        (None, "out: a path (str or Path), not NoneType"),
    ]:
        with pytest.raises(InputError) as raised:
            revdem.run(short, out)
        assert str(raised.value) == line
    result = revdem.run(short, tmp_path / "run", reverse=False)
    with pytest.raises(InputError, match=f"^{afile}: a file, not a folder$"):
        revdem.reverse(result.outputs.restart, afile)
    with pytest.raises(InputError, match="^<dict>: the scenario's fields as a dict, not list$"):
        revdem.from_dict([1, 2])
    with pytest.raises(InputError, match=r"^overrides: a list of key=value texts, not one"):
        revdem.load(CONFIGS / "collision.toml", overrides="integrator.dt=5e-8")
    assert afile.read_text() == "mine"
    collision = CONFIGS / "collision.toml"
    with pytest.raises(InputError, match=f"^{collision}: stages.5.steps: '5' is not an index"):
        short.changed({"stages.5.steps": 3})
    faster = short.changed({"particles.0.velocity": np.array([0.5, 0.0, 0.0]), "integrator.dt":
                            np.float64(5e-8)})  # fmt: skip
    assert faster.scenario.integrator.dt == 5e-8


def test_a_run_with_walls_gives_each_walls_observables(tmp_path):
    """`observables()` of any run with walls raised "damaged revdem trajectory": wall_force
    and wall_position are a group a wall, with no series of their own. Each wall's series
    is now one observable by its path, and an unknown name lists those."""
    drop = revdem.load(CONFIGS / "drop_A.toml", {"stages.0.steps": 2000})
    result = revdem.run(drop, tmp_path, reverse=False)
    observables = result.observables()
    assert {"wall_force/plane", "wall_position/plane", "kinetic_energy"} <= set(observables)
    assert "events" not in observables and "wall_force" not in observables
    time, force = result.observable("wall_force/plane")
    assert force.shape == (len(time), 3)
    with pytest.raises(InputError, match=r"no observable 'wall_force' \(the run has: .*"
                       r"wall_force/plane, wall_position/plane"):  # fmt: skip
        result.observable("wall_force")


def test_an_earlier_run_is_read_back_as_the_result_it_gave(tmp_path):
    """`revdem.read(folder)` gives the Result of a run written before (there was no way to
    open one): its paths, its verdict as compare.json holds it, its arrays; a folder of no
    run, or of several without a name, is refused naming what it holds."""
    experiment = revdem.load(CONFIGS / "smoke" / "collision.yaml").changed({"stages.0.steps": 300})
    ran = revdem.run(experiment, tmp_path / "a")
    read = revdem.read(tmp_path / "a")
    assert (read.outputs.forward, read.outputs.reverse) == (
        ran.outputs.forward,
        ran.outputs.reverse,
    )
    assert read.comparison == ran.comparison and read.comparison["reversible"]
    steps, _, velocity = read.frames("velocity", "reverse")  # the reversal, from step 300
    assert steps[0] == 300 and steps[-1] == 0 and velocity.shape == (len(steps), 2, 3)
    assert "verdict" not in repr(read.outputs)  # every frame's errors are not printed
    revdem.run(experiment.changed({"name": "other"}), tmp_path / "a", reverse=False)
    with pytest.raises(InputError, match="the runs collision_smoke, other; give name="):
        revdem.read(tmp_path / "a")
    forward_only = revdem.read(tmp_path / "a", "other")
    assert forward_only.comparison is None and forward_only.outputs.reverse is None
    with pytest.raises(InputError, match="no run"):
        revdem.read(tmp_path)


def test_a_result_gives_every_per_sphere_field_the_run_keeps_and_whether_it_ended(tmp_path):
    """`frames` refused the spheres' stresses and the fixed-point grids a run writes, the
    radii, masses, ids and materials were not to be had, and a run read back that had blown
    up looked like one that had ended."""
    experiment = revdem.load(CONFIGS / "smoke" / "collision.yaml").changed(
        {"stages.0.steps": 300, "output.particle_stress": True, "integrator.arithmetic": "fixed"}
    )
    revdem.run(experiment, tmp_path / "a", reverse=False)
    result = revdem.read(tmp_path / "a")
    steps, _, stress = result.frames("stress")
    assert stress.shape == (len(steps), 2, 3, 3) and np.allclose(stress, stress.swapaxes(2, 3))
    _, _, grid = result.frames("position_grid")
    assert grid.dtype == np.int64 and grid.shape == (len(steps), 2, 3)
    spheres = result.spheres()
    radii = [p.radius for p in experiment.scenario.particles]
    assert spheres["radius"].tolist() == radii and spheres["id"].tolist() == [1, 2]
    assert spheres["mass"] == pytest.approx(4 / 3 * np.pi * np.array(radii) ** 3 * 1000.0)
    assert spheres["material"].tolist() == [0, 0] and result.ended is True
    with pytest.raises(InputError, match="no frame field 'entropy' .*stress, position_grid"):
        result.frames("entropy")

    blown = revdem.load(CONFIGS / "smoke" / "collision.yaml").changed(
        {"integrator.overlap_limit": 0.01}  # reached part-way into the contact
    )
    with pytest.raises(RunFailed):
        revdem.run(blown, tmp_path / "b")
    assert revdem.read(tmp_path / "b").ended is False
    with pytest.raises(InputError, match="no frame field 'stress'"):
        revdem.read(tmp_path / "b").frames("stress")


def test_a_reversal_gives_the_restart_it_ran_from_as_reading_it_back_does(tmp_path):
    """`reverse(restart).outputs.restart` was None, where `read` of its folder gives it."""
    short = revdem.load(CONFIGS / "collision.toml", {"stages.0.steps": 200})
    restart = revdem.run(short, tmp_path / "run", reverse=False).outputs.restart
    reversed_ = revdem.reverse(restart, tmp_path / "back", steps=100)
    assert reversed_.outputs.restart == restart
    assert revdem.read(tmp_path / "back").outputs.restart.resolve() == restart.resolve()


def test_a_reversal_into_a_folder_of_its_own_is_read_back_with_its_forward_run(tmp_path):
    """`revdem.reverse(restart, out=elsewhere)` wrote a reversal that `read` refused: its
    folder held no NAME.forward.h5. It now comes with the forward run its restart ends."""
    experiment = revdem.load(CONFIGS / "smoke" / "collision.yaml").changed({"stages.0.steps": 300})
    ran = revdem.run(experiment, tmp_path / "a", reverse=False)
    reversed_ = revdem.reverse(ran.outputs.restart, out=tmp_path / "b", steps=200)
    read = revdem.read(tmp_path / "b")
    assert read.outputs.forward.resolve() == ran.outputs.forward.resolve()
    assert read.outputs.restart.resolve() == ran.outputs.restart.resolve()
    assert read.outputs.reverse == tmp_path / "b" / "collision_smoke.reverse.h5"
    assert read.comparison == reversed_.comparison and read.comparison["reversible"]
    steps, _, _ = read.frames("position", "reverse")
    assert steps[0] == 300 and steps[-1] == 100
    ran.outputs.restart.unlink()
    with pytest.raises(InputError, match="reverse.h5's restart or forward run is not there"):
        revdem.read(tmp_path / "b")


def test_critical_time_steps_are_the_command_lines(tmp_path):
    """`revdem dt` had no Python function: its internals took a negative radius and gave a
    negative mass. `critical_time_step` and `packing_time_step` give what `--json` prints,
    checked as the command line checks it."""
    import json

    from typer.testing import CliRunner

    from revdem_cli.cli import app

    ellipsoid = {"shape": "ellipsoid", "semi_axes": (3, 2, 1), "density": 1000}
    given = revdem.critical_time_step(ellipsoid, kn=1e10, damping=np.float64(0.5))
    args = ["dt", "--shape", "ellipsoid", "--semi-axes", "3", "2", "1", "--density", "1000"]
    printed = CliRunner().invoke(app, [*args, "--kn", "1e10", "--damping", "0.5", "--json"])
    assert printed.exit_code == 0, printed.output
    assert json.loads(json.dumps(given)) == json.loads(printed.stdout)  # tuples as lists
    sphere = {"shape": "sphere", "radius": 0.01, "density": 2500}
    pair = revdem.critical_time_step(sphere, {"radius": 0.02}, kn=1e6)
    alone = revdem.critical_time_step({**sphere, "radius": 0.02}, {"radius": 0.01}, kn=1e6)
    assert pair["recommended_dt"] == alone["recommended_dt"]  # the pair either way round
    for wrong, message in (
        ({**sphere, "radius": -1.0}, "--radius must be a positive number, got -1"),
        ({**sphere, "radius": "1"}, "particle['radius']='1': a number, not str"),
        ({**sphere, "size": 1}, "particle['size']: not one of shape, radius"),
        ({**ellipsoid, "semi_axes": (3, 2)}, "particle['semi_axes']=(3, 2): 3 numbers"),
        ([0.01], "particle: a dict of shape"),
    ):
        with pytest.raises(InputError, match=re.escape(message)):
            revdem.critical_time_step(wrong, kn=1e6)
    with pytest.raises(InputError, match=re.escape("kn=True: a number, not bool")):
        revdem.critical_time_step(sphere, kn=True)

    run = revdem.run(
        revdem.load(CONFIGS / "fcc_triaxial.toml").changed(
            {"stages.0.steps": 200, "stages.1.steps": 100, "output.figures": []}
        ),
        tmp_path,
        reverse=False,
        threads=1,
    )
    packing = revdem.packing_time_step(run.outputs.restart)
    printed = CliRunner().invoke(app, ["dt", "--restart", str(run.outputs.restart), "--json"])
    timed = json.loads(printed.stdout)
    for report in (packing, timed):
        report["assembly"].pop("seconds")
    assert json.loads(json.dumps(packing)) == timed and packing["assembly"]["dt"] > 0.0
    with pytest.raises(InputError, match="restart: a path"):
        revdem.packing_time_step(3)
