"""Counts of the generated inputs the reliability tests tried, shown after the test run."""

import pytest

TRIED = pytest.StashKey[dict]()


@pytest.fixture(scope="session")
def tried(request) -> dict:
    """{what: how many} generated inputs a test tried; summed up after the run."""
    return request.config.stash.setdefault(TRIED, {})


def pytest_terminal_summary(terminalreporter, config):
    counts = config.stash.get(TRIED, {})
    if counts:
        detail = ", ".join(f"{what} {n}" for what, n in sorted(counts.items()))
        terminalreporter.write_sep(
            "-", f"reliability: {sum(counts.values())} generated bad inputs tried ({detail})"
        )
