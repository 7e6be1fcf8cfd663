"""A log of the mechanisms that destroy information, so a failed reversal can be explained.

For each kind: how often it acted, the first and last step it acted at, and the particles
and amount of its last occurrence. Walls appear as partner -1 - wall index.
"""

from revdem_cli.kernels import jit

KINDS = (
    "contact_lost_with_shear_force",  # history zeroed at separation (Hanley 2020 §4), N
    "coulomb_slip",  # shear force capped at mu |f_n| (§5.1); amount removed, N
    "local_damping",  # Eq 21 (§5.2)
    "viscous_damping",  # contact damping (§5.2)
    "velocity_fixed_point_under_drag",  # drag map at a fixed point (§5.2, case C), m/s
    "motion_below_round_off",  # x + dt v == x for v != 0 (§5.2, case B: at rest), m
)
CONTACT_LOST, COULOMB_SLIP, LOCAL_DAMPING, VISCOUS_DAMPING, FIXED_POINT, MOTION_LOST = range(
    len(KINDS)
)
COLUMNS = ("count", "first_step", "last_step", "particle", "partner", "amount")
COUNT, FIRST, LAST, PARTICLE, PARTNER, AMOUNT = range(len(COLUMNS))


@jit
def note(events, kind, step, particle, partner, amount):
    if events[kind, COUNT] == 0:
        events[kind, FIRST] = step
    events[kind, COUNT] += 1
    events[kind, LAST] = step
    events[kind, PARTICLE] = particle
    events[kind, PARTNER] = partner
    events[kind, AMOUNT] = amount


@jit
def note_contact_events(pairs, walls, law, dyn, step, events):
    """Scan the contacts of this step, in a fixed order, for lost shear force and slip."""
    for k in range(pairs.count[0]):
        if pairs.lost[k] > 0.0:
            note(events, CONTACT_LOST, step, pairs.i[k], pairs.j[k], pairs.lost[k])
        if pairs.slip[k] > 0.0:
            note(events, COULOMB_SLIP, step, pairs.i[k], pairs.j[k], pairs.slip[k])
    for q in range(walls.lost.shape[0]):
        for b in range(walls.lost.shape[1]):
            if walls.lost[q, b] > 0.0:
                note(events, CONTACT_LOST, step, q, -1 - b, walls.lost[q, b])
            if walls.slip[q, b] > 0.0:
                note(events, COULOMB_SLIP, step, q, -1 - b, walls.slip[q, b])
    if dyn.local_damping > 0.0:
        note(events, LOCAL_DAMPING, step, -1, -1, dyn.local_damping)
    if law.beta_n > 0.0 or law.beta_t > 0.0:
        note(events, VISCOUS_DAMPING, step, -1, -1, max(law.beta_n, law.beta_t))


@jit
def note_fixed_points(v, v_drift, step, events):
    """Particles whose drift velocity is bit for bit that of the previous step, under drag."""
    for q in range(v.shape[0]):
        if v[q, 0] == v_drift[q, 0] and v[q, 1] == v_drift[q, 1] and v[q, 2] == v_drift[q, 2]:
            note(events, FIXED_POINT, step, q, -1, abs(v[q, 0]) + abs(v[q, 1]) + abs(v[q, 2]))
        v_drift[q, 0], v_drift[q, 1], v_drift[q, 2] = v[q, 0], v[q, 1], v[q, 2]
