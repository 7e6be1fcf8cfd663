"""Fixed-point arithmetic ([integrator] arithmetic = "fixed"): a conservative run and its
reversal return the very integers they started from; the trajectories stay within the grid
resolution of floating point; dissipation still breaks exactness; nothing wraps around."""

import subprocess
import sys

import h5py
import numba
import numpy as np
import pytest

from revdem_cli.config import load_scenario
from revdem_cli.engine import run_scenario
from tests.conftest import CONFIGS

FIXED = "integrator.arithmetic=fixed"


def run(config, tmp_path, *overrides, reverse=True):
    scenario, text = load_scenario(CONFIGS / config, [FIXED, *overrides])
    return run_scenario(scenario, text, ".toml", tmp_path, reverse=reverse)


CONSERVATIVE = {
    "collision": ("collision.toml",),
    "oedometer compression with its moving platen": ("smoke/oedometer.toml",),
    "fcc, strain rate and inertial servo": ("fcc_triaxial.toml",),
    "fcc, strain rates only": (
        "fcc_triaxial.toml",
        "stages.1.cell.x={strain_rate=5e-7}",
        "stages.1.cell.y={strain_rate=5e-7}",
    ),
    "undamped drop": ("drop_A.toml", "damping.drag=1.0", "stages.0.steps=300000"),
    # the cell's edges on their grid whatever moves them: a stage began from edges put on it
    # after the frame that ended the stage before, 2.8e-14 m from it, and was called bitwise
    "fcc, a strain-rate stage then the servo's, each reversed, the tape for the damping": (
        "fcc_triaxial.toml",
        "stages.0.cell.z={strain_rate=-1e-6}",
        "stages.0.steps=2000",
        "stages.1.steps=2000",
        "reversal.all_stages=true",
        "reversal.tape=true",
    ),
}


@pytest.mark.parametrize("case", CONSERVATIVE)
def test_a_conservative_run_reverses_to_the_same_integers(tmp_path, case):
    config, *overrides = CONSERVATIVE[case]
    verdict = run(config, tmp_path, *overrides).verdict
    assert verdict["bitwise_identical"] is True
    assert verdict["max_position_error"] == 0.0 and verdict["max_velocity_error"] == 0.0
    name = load_scenario(CONFIGS / config)[0].name
    with (
        h5py.File(tmp_path / f"{name}.forward.h5") as f,
        h5py.File(tmp_path / f"{name}.reverse.h5") as b,
    ):
        first = int(b["particles/all/position_grid/step"][-1])
        k = int(np.nonzero(f["particles/all/position_grid/step"][:] == first)[0][0])
        for field in ("position_grid", "velocity_grid"):
            start = f[f"particles/all/{field}/value"][k]
            back = b[f"particles/all/{field}/value"][-1]
            assert start.dtype == np.int64 and np.array_equal(start, back)


def test_fixed_point_follows_floating_point_within_the_grid_times_the_steps(tmp_path):
    """|x_fixed - x_float| <= (N + 1) (q_x + N dt q_v): the start and each of N steps round a
    position by at most a step q_x, and a velocity by q_v, which moves the position by
    dt q_v every step after."""
    fixed = run("collision.toml", tmp_path / "fixed", reverse=False)
    scenario, text = load_scenario(CONFIGS / "collision.toml")
    floating = run_scenario(scenario, text, ".toml", tmp_path / "float", reverse=False)
    with h5py.File(fixed.forward) as a, h5py.File(floating.forward) as b:
        grid = a["parameters/revdem"].attrs["fixed_grid"]
        steps = a["particles/all/position/step"][:]
        dx = np.abs(a["particles/all/position/value"][:] - b["particles/all/position/value"][:])
        dv = np.abs(a["particles/all/velocity/value"][:] - b["particles/all/velocity/value"][:])
    dt = scenario.integrator.dt
    n = steps[:, None, None]
    assert (dx <= (n + 1) * (grid[0] + n * dt * grid[3])).all()
    assert (dv <= (n + 1) * grid[3]).all()
    assert dx.max() > 0.0  # the grids are not those of floating point


