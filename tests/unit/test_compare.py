"""compare.json's divergence causes: the particles they name."""

import numpy as np

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
