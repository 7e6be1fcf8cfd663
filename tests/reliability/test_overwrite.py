"""No overwrites by accident: `revdem run` and `revdem reverse` keep the outputs of an earlier
run (trajectories, restart, comparison, figures) unless --force, and say so in one line before
doing any work."""

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS, assert_one_line_error

runner = CliRunner()
SMOKE = CONFIGS / "smoke" / "collision.yaml"
SHORT = ["--set", "stages.0.steps=200", "-q"]
NAME = "collision_smoke"
OUTPUTS = ("forward.h5", "restart.h5", "reverse.h5", "compare.json")


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def snapshot(folder: Path) -> dict[str, tuple[int, bytes]]:
    """Every file in `folder`: its modification time (ns) and contents."""
    return {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """The outputs of an earlier run of the YAML collision, 200 steps each way."""
    out = tmp_path_factory.mktemp("earlier")
    result = invoke("run", SMOKE, "--out", out, *SHORT)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == sorted(f"{NAME}.{o}" for o in OUTPUTS)
    return out


@pytest.fixture
def out(earlier, tmp_path) -> Path:
    """A copy of the earlier run's folder."""
    return Path(shutil.copytree(earlier, tmp_path / "out"))


def test_a_second_run_into_the_same_folder_is_refused_and_keeps_the_files(out):
    before = snapshot(out)
    result = invoke("run", SMOKE, "--out", out, *SHORT)
    assert_one_line_error(
        result,
        f"error: {out / NAME}.forward.h5: exists (and 3 more outputs of the earlier run); "
        "use --force to overwrite",
    )
    assert snapshot(out) == before


def test_force_overwrites(out):
    before = snapshot(out)
    result = invoke(
        "run", SMOKE, "--out", out, *SHORT, "--set", "stages.0.output_every=100", "--force"
    )
    assert result.exit_code == 0, result.output
    after = snapshot(out)
    assert after.keys() == before.keys()
    assert all(after[name][0] > before[name][0] for name in before)
    assert after[f"{NAME}.forward.h5"][1] != before[f"{NAME}.forward.h5"][1]


def test_a_forced_run_keeps_the_exports_of_the_run_it_replaces_and_lists_each(out):
    """`run --force` replaced the trajectories and left their exports beside them without a
    word, carrying the run's name while showing the run replaced. A run writes no export,
    so they are kept, and its summary lists each one to export again."""
    forward, reverse = (out / f"{NAME}.{kind}.h5" for kind in ("forward", "reverse"))
    for trajectory, fmt in ((forward, "lammps-dump"), (forward, "vtk"), (reverse, "gsd")):
        assert invoke("export", trajectory, "--format", fmt, "-q").exit_code == 0
    exports = [
        out / f"{NAME}.forward.vtk",
        out / f"{NAME}.forward.dump",
        out / f"{NAME}.reverse.gsd",
    ]
    result = invoke("run", SMOKE, "--out", out, *SHORT, "--force")
    assert result.exit_code == 0, result.output
    stale = [line.split(None, 2)[2] for line in result.output.splitlines() if "stale" in line]
    said = "(made before this run wrote its trajectory; export again)"
    assert stale == [f"{path} {said}" for path in exports]
    assert all(path.exists() for path in exports)

    gsd = out / f"{NAME}.reverse.gsd"  # a reversal alone replaces the reversed trajectory
    reversed_again = invoke("reverse", out / f"{NAME}.restart.h5", "-q", "--force")
    assert reversed_again.exit_code == 0, reversed_again.output
    stale = [
        line.split(None, 2)[2] for line in reversed_again.output.splitlines() if "stale" in line
    ]
    assert stale == [f"{gsd} {said}"]


@pytest.mark.parametrize("kept", OUTPUTS)
def test_any_one_output_left_is_kept(out, kept):
    for name in OUTPUTS:
        if name != kept:
            (out / f"{NAME}.{name}").unlink()
    result = invoke("run", SMOKE, "--out", out, *SHORT)
    assert_one_line_error(result, f"error: {out / NAME}.{kept}: exists; use --force")


def test_an_earlier_reversal_counts_though_this_run_writes_none(out):
    """Forward only, a run writes no reversed trajectory and no comparison. It let an earlier
    run's stay, and `revdem info` of the new trajectory then showed their verdict as its
    own; with --force too, which removed only what the new run writes. Now any output of an
    earlier run of the name is refused, and removed by --force."""
    (out / f"{NAME}.forward.h5").unlink()
    (out / f"{NAME}.restart.h5").unlink()
    before = snapshot(out)
    refused = invoke("run", SMOKE, "--out", out, *SHORT, "--no-reverse")
    assert_one_line_error(refused, f"{out / NAME}.reverse.h5: exists (and 1 more output")
    assert snapshot(out) == before
    result = invoke("run", SMOKE, "--out", out, *SHORT, "--no-reverse", "--force")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [f"{NAME}.forward.h5", f"{NAME}.restart.h5"]
    shown = invoke("info", out / f"{NAME}.forward.h5")
    assert shown.exit_code == 0 and "reversible" not in shown.output, shown.output


def test_a_figure_is_kept(tmp_path):
    scenario = tmp_path / "speed.yaml"
    scenario.write_text(SMOKE.read_text() + "output: {figures: [speed]}\n")
    figure = tmp_path / "out" / f"{NAME}.speed.png"
    figure.parent.mkdir()
    figure.write_bytes(b"a figure kept from before")
    result = invoke("run", scenario, "--out", tmp_path / "out", *SHORT)
    assert_one_line_error(result, f"error: {figure}: exists; use --force to overwrite")
    assert figure.read_bytes() == b"a figure kept from before"
    assert [p.name for p in figure.parent.iterdir()] == [figure.name]


def test_a_time_step_study_keeps_its_figures(tmp_path):
    study = tmp_path / "study.toml"
    study.write_text('kind = "critical_time_step"\nname = "tiny"\nfigures = [3]\n')
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "tiny.figure3.csv").write_text("kept\n")
    result = invoke("run", study, "--out", tmp_path / "out")
    assert_one_line_error(result, f"error: {tmp_path / 'out' / 'tiny.figure3.csv'}: exists")


