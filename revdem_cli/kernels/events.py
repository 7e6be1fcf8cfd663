"""A log of the mechanisms that destroy information, so a failed reversal can be explained.

For each kind: how often it acted, the first and last step it acted at, and the particles
and amount of its last occurrence. Walls appear as partner -1 - wall index.
"""

from revdem_cli.kernels import jit

KINDS = (
    "contact_lost_with_shear_force",  # history zeroed at separation (Hanley 2020 §4), N
    "coulomb_slip",  # shear force capped at mu |f_n| (§5.1); amount removed, N
    "local_damping",  # Eq 21 (§5.2)
    "viscous_damping",  # contact damping (§5.2), at contacts touching; amount beta
    "velocity_fixed_point_under_drag",  # drag map at a fixed point (§5.2, case C), m/s
    "motion_below_round_off",  # x + dt v == x for v != 0 (§5.2, case B: at rest), m
    "rolling_limit",  # rolling moment capped by its law's limit (§5.3); amount removed, N m
    "contact_lost_with_rolling_moment",  # rolling history zeroed at separation, N m
)
(
    CONTACT_LOST,
    COULOMB_SLIP,
    LOCAL_DAMPING,
    VISCOUS_DAMPING,
    FIXED_POINT,
    MOTION_LOST,
    ROLLING_LIMIT,
    ROLLING_LOST,
) = range(len(KINDS))
COLUMNS = ("count", "first_step", "last_step", "particle", "partner", "amount")
COUNT, FIRST, LAST, PARTICLE, PARTNER, AMOUNT = range(len(COLUMNS))


@jit
def note(events, kind, step, particle, partner, amount, times):
    """`kind` acted `times` times at `step`, last on (particle, partner) by `amount`."""
    if events[kind, COUNT] == 0:
        events[kind, FIRST] = step
    events[kind, COUNT] += times
    events[kind, LAST] = step
    events[kind, PARTICLE] = particle
    events[kind, PARTNER] = partner
    events[kind, AMOUNT] = amount


@jit
def note_destroyed(events, step, pairs, walls, pair_counts, wall_counts, law):
    """Log what the contacts destroyed at `step`, as the force loops counted it: (slips, last
    pair that slipped, losses, last pair that lost its shear force, then the same for the
    rolling moment: caps, last capped, losses, last lost, then with viscous damping the
    contacts touching and the last of them, whose amount is the law's larger beta) for the
    pairs, and the same for the wall contacts, numbered q W + b. The last occurrence is the
    one a scan of the pairs in order, then of the wall contacts, would meet last."""
    walls_per_particle = walls.destroyed.shape[1]
    kinds = (
        (COULOMB_SLIP, 0), (CONTACT_LOST, 2), (ROLLING_LIMIT, 4), (ROLLING_LOST, 6),
        (VISCOUS_DAMPING, 8),
    )  # fmt: skip
    for kind, offset in kinds:
        pair_count, last_pair = pair_counts[offset], pair_counts[offset + 1]
        wall_count, last_wall = wall_counts[offset], wall_counts[offset + 1]
        if pair_count + wall_count == 0:
            continue
        q = b = 0
        if wall_count > 0:
            q, b = last_wall // walls_per_particle, last_wall % walls_per_particle
            particle, partner = q, -1 - b
        else:
            particle, partner = pairs.i[last_pair], pairs.j[last_pair]
        if kind == VISCOUS_DAMPING:  # read first: without shear or rolling, no such arrays
            amount = max(law.beta_n, law.beta_t)
        elif wall_count > 0:
            amount = walls.rolled[q, b] if offset >= 4 else walls.destroyed[q, b]
        else:
            amount = pairs.rolled[last_pair] if offset >= 4 else pairs.destroyed[last_pair]
        note(events, kind, step, particle, partner, amount, pair_count + wall_count)


@jit
def note_local_damping(events, step, dyn):
    """Log the local damping that acted at `step` (viscous damping is logged by the force
    loops, at the contacts it acted on: `note_destroyed`)."""
    if dyn.local_damping > 0.0:
        note(events, LOCAL_DAMPING, step, -1, -1, dyn.local_damping, 1)


@jit
def note_fixed_points(v, v_drift, step, events):
    """Particles whose drift velocity is bit for bit that of the previous step, under drag."""
    for q in range(v.shape[0]):
        if v[q, 0] == v_drift[q, 0] and v[q, 1] == v_drift[q, 1] and v[q, 2] == v_drift[q, 2]:
            note(events, FIXED_POINT, step, q, -1, abs(v[q, 0]) + abs(v[q, 1]) + abs(v[q, 2]), 1)
        v_drift[q, 0], v_drift[q, 1], v_drift[q, 2] = v[q, 0], v[q, 1], v[q, 2]
