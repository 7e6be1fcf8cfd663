"""Exit status: 0 ok, 2 bad input, 1 when a run fails otherwise; bugs keep their traceback."""

import errno

import pytest
from typer.testing import CliRunner

from revdem_cli import engine
from revdem_cli.cli import app
from tests.conftest import CONFIGS

runner = CliRunner()
SMOKE = str(CONFIGS / "smoke" / "collision.yaml")


@pytest.mark.parametrize(
    ("error", "status", "line"),
    [
        (OSError(errno.EIO, "Input/output error", "out/x.h5"), 1, "failed: OSError: "),
        (OSError(errno.EISDIR, "Is a directory", "out/x.h5"), 2, "error: out/x.h5: a folder"),
        (OSError(errno.ENOSPC, "No space left on device"), 1, "failed: OSError: "),
    ],
    ids=["machine", "path", "no-path"],
)
def test_a_file_system_error_is_one_line_bad_input_only_where_a_path_given_is(
    tmp_path, monkeypatch, error, status, line
):
    """An OSError the machine made exits 1; one about a path the user gave that cannot be
    used (`errors.path_problem`) exits 2, as bad input."""

    def failing(*args, **kwargs):
        raise error

    monkeypatch.setattr(engine, "run_scenario", failing)
    result = runner.invoke(app, ["run", SMOKE, "--out", str(tmp_path), "-q"])
    assert result.exit_code == status
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(line), result.output


def test_a_programming_error_is_not_turned_into_a_message(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise TypeError("a bug")

    monkeypatch.setattr(engine, "run_scenario", broken)
    result = runner.invoke(app, ["run", SMOKE, "--out", str(tmp_path), "-q"])
    assert isinstance(result.exception, TypeError)
    assert "failed:" not in result.output


@pytest.mark.parametrize(
    "command",
    ["run", "reverse", "compare", "validate", "schema", "info", "export", "sweep", "report", "dt"],
)
def test_every_command_shows_an_example(command):
    result = runner.invoke(app, [command, "--help"], terminal_width=200)
    assert result.exit_code == 0
    assert f"Example: revdem {command}" in result.output
    assert "[]" not in result.output  # no [bracketed] word taken for rich markup and dropped
    # each paragraph one line, which the help wraps at the terminal's width: it broke
    # lines where the docstring's source lines end ("hold each / variant's values")
    (help_text,) = (c.help for c in app.registered_commands
                    if (c.name or c.callback.__name__) == command)  # fmt: skip
    assert all("\n" not in paragraph for paragraph in help_text.split("\n\n"))


def test_shell_completion_is_offered():
    assert "--install-completion" in runner.invoke(app, ["--help"]).output


def test_output_cut_short_by_its_reader_ends_without_a_word():
    """`revdem dt --sweep ... | head`: the reader closes the pipe after a few lines; the
    command stops with status 1 (as click's --help does) and nothing on stderr, where it
    printed "failed: BrokenPipeError"."""
    import subprocess
    import sys

    sweep = ["dt", "--shape", "sphere", "--radius", "1", "--density", "1000"]
    command = [sys.executable, "-m", "revdem_cli.cli", *sweep, "--sweep", "kn=1e6:1e9:5000"]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert child.stdout.readline().startswith(b"kn")  # the CSV's header
    child.stdout.close()
    assert child.stderr.read() == b"" and child.wait(timeout=120) == 1