def test_a_second_reversal_is_refused_unless_forced(out):
    restart = out / f"{NAME}.restart.h5"
    before = snapshot(out)
    result = invoke("reverse", restart, "-q", "--steps", "100")
    assert_one_line_error(
        result,
        f"error: {out / NAME}.reverse.h5: exists (and 1 more output of the earlier reversal); "
        "use --force",
    )
    assert snapshot(out) == before
    forced = invoke("reverse", restart, "-q", "--steps", "100", "--force")
    assert forced.exit_code == 0, forced.output
    after = snapshot(out)
    assert after[f"{NAME}.reverse.h5"] != before[f"{NAME}.reverse.h5"]
    assert after[f"{NAME}.forward.h5"] == before[f"{NAME}.forward.h5"]


def test_a_second_reversal_counts_the_figures_it_would_replace(tmp_path):
    """A reversal over an earlier one replaces its comparison and its figures: the refusal
    said "(and 1 more output ...)", the figures left uncounted."""
    scenario = tmp_path / "speed.yaml"
    scenario.write_text(SMOKE.read_text() + "output: {figures: [speed]}\n")
    out = tmp_path / "out"
    assert invoke("run", scenario, "--out", out, *SHORT).exit_code == 0
    before = snapshot(out)
    result = invoke("reverse", out / f"{NAME}.restart.h5", "-q")
    assert_one_line_error(
        result,
        f"error: {out / NAME}.reverse.h5: exists (and 2 more outputs of the earlier reversal); "
        "use --force",
    )
    assert snapshot(out) == before


def test_a_reversal_into_another_folder_needs_no_force(out, tmp_path):
    result = invoke("reverse", out / f"{NAME}.restart.h5", "--out", tmp_path / "again", "-q")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "again" / f"{NAME}.compare.json").exists()


def test_a_run_forward_only_is_reversed_without_force(tmp_path):
    """`run --no-reverse`, then `reverse`: the forward run's figures are drawn again with the
    reversed run beside them (the reversal refused to start over them)."""
    scenario = tmp_path / "speed.yaml"
    scenario.write_text(SMOKE.read_text() + "output: {figures: [speed]}\n")
    out = tmp_path / "out"
    assert invoke("run", scenario, "--out", out, *SHORT, "--no-reverse").exit_code == 0
    figure = out / f"{NAME}.speed.png"
    drawn = figure.stat().st_mtime_ns
    result = invoke("reverse", out / f"{NAME}.restart.h5", "-q")
    assert result.exit_code == 0, result.output
    assert (out / f"{NAME}.compare.json").exists() and figure.stat().st_mtime_ns > drawn


@pytest.mark.parametrize(
    "command",
    [
        ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "2500",
         "--sweep", "kn=1e5:1e7:3"],
        ["report"],
    ],
    ids=["dt --sweep", "report"],
)  # fmt: skip
def test_a_table_or_page_named_by_out_keeps_a_run_and_any_file_without_force(out, command):
    """`revdem dt --sweep --out` wrote its CSV over a trajectory it was pointed at, and
    `revdem report --out` its page over any file. A run's HDF5 file is never written over;
    another existing file only with --force; an --out that is a folder is refused."""
    args = [*command, *([str(out)] if command == ["report"] else [])]
    forward, verdict = out / f"{NAME}.forward.h5", out / f"{NAME}.compare.json"
    kept = snapshot(out)
    assert_one_line_error(invoke(*args, "--out", forward, "--force"), f"--out {forward}: HDF5")
    assert_one_line_error(invoke(*args, "--out", verdict), f"--out {verdict}: exists; use --force")
    assert_one_line_error(invoke(*args, "--out", out), f"--out {out}: a folder")
    assert snapshot(out) == kept
    (out / "collision.compare.json").symlink_to(verdict)  # a case of the paper, for report
    mine = out.parent / f"{command[0]}-table.txt"
    mine.write_text("mine\n")
    forced = invoke(*args, "--out", mine, "--force")
    assert forced.exit_code == 0, forced.output
    assert mine.read_text() != "mine\n"


@pytest.mark.parametrize(
    "command",
    [
        ["dt", "--shape", "sphere", "--radius", "0.01", "--density", "2500",
         "--sweep", "kn=1e5:1e7:3"],
        ["report"],
        ["export", "--format", "gsd"],
        ["export", "--format", "lammps-dump"],
        ["export", "--format", "lammps-data"],
    ],
    ids=["dt --sweep", "report", "export gsd", "export lammps-dump", "export lammps-data"],
)  # fmt: skip
def test_an_out_ending_in_a_separator_names_a_folder_not_a_file(out, command):
    """`export --out slashdir/` wrote a file named slashdir where no such folder was: a
    path ending in / names a folder, refused where a file is wanted as one that exists is."""
    argument = {"report": [out], "export": [out / f"{NAME}.forward.h5"]}.get(command[0], [])
    kept = snapshot(out)
    folder = f"{out / 'new'}/"
    result = invoke(*command[:1], *argument, *command[1:], "--out", folder)
    assert_one_line_error(result, f"{command[0]}: --out {folder}: a folder; name a file")
    assert snapshot(out) == kept