def test_fixed_point_spins_follow_floating_point_in_a_shear_collision(tmp_path):
    """The moments of a sliding collision (Hanley 2020 Eq 5): fixed point takes each pair's
    n x f from the normal it keeps and its force on the grid, floating point from the pair
    loop's n x f; the spins they give agree to a millionth of the largest (the grids are
    2^-52 of their scales), and are not zero."""
    shear = "collision_shear.toml"
    fixed = run(shear, tmp_path / "fixed", reverse=False)
    scenario, text = load_scenario(CONFIGS / shear)
    floating = run_scenario(scenario, text, ".toml", tmp_path / "float", reverse=False)
    with h5py.File(fixed.forward) as a, h5py.File(floating.forward) as b:
        spin_fixed = a["particles/all/angular_velocity/value"][:]
        spin_float = b["particles/all/angular_velocity/value"][:]
    largest = np.abs(spin_float).max()
    assert largest > 1.0  # rad/s: the collision sets the spheres spinning
    assert np.abs(spin_fixed - spin_float).max() <= 1e-6 * largest


def test_drag_breaks_exactness_in_fixed_point_too(tmp_path):
    # drag merges a fraction 1 - gamma_d of the velocities of the grid, two onto one (Eq
    # 25): over 300 000 steps at 0.99999 the falling sphere meets a few, which no reversal
    # can tell apart
    verdict = run("drop_A.toml", tmp_path, "stages.0.steps=300000").verdict
    assert verdict["bitwise_identical"] is False
    assert verdict["max_velocity_error"] > 0.0


