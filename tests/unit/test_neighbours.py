import numpy as np

from revdem_cli.kernels.neighbours import build_pairs, carry_history, index_by_particle


def brute_force_pairs(x, radius, skin):
    n = len(x)
    return [
        (i, j)
        for i in range(n)
        for j in range(i + 1, n)
        if np.linalg.norm(x[j] - x[i]) < radius[i] + radius[j] + skin
    ]


def random_packing(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 0.05, (n, 3)), rng.uniform(0.004, 0.006, n)


def test_cell_list_pairs_equal_brute_force_and_are_sorted():
    x, radius = random_packing(400, 1)
    cap = 20000
    pi, pj = np.zeros(cap, np.int64), np.zeros(cap, np.int64)
    n = build_pairs(x, radius, 0.001, pi, pj)
    expected = brute_force_pairs(x, radius, 0.001)
    assert n == len(expected) > 0
    assert list(zip(pi[:n].tolist(), pj[:n].tolist(), strict=True)) == expected


def test_too_small_arrays_report_the_size_needed():
    x, radius = random_packing(200, 2)
    needed = len(brute_force_pairs(x, radius, 0.001))
    pi, pj = np.zeros(needed // 2, np.int64), np.zeros(needed // 2, np.int64)
    assert build_pairs(x, radius, 0.001, pi, pj) == needed


def test_history_follows_its_pair_across_rebuilds():
    old_i, old_j = np.array([0, 0, 1, 2]), np.array([1, 3, 2, 3])
    old = np.arange(12.0).reshape(4, 3)
    new_i, new_j = np.array([0, 1, 1, 2]), np.array([3, 2, 3, 3])
    new = np.full((4, 3), -1.0)
    carry_history(old_i, old_j, old, 4, new_i, new_j, new, 4)
    np.testing.assert_array_equal(new, [old[1], old[2], [0, 0, 0], old[3]])


def test_each_particle_lists_its_pairs_in_partner_order():
    pi, pj = np.array([0, 0, 1, 2]), np.array([1, 3, 2, 3])
    start, slots = np.zeros(5, np.int64), np.zeros(8, np.int64)
    index_by_particle(pi, pj, 4, start, slots)
    per_particle = [slots[start[p] : start[p + 1]].tolist() for p in range(4)]
    assert per_particle == [[0, 1], [0, 2], [2, 3], [1, 3]]
