"""The contact list a trajectory keeps ([output] contacts): Coulomb's law in the sliding
flags of a frictional collision, the pair loop's own geometry, and the rows a continued run
copies from its checkpoint."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from revdem_cli.cli import app
from revdem_cli.config import Scenario
from revdem_cli.contacts import contact_list, touching_pairs
from revdem_cli.engine import _writer
from revdem_cli.io.h5md import read_contacts
from revdem_cli.stage import Model
from revdem_cli.state import empty_events, initial_state
from tests.conftest import CONFIGS, periodic_fcc, stepped, two_spheres

MU = 0.3


def test_a_contact_slides_where_coulomb_caps_its_shear_force(tmp_path):
    """The shear collision with μ = 0.3 (Hanley 2020 §5.1), a frame every 10 steps: where a
    contact is flagged sliding its shear force is μ times its normal force (Eq 10 capped);
    elsewhere below it. Both happen in this collision."""
    sets = [f"contact.friction={MU}", "stages.0.output_every=10", "output.contacts=true"]
    args = ["run", str(CONFIGS / "collision_shear.toml"), "--out", str(tmp_path), "-q"]
    args += ["--no-reverse", *(part for item in sets for part in ("--set", item))]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    ratios, slid = [], []
    with h5py.File(tmp_path / "collision_shear.forward.h5", "r") as f:
        for frame in range(len(f["particles/all/position/step"])):
            contacts = read_contacts(f, frame)
            normal = np.linalg.norm(contacts["normal_force"], axis=1)
            shear = np.linalg.norm(contacts["tangential_force"], axis=1)
            ratios += list(shear / normal)
            slid += list(contacts["sliding"])
    ratios, slid = np.array(ratios), np.array(slid, dtype=bool)
    assert slid.sum() > 5 and (~slid).sum() > 5, (slid.sum(), (~slid).sum())
    np.testing.assert_allclose(ratios[slid], MU, rtol=1e-12)
    assert (ratios[~slid] <= MU * (1 + 1e-12)).all()


def test_the_contacts_of_a_state_are_those_the_pair_loop_found_to_the_bit():
    """A periodic fcc lattice 1e-4 of its spacing apart, shaken at 0.05 m/s for 200 steps
    in fixed point with friction, whose pair loop keeps every pair's overlap and contact
    normal (zero apart): the contacts of its state (`touching_pairs`, read by the contact
    list and `revdem dt --restart`) are exactly the pairs the pair loop found touching,
    with its normals and overlaps, bit for bit."""
    spacing = 1.0001 * 0.01 * 2**0.5
    scenario = Scenario.model_validate(
        {
            "name": "shaken",
            **periodic_fcc(3, spacing, random_velocity=0.05, seed=7),
            "integrator": {"dt": 1e-6, "arithmetic": "fixed"},
            "stages": [{"name": "shake", "steps": 200, "output_every": 200}],
        }
    )
    *_, state = stepped(scenario, 200, 200)
    pairs = state.pairs
    count = int(pairs.count[0])
    touching = touching_pairs(state)
    assert 0 < len(touching.slot) < count  # pairs in contact and pairs apart
    np.testing.assert_array_equal(touching.slot, np.flatnonzero(pairs.overlap[:count] > 0.0))
    assert np.array_equal(touching.normal, pairs.normal[touching.slot])
    assert np.array_equal(touching.overlap, pairs.overlap[touching.slot])


def _touching_pair():
    """The model and initial state of two spheres in contact, writing their contacts."""
    sphere = {"material": "sphere", "radius": 0.005}
    touching = [{**sphere, "position": [0, 0, 0]}, {**sphere, "position": [0.0099, 0, 0]}]
    scenario = two_spheres(output={"contacts": True}, particles=touching)
    return Model.of(scenario), initial_state(scenario)


def test_a_continued_trajectory_copies_the_contacts_of_its_frames(tmp_path):
    """A run continued from a checkpoint copies the first frames of its trajectory: their
    contacts are the same rows, and the contacts of later frames are left behind."""
    model, state = _touching_pair()
    source = _writer(tmp_path / "a.h5", state, model, "", "forward")
    for step in range(3):
        state.particles.f[0, 0] = step  # frames that differ
        contacts = contact_list(state)
        assert len(contacts) == 1
        source.frame(step, float(step), state.particles, empty_events(), contacts=contacts)
    source.close()
    copy = _writer(tmp_path / "b.h5", state, model, "", "forward")
    with h5py.File(tmp_path / "a.h5", "r") as f:
        copy.copy_rows(f, 2, 0)
        expected = [read_contacts(f, k) for k in range(2)]
    copy.close()
    with h5py.File(tmp_path / "b.h5", "r") as f:
        assert len(f["connectivity/contacts/count"]) == 2
        assert len(f["connectivity/contacts/value"]) == 2
        for k in range(2):
            got = read_contacts(f, k)
            for name, values in expected[k].items():
                np.testing.assert_array_equal(got[name], values)


def test_a_contact_list_shorter_than_its_counts_is_damage(tmp_path):
    """A trajectory whose contact rows fall short of what its frames count is refused in one
    line naming the dataset, as any other damaged trajectory."""
    from revdem_cli.errors import InputError
    from revdem_cli.io.h5md import open_trajectory

    model, state = _touching_pair()
    writer = _writer(tmp_path / "t.h5", state, model, "", "forward")
    for step in range(2):
        writer.frame(
            step, float(step), state.particles, empty_events(), contacts=contact_list(state)
        )
    writer.close()
    open_trajectory(tmp_path / "t.h5").close()  # whole, it opens
    with h5py.File(tmp_path / "t.h5", "r+") as f:
        f["connectivity/contacts/normal_force"].resize(1, axis=0)
    with pytest.raises(InputError, match="contacts/normal_force is shorter than the 2 contacts"):
        open_trajectory(tmp_path / "t.h5")