def test_a_value_leaving_its_grid_is_an_error_not_a_wrap_around(tmp_path):
    # a sphere at rest at the origin and one leaving it along y at 1 m/s: the grid reaches
    # 1024 x the power of two above the extent (0.016 m), 32 m; the flying one is named
    scenario = tmp_path / "away.toml"
    scenario.write_text(
        """name = "away"
[materials.m]
density = 1000.0
shear_modulus = 2.0e6
poisson_ratio = 0.2
[contact]
model = "hertz"
[[particles]]
material = "m"
radius = 0.005
position = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0]
[[particles]]
material = "m"
radius = 0.005
position = [0.0, 0.011, 0.0]
velocity = [0.0, 1.0, 0.0]
[integrator]
dt = 2.0e-4
arithmetic = "fixed"
[[stages]]
name = "fly"
steps = 200000
output_every = 5000
"""
    )
    done = subprocess.run(
        [sys.executable, "-m", "revdem_cli.cli", "run", str(scenario), "--out", str(tmp_path)]
        + ["-q"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert "position of particle 1 (id 2) left the range of its fixed-point grid" in lines[0]
    with h5py.File(tmp_path / "away.forward.h5") as f:  # what was written is kept
        y = f["particles/all/position/value"][:, 1, 1]
    assert 31.0 < y[-1] < 32.0 and (np.diff(y) > 0).all()


def test_fixed_point_is_recorded_with_its_grid(tmp_path):
    outputs = run("collision.toml", tmp_path, reverse=False)
    with h5py.File(outputs.forward) as f:
        attrs = f["parameters/revdem"].attrs
        assert attrs["arithmetic"] == "fixed"
        grid = attrs["fixed_grid"]
        n = f["particles/all/position_grid/value"][-1]
        x = f["particles/all/position/value"][-1]
    assert (np.log2(grid) == np.round(np.log2(grid))).all()  # powers of two
    np.testing.assert_array_equal(x, n * grid[0])


def test_an_overflow_names_the_quantity_that_left_its_grid():
    """The gather's kick of a velocity at the end of its grid is reported as the velocity
    (of that particle), not as a force."""
    from revdem_cli.kernels import fixed
    from revdem_cli.kernels.contact import FORWARD
    from revdem_cli.kernels.forces import compute_forces
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import OffGrid, empty_events, initial_state
    from tests.conftest import two_spheres

    scenario = two_spheres(gravity=(9.81, 0.0, 0.0), integrator={"dt": 1e-7, "arithmetic": "fixed"})
    model, state = Model.of(scenario), initial_state(scenario)
    state.fixed.v[1, 0] = fixed.RANGE  # the weight's kick takes it past the end
    bundles = stepping_bundles(state, model, model.dynamics, model.law)
    compute_forces(*bundles, FORWARD, 1e-7, 0.5e-7, empty_events(), 1, True)
    assert list(state.fixed.overflow) == [1 + fixed.OF_VELOCITY, 1]
    assert "the velocity of particle 1 (id 2) left" in str(OffGrid(1, state.fixed, state.ids))


def _three_touching(**changes):
    """Three spheres in a bent row, each touching the next: pair forces with three
    components, in fixed-point arithmetic."""
    from tests.conftest import two_spheres

    sphere = {"material": "sphere", "radius": 0.005, "velocity": [0.0, 0.0, 0.0]}
    rows = ([0.0, 0.0, 0.0], [0.0099, 0.0005, 0.0002], [0.0195, 0.001, -0.0003])
    particles = [sphere | {"position": list(x)} for x in rows]
    integrator = {"dt": 1e-7, "arithmetic": "fixed"}
    return two_spheres(particles=particles, integrator=integrator, **changes)


def test_a_pair_force_is_rounded_once_and_summed_exactly():
    """The pair loop rounds each pair's force to the force grid once (fixed.snapped_in_range)
    and each sphere's sum adds those integers exactly: each sphere's net force is the sum of its
    pairs' forces, in whole grid steps."""
    from revdem_cli.kernels import fixed
    from revdem_cli.state import initial_state

    state = initial_state(_three_touching())  # its forces found, as at a run's start
    pairs, step = state.pairs, state.fixed.grid[fixed.FORCE]
    count = int(pairs.count[0])
    steps = pairs.force[:count] / step
    assert np.count_nonzero(steps.any(axis=1)) == 2  # 0 and 1, 1 and 2 touch
    np.testing.assert_array_equal(steps, np.round(steps))
    net = np.zeros((3, 3), dtype=np.int64)
    for k in range(count):  # the force on i from j, and its reaction on j
        net[pairs.i[k]] += steps[k].astype(np.int64)
        net[pairs.j[k]] -= steps[k].astype(np.int64)
    np.testing.assert_array_equal(state.particles.f / step, net)


@pytest.mark.parametrize("keep", [True, False])
def test_a_net_force_is_the_integer_sum_of_its_terms_whichever_way_it_is_summed(keep):
    """A sphere's forces are summed in doubles (the pair loop) and kept where every partial
    sum is an integer a double holds (fixed.sum_exact), else summed again as integers (the
    gather, `complete_sums`): a sphere pressed by three neighbours
    with forces of 2^50 to 2^52 force-grid steps, whose sum in doubles rounds, gets the
    integer sum rounded once; on a grid 16 times coarser, where the doubles are exact, the
    integer sum as well. The same where nothing asks the pair loop to keep its forces
    (`keep` false): frictionless, it runs again to keep them where a sum needs them."""
    from revdem_cli.kernels import fixed
    from revdem_cli.kernels.contact import FORWARD
    from revdem_cli.kernels.forces import compute_forces
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import empty_events, initial_state
    from tests.conftest import two_spheres

    sphere = {"material": "sphere", "radius": 0.005, "velocity": [0.0, 0.0, 0.0]}
    rows = (
        [0, 0, 0],
        [0.0099, 0.0003, 0.0001],
        [-0.0003, 0.0097, 0.0002],
        [0.0002, -0.0004, 0.0096],
    )
    particles = [sphere | {"position": [float(c) for c in x]} for x in rows]
    scenario = two_spheres(particles=particles, integrator={"dt": 1e-7, "arithmetic": "fixed"})
    for coarser, rounds in ((1.0, True), (16.0, False)):
        model, state = Model.of(scenario), initial_state(scenario)
        step = state.fixed.grid[fixed.FORCE] * coarser
        state.fixed.grid[fixed.FORCE] = step
        bundles = stepping_bundles(
            state, model, model.dynamics, model.law._replace(force_grid=step)
        )
        compute_forces(*bundles, FORWARD, 1e-7, 0.0, empty_events(), 1, keep)
        net = state.particles.f[0].copy()
        compute_forces(*bundles, FORWARD, 1e-7, 0.0, empty_events(), 1, True)
        count = int(state.pairs.count[0])
        terms = [state.pairs.force[k] for k in range(count) if state.pairs.i[k] == 0]
        assert len(terms) == 3 and state.fixed.overflow[0] == 0
        in_doubles = sum(terms[1:], terms[0]) / step  # in the gather's order
        exact = [float(sum(int(t[d] / step) for t in terms)) for d in range(3)]
        assert (list(in_doubles) != exact) == rounds
        np.testing.assert_array_equal(net / step, exact)


def test_a_pair_force_beyond_its_grid_is_reported_as_the_force():
    """A pair's force more than 2^62 force-grid steps is held at the end of the range, never
    converted past it, and the sums it enters are reported out of range, as the force on the
    last particle they act on."""
    from revdem_cli.kernels import fixed
    from revdem_cli.kernels.contact import FORWARD
    from revdem_cli.kernels.forces import compute_forces
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import OffGrid, empty_events, initial_state

    scenario = _three_touching()
    model, state = Model.of(scenario), initial_state(scenario)
    assert state.fixed.overflow[0] == 0
    fine = state.fixed.grid[fixed.FORCE] * 2.0**-40  # every force now ~2^70 steps
    state.fixed.grid[fixed.FORCE] = fine
    law = model.law._replace(force_grid=fine)
    bundles = stepping_bundles(state, model, model.dynamics, law)
    compute_forces(*bundles, FORWARD, 1e-7, 0.5e-7, empty_events(), 1, True)
    assert list(state.fixed.overflow) == [1 + fixed.OF_FORCE, 2]
    assert "the force of particle 2 (id 3) left" in str(OffGrid(1, state.fixed, state.ids))


def test_a_shear_history_lies_on_the_grid_of_its_own_contact(tmp_path):
    """In fixed-point arithmetic a shear history is a whole number of steps of 2^-40 of the
    power of two at or below its contact's elastic normal force (kernels/fixed.py,
    HISTORY_BITS), however large: the shear collision (Hanley 2020 Figure 5) stopped while
    its spheres touch, its history read from the restart."""
    from revdem_cli import laws
    from revdem_cli.kernels.fixed import HISTORY_BITS
    from revdem_cli.state import moduli

    scenario, text = load_scenario(CONFIGS / "collision_shear.toml", [FIXED, "stages.0.steps=6000"])
    run_scenario(scenario, text, ".toml", tmp_path, reverse=False)
    with h5py.File(tmp_path / "collision_shear.restart.h5") as restart:
        x = restart["particles/x"][:]
        radius = restart["particles/radius"][:]
        history = restart["pairs/history"][0]
    overlap = radius.sum() - np.linalg.norm(x[1] - x[0])
    assert overlap > 0.0 and np.abs(history).max() > 0.0
    rstar = radius.prod() / radius.sum()
    estar = float(moduli(scenario).estar[0, 0])
    elastic = laws.evaluate(scenario.contact, "normal", "force", overlap, rstar, estar)[0]
    step = 2.0 ** (np.floor(np.log2(elastic)) - HISTORY_BITS)
    steps = history / step
    assert np.all(steps == np.round(steps)), steps
    assert np.abs(steps).max() > 2**20  # resolved far below the force it carries


def test_the_normals_a_step_turns_from_are_kept_by_a_restart_and_a_grown_list(tmp_path):
    """In fixed point with shear each pair keeps its contact normal at the current positions
    (`Pairs.normal`), which the next step turns its history from. The stepping loop does not
    find them again when it is called, so a restart read back and a grown list must hold the
    normals the pair loop left, to the bit."""
    from revdem_cli.io.restart import Restart, read_restart, write_restart
    from revdem_cli.state import grown
    from tests.conftest import stepped

    contact = {"model": "hertz", "tangential": "mindlin", "friction": 0.3}
    scenario = _three_touching(contact=contact)
    state = list(stepped(scenario, 200, 200))[-1]
    count = int(state.pairs.count[0])
    normals = state.pairs.normal[:count].copy()
    assert np.count_nonzero(normals.any(axis=1)) == 2  # 0 and 1, 1 and 2 touch
    bigger = grown(state.pairs, 2 * state.pairs.i.shape[0])
    np.testing.assert_array_equal(bigger.normal[:count], normals)
    clock = (0, 0.0, 1e-7)  # the stage's first step, its time there and its time step
    restart = Restart(state, scenario.model_dump_json(), "", ".toml", "collide", "", *clock)
    write_restart(tmp_path / "state.restart.h5", restart)
    read = read_restart(tmp_path / "state.restart.h5").state.pairs
    np.testing.assert_array_equal(read.normal[:count], normals)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_the_drift_cut_into_a_part_a_thread_gives_the_same_integers_and_overflows(
    every_loop_parallel,
):
    """The fixed-point drift runs in one part a thread (`kernels.by_parts`): the integers,
    the positions they give, and which coordinates left their grid (how many, and the
    particle of the last) are the same on one thread and two."""
    from revdem_cli.kernels import fixed

    count = 1000  # above the crossovers `every_loop_parallel` sets
    v = np.random.default_rng(5).uniform(-1.0, 1.0, 3 * count)
    v[[3 * 10 + 1, 3 * 900 + 2]] = 1e300  # off the grid, one in each thread's part
    results = []
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            n, x = np.arange(3 * count, dtype=np.int64), np.zeros(3 * count)
            results.append((fixed.drift_uniform(count, n, x, v, 1e-3, 2.0**-30), n, x))
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    (one, n1, x1), (two, n2, x2) = results
    assert one == two == (2, 900)
    np.testing.assert_array_equal(n1, n2)
    np.testing.assert_array_equal(x1, x2)
    assert n1[3 * 10 + 1] == 3 * 10 + 1  # a value that would leave its grid stays


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_the_half_kick_on_its_grid_adds_each_rounded_increment_on_any_thread_count(
    every_loop_parallel,
):
    """The half kick on the velocity grid (`fixed.kick`: blocks of particles, each
    coordinate kicked in one elementwise loop) adds to each integer its increment h f / m in
    grid steps rounded half away from zero, with the velocity the integer gives beside it;
    one coordinate in each thread's part that would leave the grid stays and is reported
    (how many, the particle of the last), the same on one thread and two."""
    from revdem_cli.kernels import fixed

    count = 1000  # above the crossovers, and many blocks of fixed.KICK_BLOCK
    rng = np.random.default_rng(11)
    f = rng.normal(size=(count, 3)) * 1e3
    inv_m = rng.uniform(1.0, 1e4, count)
    step = 2.0**-30
    start = rng.integers(-(2**40), 2**40, size=(count, 3))
    f[10, 1] = f[900, 2] = 1e300  # off the grid, one in each thread's part
    for h in (0.5e-6, -0.5e-6):
        y = h * f * inv_m[:, None] * (1.0 / step)  # `fixed.kick_steps`, in its order
        y[10, 1] = y[900, 2] = 0.0  # these stay
        expected = start + np.trunc(y + np.copysign(0.5, y)).astype(np.int64)
        results = []
        try:
            for threads in (1, 2):
                numba.set_num_threads(threads)
                n, v = start.copy(), np.zeros((count, 3))
                results.append((fixed.kick(count, n, v, f, inv_m, h, step), n, v))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        for counts, n, v in results:
            assert counts == (2, 900)
            np.testing.assert_array_equal(n, expected)
            np.testing.assert_array_equal(v, expected * step)


@pytest.mark.parametrize("moment_out", [False, True])
def test_sums_without_walls_kept_in_doubles_are_those_of_the_sums_in_full(moment_out):
    """Without walls, where no sphere's force sum in doubles may have rounded, the gather
    keeps the pair loop's sums and only rounds the moments onto their grid
    (`gather.complete_sums`): the same forces, moments, and moment that left its grid
    (reported as the moment of the last such particle) as the sums judged sphere by sphere
    (`gather.sums_in_full`)."""
    from revdem_cli.kernels import fixed
    from revdem_cli.kernels.gather import complete_sums, sums_in_full

    count = 300
    rng = np.random.default_rng(12)
    grid = np.zeros(9)
    grid[fixed.FORCE], grid[fixed.TORQUE] = 2.0**-40, 2.0**-44
    mass = rng.uniform(1e-3, 1e-2, count)
    first = np.arange(count + 1, dtype=np.int32) * 6 // 2  # three pairs a sphere
    start = first.copy()
    f = np.round(rng.normal(size=(count, 3)) * 2.0**20) * grid[fixed.FORCE]  # on the grid
    t = rng.normal(size=(count, 3)) * 1e-3
    if moment_out:
        t[17, 0] = t[250, 2] = 1e30
    gravity = np.array([0.0, 0.0, -9.81])
    no_pairs = np.zeros((0, 3))
    no_walls = np.zeros((count, 0, 3))
    found = []
    for sums in (complete_sums, sums_in_full):
        f_out, t_out = f.copy(), t.copy()
        counts = sums(count, mass, gravity, first, start, np.zeros(0, dtype=np.int32),
                      no_pairs, True, no_walls, no_walls, f_out, t_out, True, grid, 1e-3,
                      False)  # fmt: skip
        found.append((counts, f_out, t_out))
    (fast, f_fast, t_fast), (full, f_full, t_full) = found
    assert fast == full == ((2, 250, fixed.OF_MOMENT, 0) if moment_out else (0, -1, 0, 0))
    np.testing.assert_array_equal(f_fast, f_full)
    np.testing.assert_array_equal(t_fast, t_full)
    steps = t_fast / grid[fixed.TORQUE]
    np.testing.assert_array_equal(steps, np.round(steps))


def test_the_velocity_grid_takes_the_walls_speeds():
    """A plane driven at 2000 m/s into a sphere at rest overflowed the velocity grid, whose
    scale came from the spheres alone (1 m/s): a wall's speed in any stage now counts."""
    from revdem_cli.kernels import fixed
    from revdem_cli.state import fixed_grid

    still, _ = load_scenario(CONFIGS / "drop_A.toml", [FIXED])
    driven, _ = load_scenario(
        CONFIGS / "drop_A.toml", [FIXED, "stages.0.wall_velocities={plane=[0, 0, 2000]}"]
    )
    assert fixed_grid(still)[fixed.VELOCITY] < 1.0 * 2.0**-52
    assert fixed_grid(driven)[fixed.VELOCITY] == 2048.0 * 2.0**-52
