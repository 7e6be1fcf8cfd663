"""`revdem report`: the paper's numbers beside a directory's runs, as a Markdown page."""

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import ROOT, assert_one_line_error

runner = CliRunner()

PAPER = """
[collision_smoke]
config = "CONFIG"
section = "§0"
max_position_error_rel = 1e-10
reversible = false
max_shear_force = 0.066
relative_tolerance = 0.10
coefficient_of_restitution = 1.0

[drop_A]
reversible = true
"""


def smoke_config(folder) -> str:
    """The smoke collision as `smoke_run` ran it (1000 steps each way), a file in `folder`."""
    text = (ROOT / "configs/smoke/collision.yaml").read_text()
    path = folder / "collision.yaml"
    path.write_text(text.replace("steps: 5000", "steps: 1000"))
    return str(path)


def test_report_judges_each_number_against_the_run(smoke_run, tmp_path):
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER.replace("CONFIG", smoke_config(tmp_path)))
    page = tmp_path / "page.md"
    args = ["report", str(smoke_run), "--paper", str(paper), "--out", str(page)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    smoke, drop = page.read_text().split("## drop_A")
    lines = smoke.splitlines()
    assert "## collision_smoke (§0)" in lines
    rows = {line.split(" | ")[0].strip("| "): line for line in lines if line.startswith("| ")}
    assert rows["max_position_error_rel"].endswith("| yes |")  # the smoke run reverses
    assert "| no | yes | **no** |" in rows["reversible"]  # the paper file says otherwise
    assert "| 0.066 ± 10% | 0 | **no** |" in rows["max_shear_force"]  # no shear law
    assert "not measured" in rows["coefficient_of_restitution"]
    assert drop.splitlines()[-1] == "| reversible | yes | no drop_A.compare.json |  |"


def test_a_run_of_other_settings_than_the_cases_is_shown_not_judged(smoke_run, tmp_path):
    """A run made with --set (here 1000 steps each way, the config's 5000) was judged
    against the paper's numbers as if it were the paper's case: revdem then seemed to
    disagree with the paper."""
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER.replace("CONFIG", "configs/smoke/collision.yaml"))
    page = tmp_path / "page.md"
    args = ["report", str(smoke_run), "--paper", str(paper), "--out", str(page)]
    assert runner.invoke(app, args).exit_code == 0
    smoke = page.read_text().split("## drop_A")[0]
    assert (
        "**Not the paper's case**: the run differs from `configs/smoke/collision.yaml` in "
        "`stages.0.steps = 1000 (5000 in configs/smoke/collision.yaml)`. Its numbers are "
        "shown, not judged." in smoke
    )
    rows = [line for line in smoke.splitlines() if line.startswith("| ") and "quantity" not in line]
    assert "| no | yes | not the case |" in "".join(rows)
    assert not any("**no**" in row or row.endswith("| yes |") for row in rows)
    # what changes no number, a checkpoint interval say, leaves it the case
    out = tmp_path / "checkpointed"
    args = ["run", str(ROOT / "configs/smoke/collision.yaml"), "--out", str(out), "-q"]
    args += ["--set", "stages.0.steps=1000", "--set", "output.checkpoint_interval=5"]
    assert runner.invoke(app, args).exit_code == 0
    paper.write_text(PAPER.replace("CONFIG", smoke_config(tmp_path)))
    assert (
        runner.invoke(
            app, ["report", str(out), "--paper", str(paper), "--out", str(page), "--force"]
        ).exit_code
        == 0
    )
    assert "Not the paper's case" not in page.read_text()


