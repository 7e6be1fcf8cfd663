import numpy as np
import pytest
from scipy.spatial import cKDTree

from revdem_cli.config import scenario_from_text
from revdem_cli.errors import InputError

OEDOMETER_FILL = """
name = "fill"
[materials.sphere]
density = 1000.0
shear_modulus = 2.0e6
poisson_ratio = 0.2
[contact]
model = "hertz"
[[packings]]
count = 900
material = "sphere"
radius_min = 0.0045
radius_max = 0.0055
seed = 3
region = {shape = "cylinder", origin = [0.0, 0.0, 0.0], radius = 0.1, height = 0.2}
[integrator]
dt = 5e-8
[[stages]]
name = "none"
steps = 1
"""


def spheres(text=OEDOMETER_FILL):
    scenario = scenario_from_text(text, ".toml", "fill.toml")
    x = scenario.spheres.position
    r = scenario.spheres.radius
    return x, r


def test_the_papers_oedometer_fill_has_no_overlap_and_stays_in_the_cylinder():
    x, r = spheres()  # Hanley 2020 §3.2.2: 900 spheres, diameters U(9, 11) mm, R = 0.1 m
    assert len(r) == 900
    assert 0.0045 <= r.min() and r.max() <= 0.0055 and r.std() > 0.0002
    for i, j in cKDTree(x).query_pairs(0.011):
        assert np.linalg.norm(x[i] - x[j]) >= r[i] + r[j]
    assert (np.hypot(x[:, 0], x[:, 1]) + r <= 0.1).all()
    assert (x[:, 2] - r >= 0).all() and (x[:, 2] + r <= 0.2).all()


def test_a_seed_gives_the_same_packing_and_another_seed_another():
    first, second = spheres()[0], spheres()[0]
    np.testing.assert_array_equal(first, second)
    other = spheres(OEDOMETER_FILL.replace("seed = 3", "seed = 4"))[0]
    assert not np.array_equal(first, other)


def test_a_region_too_small_is_refused_with_one_line():
    text = OEDOMETER_FILL.replace("radius = 0.1, height = 0.2", "radius = 0.02, height = 0.02")
    with pytest.raises(InputError, match=r"fill.toml: packings\[0\]: sphere \d+ of 900 found no"):
        spheres(text)


def test_a_packing_is_numbered_in_space_so_that_partners_lie_near_in_memory():
    x, r = spheres()  # placed at random, numbered cell by cell (`spatial_order`)
    width = 2.0 * r.max()
    slowest = int(np.argmax(np.ptp(x, axis=0)))
    plane = np.floor((x[:, slowest] - x[:, slowest].min()) / width).astype(int)
    assert np.all(np.diff(plane) >= 0)  # the longest axis's planes of cells one after another
    per_plane = np.bincount(plane)
    three_planes = int((per_plane[:-2] + per_plane[1:-1] + per_plane[2:]).max())
    near = cKDTree(x).query_pairs(2.0 * width)  # at most two planes of cells apart
    assert len(near) > len(r)  # more than one a sphere, though the packing is loose
    assert max(abs(i - j) for i, j in near) < three_planes < len(r) / 4
    rank = np.argsort(np.random.default_rng(0).permutation(len(r)))  # a random order
    assert max(abs(rank[i] - rank[j]) for i, j in near) > len(r) / 2


def test_joined_tables_keep_their_ids_each_after_the_largest_before_it():
    """`Spheres.join`: a generated table numbered from 1, then a data file's atoms with ids
    of their own, then another table: every id once, the file's ids shifted by the largest
    before them, so that one table alone keeps its ids as they are; `table_id` gives each
    sphere its table's own id back."""
    from dataclasses import replace

    from revdem_cli.assembly.spheres import Spheres, uniform

    def table(count):
        return uniform(count, 0.001, 0, ("m",), np.zeros((count, 3)), np.zeros(3))

    file_atoms = replace(table(3), id=np.array([7, 2, 40]))
    joined = Spheres.join([table(2), table(0), file_atoms, table(2)], ("m",))
    assert list(joined.id) == [1, 2, 9, 4, 42, 43, 44]
    assert Spheres.join([table(0), file_atoms], ("m",)).id is file_atoms.id
    assert [joined.table_id(k, 2) for k in (2, 3, 4)] == [7, 2, 40]  # the file's own ids
    assert [joined.table_id(k, 5) for k in (5, 6)] == [1, 2]
