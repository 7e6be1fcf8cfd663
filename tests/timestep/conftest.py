"""The paper's numbers and the committed figure data (scenarios/peng2020)."""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "peng2020"


@pytest.fixture(scope="session")
def paper() -> dict:
    return tomllib.loads((SCENARIO / "paper_numbers.toml").read_text())


@pytest.fixture(scope="session")
def committed():
    """Columns of a committed figure CSV by name; empty cells are NaN."""

    def read(name: str) -> dict[str, np.ndarray]:
        with open(SCENARIO / f"{name}.csv") as stream:
            rows = list(csv.DictReader(stream))
        return {key: np.array([float(r[key] or "nan") for r in rows]) for key in rows[0]}

    return read