def test_a_number_within_an_absolute_tolerance_and_one_the_run_sets(smoke_run, tmp_path):
    """The oedometer's solid fractions were judged within the case's 10 %, which let its
    start (0.606) pass for its end (0.625), and its start, where a stage of the run stops,
    was said to agree. `<quantity>_absolute_tolerance` judges a number within so much of
    the paper's, before any relative tolerance; `<quantity>_set_by` shows it, not judged."""
    paper = tmp_path / "paper.toml"
    given = PAPER.replace("CONFIG", smoke_config(tmp_path))

    def report(*entries):
        paper.write_text(given.replace("[drop_A]", "\n".join(entries) + "\n\n[drop_A]"))
        page = tmp_path / "page.md"
        args = ["report", str(smoke_run), "--paper", str(paper), "--out", str(page), "--force"]
        result = runner.invoke(app, args)
        if result.exit_code:
            return result
        lines = page.read_text().split("## drop_A")[0].splitlines()
        return {line.split(" | ")[0].strip("| "): line for line in lines if line.startswith("| ")}

    rows = report("max_shear_force_absolute_tolerance = 0.07", 'reversible_set_by = "the test"')
    assert rows["max_shear_force"].endswith("| 0.066 ± 0.07 | 0 | yes |")  # 10 %: **no**
    assert rows["reversible"].endswith("| no | yes | not judged: set by the test |")
    for entry, wrong in [
        ("max_shear_force_absolute_tolerance = -1", "= -1: give a number, 0 or more"),
        ('max_shear_force_absolute_tolerance = "x"', "= 'x': give a number, 0 or more"),
        ("reversible_set_by = 1", "reversible_set_by = 1: say what sets it"),
        ("max_normal_force_absolute_tolerance = 1", "collision_smoke reports no max_normal_force"),
        # a wall's force of a case that names no wall failed with a KeyError
        ("lower_wall_force_end = 1.0", "give collision_smoke.lower_wall, the name of that wall"),
        ("lower_wall = 3\nlower_wall_force_end = 1.0", "= 3: give the name of a wall of the"),
    ]:
        assert_one_line_error(report(entry), f"collision_smoke.{entry.split(' =')[0]}", wrong)


def test_the_oedometers_solid_fractions_are_told_apart():
    """Within the committed paper file's tolerance the oedometer's end is not its start nor
    its start its end, while the paper's rounding (0.0005) and the 0.0006 by which the close
    stage may pass 0.606 are within it; the start, which the run sets, is not judged."""
    from revdem_cli.report.paper import HANLEY_2020, _judge, read_paper, tolerance_of

    oedometer = read_paper(HANLEY_2020)["oedometer"]
    for moment, other in (("end", "start"), ("reversed", "end")):
        key = f"solid_fraction_{moment}"
        tolerance = tolerance_of(oedometer, key)
        assert not _judge("close", oedometer[key], oedometer[f"solid_fraction_{other}"], tolerance)
        assert _judge("close", oedometer[key], oedometer[key] + 0.0011, tolerance)
    assert "solid_fraction_start_set_by" in oedometer


