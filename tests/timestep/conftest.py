"""The paper's numbers (scenarios/peng2020) for the critical time step tests."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "peng2020"


@pytest.fixture(scope="session")
def paper() -> dict:
    return tomllib.loads((SCENARIO / "paper_numbers.toml").read_text())
