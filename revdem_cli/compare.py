"""Forward against reversed trajectories: frames aligned by step, error metrics, verdict."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from revdem_cli.config import Reversal, Scenario
from revdem_cli.errors import InputError
from revdem_cli.io.h5md import frame_steps, open_trajectory, read_frame


def _max_norm(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((a - b) ** 2).sum(axis=1)).max()) if len(a) else 0.0


def tolerances_of(trajectory) -> Reversal:
    """The reversal tolerances of the scenario a trajectory was run from."""
    text = trajectory["parameters/revdem"].attrs.get("scenario_json")
    return Scenario.model_validate_json(text).reversal if text else Reversal()


def compare_trajectories(first: str | Path, second: str | Path, tolerance: Reversal | None = None):
    """Compare two trajectories frame by frame at their common steps.

    `first_divergence_step` is the first step, in the order the second run went through
    them, at which an error exceeds its tolerance (None if none does).
    """
    with open_trajectory(first) as a, open_trajectory(second) as b:
        tolerance = tolerance or tolerances_of(a)
        steps_a, steps_b = frame_steps(a), frame_steps(b)
        common, index_a, index_b = np.intersect1d(steps_a, steps_b, return_indices=True)
        if len(common) == 0:
            raise InputError(f"{first} and {second} have no frame at a common step")
        radius = a["particles/all/radius"][:]
        if len(radius) != len(b["particles/all/radius"]):
            raise InputError(f"{first} and {second} hold different numbers of particles")
        diameter = 2.0 * float(radius.min())
        order = np.argsort(common)
        if b["parameters/revdem"].attrs.get("direction") == "reverse":
            order = order[::-1]
        rows = []
        identical = True
        for k in order:
            errors = []
            for field in ("position", "velocity", "angular_velocity"):
                va = read_frame(a, field, index_a[k])
                vb = read_frame(b, field, index_b[k])
                identical &= bool(np.array_equal(va, vb))
                errors.append(_max_norm(va, vb))
            rows.append((int(common[k]), errors[0] / diameter, errors[0], errors[1], errors[2]))
    table = np.array([r[1:] for r in rows])
    limits = np.array(
        [
            tolerance.position_tolerance_rel,
            np.inf,
            tolerance.velocity_tolerance,
            tolerance.angular_velocity_tolerance,
        ]
    )
    exceeded = (table > limits).any(axis=1)
    first_divergence = int(rows[int(np.argmax(exceeded))][0]) if exceeded.any() else None
    return {
        "frames_compared": len(rows),
        "max_position_error": float(table[:, 1].max()),
        "max_position_error_rel": float(table[:, 0].max()),
        "max_velocity_error": float(table[:, 2].max()),
        "max_angular_velocity_error": float(table[:, 3].max()),
        "first_divergence_step": first_divergence,
        "bitwise_identical": identical,
        "reversible": first_divergence is None,
        "tolerance": tolerance.model_dump(),
        "smallest_diameter": diameter,
        "frames": {
            "step": [r[0] for r in rows],
            "position_error_rel": table[:, 0].tolist(),
            "velocity_error": table[:, 2].tolist(),
        },
    }