def test_a_tolerance_of_revdems_is_shown_as_standing_for_the_papers_words(smoke_run, tmp_path):
    """Hanley 2020 gives no bound on a reversal's error (§3.2.1: the plots overlap), yet the
    paper column showed revdem's tolerances, ≤ 1e-10, as if it did. A number with
    `<quantity>_stands_for` is shown after the paper's words, marked revdem's, and judged
    as before."""
    from revdem_cli.report.paper import HANLEY_2020, MEASURES, read_paper

    paper = tmp_path / "paper.toml"
    stands = 'max_position_error_rel_stands_for = "the curves overlap"\n[drop_A]'
    paper.write_text(PAPER.replace("CONFIG", smoke_config(tmp_path)).replace("[drop_A]", stands))
    page = tmp_path / "page.md"
    args = ["report", str(smoke_run), "--paper", str(paper), "--out", str(page)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    row = '| max_position_error_rel | "the curves overlap": revdem\'s ≤ 1e-10 | '
    assert next(line for line in page.read_text().splitlines() if line.startswith(row)).endswith(
        "| yes |"
    )
    paper.write_text(paper.read_text().replace('"the curves overlap"', "1"))
    wrong = "collision_smoke.max_position_error_rel_stands_for = 1: give the paper's words"
    assert_one_line_error(runner.invoke(app, [*args, "--force"]), wrong)
    for case in read_paper(HANLEY_2020).values():  # the paper bounds no error: each is revdem's
        bounds = [key for key in case if MEASURES.get(key, ("",))[0] == "at most"]
        assert all(f"{key}_stands_for" in case for key in bounds), case


def test_a_reversal_short_of_the_reversed_stages_start_is_shown_not_judged(tmp_path):
    """`revdem reverse --steps 300` of the smoke collision's 1000 steps reverses steps 1000
    to 700 alone: its error was judged to agree with the paper's claim of the whole stage,
    which it never tested. A reversal of the whole stage is judged; one whose restart is
    gone, which alone tells where the stage began, is not."""
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER.replace("CONFIG", smoke_config(tmp_path)))
    out = tmp_path / "part"
    args = ["run", smoke_config(tmp_path), "--out", str(out), "-q", "--no-reverse"]
    assert runner.invoke(app, args).exit_code == 0
    restart = str(out / "collision_smoke.restart.h5")
    result = runner.invoke(app, ["reverse", restart, "--steps", "300", "-q"])
    assert result.exit_code == 0, result.output

    def case(directory):
        page = tmp_path / "page.md"
        args = ["report", str(directory), "--paper", str(paper), "--out", str(page), "--force"]
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        smoke = page.read_text().split("## drop_A")[0]
        rows = {line.split(" | ")[0].strip("| "): line for line in smoke.splitlines()}
        return smoke, rows

    smoke, rows = case(out)
    assert (
        "**Not the paper's case**: it reversed 300 of the reversed stage's 1000 steps, going "
        "back from step 1000 to step 700, not to step 0. Its numbers are shown, not judged."
        in smoke
    )
    assert rows["max_position_error_rel"].endswith("| not the case |")
    result = runner.invoke(app, ["reverse", restart, "-q", "--force"])  # the whole stage
    assert result.exit_code == 0, result.output
    smoke, rows = case(out)
    assert "Not the paper's case" not in smoke
    assert rows["max_position_error_rel"].endswith("| yes |")
    (out / "collision_smoke.restart.h5").unlink()
    smoke, rows = case(out)
    assert "**Not judged**: no collision_smoke.restart.h5, without which how far back" in smoke
    assert rows["max_position_error_rel"].endswith("| not judged |")


def test_a_run_reversing_every_stage_is_measured_at_its_reversed_stage(tmp_path):
    """With `[reversal] all_stages` the reversed trajectory runs back to step 0, whose
    lattice carries no stress: the fcc case's start and reversed values were read there
    (sigma_1/sigma_3 nan, coordination 0), not where its reversed stage began."""
    overrides = [
        "--set", "stages.0.steps=3000", "--set", "stages.1.steps=2000",
        "--set", "integrator.arithmetic=fixed", "--set", "reversal.tape=true",
    ]  # fmt: skip
    pages = []
    for every in ("false", "true"):
        out = tmp_path / every
        args = ["run", str(ROOT / "configs/fcc_triaxial.toml"), "--out", str(out), "-q"]
        args += [*overrides, "--set", f"reversal.all_stages={every}"]
        assert runner.invoke(app, args).exit_code == 0
        page = out / "r.md"
        assert runner.invoke(app, ["report", str(out), "--out", str(page)]).exit_code == 0
        case = page.read_text().split("## fcc_triaxial")[1].split("##")[0]
        rows = [line for line in case.splitlines() if line.startswith("| ")]
        pages.append([row for row in rows if not row.startswith("| quantity")])
    assert pages[1] == pages[0]
    rows = {row.split(" | ")[0].strip("| "): row.split(" | ")[2] for row in pages[1]}
    assert rows["stress_ratio_start"] == rows["stress_ratio_reversed"] == "1"
    assert rows["coordination_number_start"] == "12"


