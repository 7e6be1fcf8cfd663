"""compare.json's divergence causes: the particles they name."""

import numpy as np
import pytest

from revdem_cli.compare import _cause
from revdem_cli.kernels.events import AMOUNT, COLUMNS, COUNT, KINDS, LAST, PARTICLE, PARTNER


def test_a_cause_names_each_sphere_by_index_and_id_and_a_wall_by_name():
    """The event log holds indices in the arrays; a cause gives each sphere's id too (a data
    file's atom id), and a wall's name for a partner -1 - w."""
    entry = np.zeros(len(COLUMNS))
    entry[COUNT], entry[LAST], entry[AMOUNT] = 3, 120, 0.004
    entry[PARTICLE], entry[PARTNER] = 2, 0
    ids = np.array([40, 7, 13])
    cause = _cause(KINDS.index("coulomb_slip"), entry, ["bottom", "lid"], ids, "")
    assert (cause["particle"], cause["partner"]) == (2, 0)
    assert (cause["particle_id"], cause["partner_id"]) == (13, 40)
    assert cause["message"].startswith(
        "the contact of particle 2 (id 13) and particle 0 (id 40) slid at step 120: the Coulomb "
        "limit removed 4 mN"
    )
    entry[PARTNER] = -2  # wall 1
    cause = _cause(KINDS.index("coulomb_slip"), entry, ["bottom", "lid"], ids, "")
    assert (cause["partner"], cause["partner_id"], cause["partner_wall"]) == (-2, None, "lid")
    assert cause["message"].startswith("the contact of particle 2 (id 13) and wall lid slid")


def test_a_force_in_a_cause_reads_in_the_prefix_of_its_size():
    """A slip in the fcc test, 7.73e+06 mN; a pair's, 0.0006 mN: each in its prefix."""
    from revdem_cli.compare import _newtons

    said = [_newtons(f) for f in (7.73e3, 27.5, 0.0353, 6e-7, 0.0)]
    assert said == ["7.73 kN", "27.5 N", "35.3 mN", "600 nN", "0 N"]


def test_a_cause_of_the_whole_run_names_no_particle_and_keeps_the_keys_of_a_mechanism():
    """Drag's amplification of round-off (Hanley 2020 Eq 28) and a time step above its limit
    act at every step back from the restart, at no particle: the keys of a mechanism's cause,
    in its order, each particle field null, the amount its growth or its ratio."""
    import math

    from revdem_cli.compare import _drag_amplification, _unstable_time_step
    from revdem_cli.timestep.guard import Excess

    entry = np.zeros(len(COLUMNS))
    entry[COUNT], entry[LAST], entry[PARTICLE], entry[PARTNER] = 1, 10, 0, 1
    keys = list(_cause(KINDS.index("coulomb_slip"), entry, [], np.array([1, 2]), ""))
    drag = _drag_amplification(0.99, 1000, 400)
    assert list(drag) == keys and drag["mechanism"] == "drag_amplifies_round_off"
    assert drag["amount"] == 600 * -math.log(0.99) and drag["occurrences"] == 600
    assert all(drag[k] is None for k in ("particle", "partner", "particle_id", "partner_id"))
    said = "no mechanism destroyed information here, but the reversed run divides velocities"
    assert drag["message"].startswith(f"{said} by gamma_d = 0.99 each step (Eq 28)")
    excess = Excess("integrator.dt", 6e-4, "critical time step", 3.86e-4, "Hertz contact")
    unstable = _unstable_time_step(excess, 1000, 400)
    assert list(unstable) == keys and unstable["amount"] == 6e-4 / 3.86e-4
    assert "1.55 times the critical time step" in unstable["message"]


def test_a_drop_held_at_its_terminal_velocity_is_blamed_on_the_drag_maps_fixed_point(tmp_path):
    """Drop A's sphere with gamma_d = 0.999, 60 000 steps in the air: it reaches the terminal
    velocity gamma_d g dt / (1 - gamma_d) by step 30 173 and the reversal, held there, climbs back
    to rest never, parting only at step 0. The causes looked between step 0 and the next
    frame, found nothing and blamed drag's amplification of round-off; the fixed point,
    logged from step 30 173, is named."""
    from revdem_cli import api as revdem
    from tests.conftest import CONFIGS

    experiment = revdem.load(CONFIGS / "drop_A.toml").changed(
        {"damping.drag": 0.999, "stages.0.steps": 60000, "stages.0.output_every": 5000}
    )
    verdict = revdem.run(experiment, tmp_path, threads=1).comparison
    assert verdict["first_divergence_step"] == 0
    (cause,) = verdict["divergence_causes"]
    assert cause["mechanism"] == "velocity_fixed_point_under_drag"
    # v = gamma (v + g dt) at the fixed point (Eq 25): gamma g dt / (1 - gamma)
    assert cause["amount"] == pytest.approx(0.999 * 9.81 * 1e-8 / 1e-3, rel=1e-6)


@pytest.mark.parametrize(
    ("reverse", "pairs"),
    [
        ([400, 300, 200], [(4, 0), (3, 1), (2, 2)]),  # back to the shear stage's own start
        ([400, 300, 200, 200, 100], [(4, 0), (3, 1), (2, 2), (1, 3), (0, 4)]),  # every stage
        ([200, 100], [(1, 0), (0, 1)]),  # from the preparation's restart: its end
    ],
    ids=["to the stage's start", "every stage", "from the stage before"],
)
def test_a_reversed_row_pairs_with_the_forward_row_of_its_state(reverse, pairs):
    """A forward run whose shear stage began at step 200 with its own row beside the
    preparation's end (rows 1 and 2): a reversal that stops at the stage's start pairs its
    last row with the stage's own; one of every stage writes both, in the other order; one
    from the preparation's restart starts from its end."""
    from revdem_cli.compare import paired_rows

    forward = np.array([100, 200, 200, 300, 400])
    assert sorted(paired_rows(forward, np.array(reverse))) == sorted(pairs)


def test_the_rows_of_a_stage_leave_out_the_end_of_the_stage_before():
    """From a stage's first step on, its own row there and not the end of the stage before
    written beside it: the second of the two going forward, the first going back."""
    from revdem_cli.io.h5md import from_stage_start

    forward, back = np.array([100, 200, 200, 300]), np.array([300, 200, 200, 100])
    assert from_stage_start(forward, 200).tolist() == [False, False, True, True]
    assert from_stage_start(back, 200, reverse=True).tolist() == [True, True, False, False]
    assert from_stage_start(forward, 300).tolist() == [False, False, False, True]
