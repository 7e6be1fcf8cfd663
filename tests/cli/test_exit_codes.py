"""Exit status: 0 ok, 2 bad input, 1 when a run fails otherwise; bugs keep their traceback."""

import pytest
from typer.testing import CliRunner

from revdem_cli import engine
from revdem_cli.cli import app
from tests.conftest import CONFIGS

runner = CliRunner()
SMOKE = str(CONFIGS / "smoke" / "collision.yaml")


def test_a_run_that_cannot_write_its_output_exits_1_with_one_line(tmp_path):
    taken = tmp_path / "a_file"
    taken.write_text("")
    result = runner.invoke(app, ["run", SMOKE, "--out", str(taken), "-q"])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("failed: FileExistsError"), result.output


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


def test_shell_completion_is_offered():
    assert "--install-completion" in runner.invoke(app, ["--help"]).output