def test_a_value_the_run_does_not_hold_is_named_in_its_row(tmp_path):
    """The fcc test reversed 1000 of its sheared stage's 2000 steps has no row at the
    stage's start, where its reversed values are read: `revdem report` failed with an
    IndexError. Its row names what the run lacks, as for a wall the run does not have."""
    out = tmp_path / "fcc"
    args = ["run", str(ROOT / "configs/fcc_triaxial.toml"), "--out", str(out), "-q"]
    args += ["--no-reverse", "--set", "stages.0.steps=3000", "--set", "stages.1.steps=2000"]
    assert runner.invoke(app, args).exit_code == 0
    restart = str(out / "fcc_triaxial.restart.h5")
    assert runner.invoke(app, ["reverse", restart, "--steps", "1000", "-q"]).exit_code == 0
    paper = tmp_path / "paper.toml"
    text = (ROOT / "scenarios/hanley2020/paper_numbers.toml").read_text()
    walled = '[fcc_triaxial]\nlower_wall = "bottom"\nlower_wall_force_end = 1.0'
    paper.write_text(text.replace("[fcc_triaxial]", walled))  # the periodic cell has none
    page = tmp_path / "r.md"
    result = runner.invoke(app, ["report", str(out), "--paper", str(paper), "--out", str(page)])
    assert result.exit_code == 0, result.output
    case = page.read_text().split("## fcc_triaxial")[1]
    rows = {line.split(" | ")[0].strip("| "): line for line in case.splitlines()}
    lacks = "no coordination_number at step 3000 in fcc_triaxial.reverse.h5 |  |"
    assert rows["coordination_number_reversed"].endswith(lacks)
    assert rows["lower_wall_force_end"].endswith(
        "| no wall_force/bottom in fcc_triaxial.forward.h5 |  |"
    )


