"""A short run of the YAML collision through `revdem run`, shared by the tests of its files."""

import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from tests.conftest import CONFIGS


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
    """configs/smoke/collision.yaml shortened to 1000 steps each way; its output directory."""
    out = tmp_path_factory.mktemp("smoke")
    args = ["run", str(CONFIGS / "smoke" / "collision.yaml"), "--out", str(out), "-q"]
    result = CliRunner().invoke(app, [*args, "--set", "stages.0.steps=1000"])
    assert result.exit_code == 0, result.output
    return out
