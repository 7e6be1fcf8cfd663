"""Counts of what the reliability tests tried: generated bad inputs, and runs killed or
stopped by a signal and resumed; shown after the test run."""

import pytest

TRIED = pytest.StashKey[dict]()
KILLED = pytest.StashKey[dict]()


@pytest.fixture(scope="session")
def tried(request) -> dict:
    """{what: how many} generated inputs a test tried; summed up after the run."""
    return request.config.stash.setdefault(TRIED, {})


@pytest.fixture(scope="session")
def kills(request) -> dict:
    """{case: how many} runs stopped and resumed to the uninterrupted files."""
    return request.config.stash.setdefault(KILLED, {})


def pytest_terminal_summary(terminalreporter, config):
    for key, what in (
        (TRIED, "generated bad inputs tried"),
        (
            KILLED,
            "runs stopped (SIGKILL at random moments, SIGINT, SIGTERM) and resumed, "
            "each to the uninterrupted run's files",
        ),
    ):
        counts = config.stash.get(key, {})
        if counts:
            detail = ", ".join(f"{name} {n}" for name, n in sorted(counts.items()))
            terminalreporter.write_sep(
                "-", f"reliability: {sum(counts.values())} {what} ({detail})"
            )