def short_run(config, out, *changes: str) -> None:
    """A run of `config` into `out`, forward only, on one thread, changed by `--set`s."""
    args = ["run", str(ROOT / config), "--out", str(out), "-q", "--no-reverse", "--threads", "1"]
    args += [part for change in ["output.figures=[]", *changes] for part in ("--set", change)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output


def report_rows(out, paper_text: str, tmp_path) -> dict[str, dict[str, str]]:
    """The revdem column of each case's rows of `revdem report` of the runs in `out`."""
    paper, page = tmp_path / "paper.toml", tmp_path / "page.md"
    paper.write_text(paper_text)
    args = ["report", str(out), "--paper", str(paper), "--out", str(page), "--force"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    cases = {}
    for case in page.read_text().split("\n## ")[1:]:
        rows = [line.split(" | ") for line in case.splitlines() if line.startswith("| ")]
        cases[case.split()[0]] = {row[0].strip("| "): row[2] for row in rows[1:]}
    return cases


def test_a_value_a_short_run_lacks_is_named_by_every_measure(smoke_run, tmp_path):
    """The drop's and the fcc test's measures read their files themselves: the terminal
    velocity of a drop cut short before its contact was its last frame's, shown as if it
    were the paper's, and the peak stress ratio of a run without principal stresses (no
    periodic cell) failed with a KeyError; the shear force at separation of a collision cut
    short in contact was its last, and of one never in contact 0. Each row names what the
    run lacks, as for a value at the reversed stage's start."""
    short = ["stages.0.steps=4000", "stages.0.output_every=1000", "stages.0.observables_every=500"]
    out = tmp_path / "runs"
    short_run("configs/drop_C.toml", out, *short)  # 40 us: 8 nm of its 300 um fall
    short_run("configs/smoke/collision.yaml", out, "stages.0.steps=1500")  # touching from 1150
    paper = """
[drop_C]
terminal_velocity = -0.00981
peak_stress_ratio = 2.0
reversible = false

[collision_smoke]
shear_force_at_separation = 0.035
max_shear_force = 0.066
"""
    rows = report_rows(out, paper, tmp_path)
    assert rows["drop_C"] == {
        "terminal_velocity": "no contact in drop_C.forward.h5",
        "peak_stress_ratio": "no principal_stress in drop_C.forward.h5",
        "reversible": "no drop_C.compare.json",
    }
    assert rows["collision_smoke"] == {
        "shear_force_at_separation": "no separation in collision_smoke.forward.h5",
        "max_shear_force": "0",  # the smoke collision has no shear law: a value, not a lack
    }
    never = report_rows(smoke_run, paper, tmp_path)["collision_smoke"]  # 1000 steps apart
    assert never["shear_force_at_separation"] == "no contact in collision_smoke.forward.h5"
    touching = tmp_path / "touching"  # the drop started on its plane: no frame before
    short_run("configs/drop_C.toml", touching, *short, "particles.0.position=[0, 0, 0.00499]")
    assert report_rows(touching, paper, tmp_path)["drop_C"]["terminal_velocity"] == (
        "no frame before the first contact (at 0 s) in drop_C.forward.h5"
    )


def test_an_fcc_trajectory_cut_short_of_its_stage_names_what_it_lacks(tmp_path):
    """A forward trajectory whose observables stop before the reversed stage (their rows
    from there on cut away) failed the report with a traceback for the peak stress ratio,
    and showed the last rows it had, from the stage before, as the stage's end."""
    out = tmp_path / "fcc"
    short = ["stages.0.steps=300", "stages.1.steps=200"]
    short_run("configs/fcc_triaxial.toml", out, *short, "stages.0.output_every=100",
              "stages.1.output_every=100")  # fmt: skip
    committed = (ROOT / "scenarios/hanley2020/paper_numbers.toml").read_text()
    paper = committed.replace("[fcc_triaxial]", "[fcc_triaxial]\nstress_ratio_end = 2.0")
    whole = report_rows(out, paper, tmp_path)["fcc_triaxial"]
    assert whole["coordination_number_end"] == "12" and float(whole["peak_stress_ratio"]) > 1.0
    with h5py.File(out / "fcc_triaxial.forward.h5", "r+") as f:
        series = f["observables/principal_stress"]
        kept = int(np.searchsorted(series["step"][:], 300))  # the rows before step 300
        for part in ("step", "time"):  # which every observable shares
            series[part].resize(kept, axis=0)
    rows = report_rows(out, paper, tmp_path)["fcc_triaxial"]
    lacks = "no {} in fcc_triaxial.forward.h5".format
    assert rows["peak_stress_ratio"] == lacks("principal_stress from step 300 on")
    assert rows["stress_ratio_start"] == lacks("principal_stress at step 300")
    assert rows["stress_ratio_end"] == lacks("principal_stress at step 500")
    assert rows["coordination_number_end"] == lacks("coordination_number at step 500")


def test_report_makes_one_run_of_each_case(smoke_run, tmp_path, monkeypatch):
    """The report made a case's run three times over: to find whether the folder held any,
    for what it says of the run, and for its rows. Nothing shows it on the page (the run
    reads its files when asked), so the runs made are counted."""
    from revdem_cli.report import paper

    made = []

    class Counted(paper._Run):
        def __init__(self, directory, name, case):
            made.append(name)
            super().__init__(directory, name, case)

    monkeypatch.setattr(paper, "_Run", Counted)
    rows = report_rows(smoke_run, PAPER.replace("CONFIG", smoke_config(tmp_path)), tmp_path)
    assert rows["collision_smoke"]["reversible"] == "yes"
    assert made == ["collision_smoke", "drop_A"]


def test_the_default_paper_file_and_a_missing_one(smoke_run, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the project's paper file, wherever revdem runs from
    runs = tmp_path / "runs"  # the smoke collision's verdict as the paper's collision's
    runs.mkdir()
    (runs / "collision.compare.json").symlink_to(smoke_run / "collision_smoke.compare.json")
    result = runner.invoke(app, ["report", str(runs), "--out", str(tmp_path / "r.md")])
    assert result.exit_code == 0, result.output
    page = (tmp_path / "r.md").read_text()
    assert "## collision_shear (§4, Figure 5)" in page
    assert '| max_position_error_rel | "the plots ... are overlapping": revdem\'s ≤ 1e-10 |' in page
    assert page.startswith(f"# {ROOT / 'scenarios/hanley2020/paper_numbers.toml'} against ")
    monkeypatch.chdir(ROOT)  # below the working folder, named from there, as `make paper` does
    result = runner.invoke(app, ["report", str(runs), "--out", str(tmp_path / "r.md"), "--force"])
    assert result.exit_code == 0, result.output
    heading = (tmp_path / "r.md").read_text().splitlines()[0]
    assert heading == f"# scenarios/hanley2020/paper_numbers.toml against the runs in {runs}"
    missing = runner.invoke(app, ["report", str(smoke_run), "--paper", str(tmp_path / "no")])
    assert missing.exit_code == 2 and "cannot read the paper's numbers" in missing.output


def test_report_shows_each_runs_figures_beside_the_page(smoke_run, tmp_path):
    import shutil

    from revdem_cli.report.figures import speed_figure

    runs = tmp_path / "runs"
    shutil.copytree(smoke_run, runs)
    speed_figure(runs / "collision_smoke.forward.h5", None, runs / "collision_smoke.speed.png")
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER)
    (tmp_path / "pages").mkdir()
    page = tmp_path / "pages" / "page.md"
    result = runner.invoke(app, ["report", str(runs), "--paper", str(paper), "--out", str(page)])
    assert result.exit_code == 0, result.output
    assert "![collision_smoke.speed](collision_smoke.speed.png)" in page.read_text()
    assert (tmp_path / "pages" / "collision_smoke.speed.png").read_bytes()[:4] == b"\x89PNG"


def test_a_folder_without_runs_and_a_file_that_is_no_papers_are_refused(smoke_run, tmp_path):
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER)
    page = tmp_path / "page.md"

    def report(directory, paper_path):
        args = ["report", str(directory), "--paper", str(paper_path), "--out", str(page)]
        return runner.invoke(app, args)

    assert_one_line_error(report(tmp_path / "none", paper), "none: no such folder of runs")
    (tmp_path / "empty").mkdir()
    no_run = "empty: no run of a case of"
    assert_one_line_error(report(tmp_path / "empty", paper), no_run, "collision_smoke, drop_A")
    scenario = ROOT / "configs" / "collision.toml"
    assert_one_line_error(report(smoke_run, scenario), "no table reports a number")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(PAPER.replace("max_shear_force = 0.066", 'max_shear_force = "big"'))
    given = "collision_smoke.max_shear_force = 'big': give a number"
    assert_one_line_error(report(smoke_run, wrong), given)
    wrong.write_text(PAPER.replace("reversible = false", "reversible = 0"))
    assert_one_line_error(report(smoke_run, wrong), "reversible = 0: give true or false")
    assert not page.exists()


def test_a_figure_shows_a_reversal_that_parts_but_not_one_that_runs_away():
    """The y limits: the forward run's range, and the reversed run's up to that range again
    beyond it. A reversal whose speeds parted from the forward run's by 17 % was cut at
    the forward run's limits; one that blew up must not flatten the forward curves."""
    from revdem_cli.report.figures import _limits

    low, high = _limits([0.0, 0.0186], [0.0, 0.0217])
    assert low == 0.0 and high > 0.0217  # speeds: the margin stops at zero
    low, high = _limits([0.0, 1.0], [-1e10, 1e10])
    assert (low, high) == pytest.approx((-1.45, 2.45))  # -1 to 2, and 15 % of 3
    assert _limits([2.0, 2.0], [2.0, 2.0]) == (1.0, 3.0)  # a constant: a unit either side


def test_a_time_figure_shows_the_forward_run_over_the_reversed_stage(tmp_path, monkeypatch):
    """A long first stage and a short reversed one: the figures against time drew the whole
    forward run, the reversal a few pixels at the right edge (a pour of 2.7 s and a reversed
    stage of 87 ms); they draw the forward run over the span of the reversal, and say so."""
    from revdem_cli import api
    from revdem_cli.report import figures

    stages = [
        {"name": "approach", "steps": 4000, "output_every": 50},
        {"name": "collide", "steps": 1000, "output_every": 50, "reverse": True},
    ]
    experiment = api.load(ROOT / "configs/smoke/collision.yaml").changed({"stages": stages})
    run = api.run(experiment, tmp_path / "run").outputs
    drawn = []
    monkeypatch.setattr(figures, "_save", lambda fig, png: drawn.append(fig) or png)
    for figure in (figures.speed_figure, figures.forces_figure):
        figure(run.forward, run.reverse, tmp_path / "f.png")
        ax = drawn[-1].axes[0]
        spans = {
            line.get_linestyle(): (min(line.get_xdata()), max(line.get_xdata()))
            for line in ax.get_lines()
            if len(line.get_xdata())
        }
        assert spans["-"] == pytest.approx(spans["--"]), spans  # forward over the reversal's
        assert spans["--"][1] - spans["--"][0] < 0.25 * spans["--"][1]
        assert ax.get_xlabel() == "time (µs), over the reversed stage"  # 500 µs in all


def test_a_time_axis_reads_in_the_unit_of_the_runs_duration(tmp_path):
    """Every time axis read in ms: the fcc test's 88 s of shear from 40 000 to 128 000 ms.
    It reads in s from 10 s of run on, in µs below 1 ms."""
    from revdem_cli import api
    from revdem_cli.report.figures import _time_unit

    experiment = api.load(ROOT / "configs/fcc_triaxial.toml").changed(
        {"stages.0.steps": 5000, "stages.1.steps": 100, "output.figures": []}
    )
    fcc = api.run(experiment, tmp_path / "fcc", reverse=False, threads=1).outputs.forward
    assert _time_unit(fcc) == (1.0, "time (s)")  # 10.2 s
    short = api.load(ROOT / "configs/collision.toml").changed({"output.figures": []})
    collision = api.run(short, tmp_path / "c", reverse=False, threads=1).outputs.forward
    assert _time_unit(collision) == (1e3, "time (ms)")  # 1.5 ms


def test_a_sphere_is_named_in_a_figure_as_in_messages(smoke_run):
    """By index and id (`state.particle_named`): a LAMMPS data file's spheres carry their
    atom ids, which the legends lacked."""
    from revdem_cli.report.figures import _each_sphere

    series = _each_sphere(lambda v: v[:, :, 2], 1e3)(smoke_run / "collision_smoke.forward.h5")
    assert [label for label, _, _ in series] == ["particle 0 (id 1)", "particle 1 (id 2)"]
    assert all(len(time) == len(values) > 1 for _, time, values in series)


def test_report_keeps_a_file_where_it_would_copy_a_figure_and_makes_its_folder(smoke_run, tmp_path):
    """`report --out ELSEWHERE/r.md` copied the runs' figures over files of the same name
    there (another run's figure), unasked; into a folder not yet made it failed, naming a
    figure's path."""
    import shutil

    from revdem_cli.report.figures import speed_figure

    runs = tmp_path / "runs"
    shutil.copytree(smoke_run, runs)
    speed_figure(runs / "collision_smoke.forward.h5", None, runs / "collision_smoke.speed.png")
    paper = tmp_path / "paper.toml"
    paper.write_text(PAPER)
    args = ["report", str(runs), "--paper", str(paper), "--out"]
    fresh = tmp_path / "new" / "deeper" / "r.md"
    assert runner.invoke(app, [*args, str(fresh)]).exit_code == 0
    assert (fresh.parent / "collision_smoke.speed.png").read_bytes()[:4] == b"\x89PNG"

    other = tmp_path / "other"
    other.mkdir()
    (other / "collision_smoke.speed.png").write_bytes(b"another run's figure")
    assert_one_line_error(
        runner.invoke(app, [*args, str(other / "r.md")]),
        f"report: {other / 'collision_smoke.speed.png'}: exists, where it would copy "
        f"{runs / 'collision_smoke.speed.png'}; use --force to overwrite",
    )
    assert (other / "collision_smoke.speed.png").read_bytes() == b"another run's figure"
    assert not (other / "r.md").exists()
    forced = runner.invoke(app, [*args, str(other / "r.md"), "--force"])
    assert forced.exit_code == 0, forced.output
    assert (other / "collision_smoke.speed.png").read_bytes()[:4] == b"\x89PNG"


def test_a_figures_axis_keeps_its_margin_on_its_side_of_zero():
    """The shear collision's largest contact forces, never negative, were drawn on an axis
    down to -0.12 N. The 15 % margin stops at zero for values of one sign; values on both
    sides, or a reversal straying off scale, keep it."""
    from revdem_cli.report.figures import _limits

    assert _limits([0.0, 0.88], [0.0, 0.87]) == (0.0, pytest.approx(1.012))
    assert _limits([-1.0, -0.2], []) == (pytest.approx(-1.12), pytest.approx(-0.08))
    assert _limits([0.2, 1.0], []) == (pytest.approx(0.08), pytest.approx(1.12))
    assert _limits([-0.5, 0.5], []) == (pytest.approx(-0.65), pytest.approx(0.65))
    assert _limits([0.0, 0.0], []) == (0.0, 1.0)
