"""The array bundles the kernels work on. Built and reallocated in Python, updated compiled.

Arrays a run does not need have length 0: the shear state of a frictionless law, the
cell coordinates of a run whose cell never deforms, the drift record of a run without drag,
and what only the reversed step needs, in a forward run.
"""

from collections import namedtuple

from revdem_cli.laws import PARAMETERS

Particles = namedtuple(
    "Particles",
    [
        "x",  # positions, m, (N, 3); unwrapped across periodic boundaries
        "s",  # cell coordinates x / L of a deforming periodic cell, (N, 3) or (0, 3)
        "v",  # velocities, m/s, (N, 3); in a deforming cell, relative to its affine motion
        "omega",  # angular velocities, rad/s, (N, 3)
        "f",  # net forces at the current full step, N, (N, 3)
        "torque",  # net moments at the current full step, N m, (N, 3)
        "radius",  # m, (N,)
        "mass",  # kg, (N,)
        "inertia",  # moment of inertia 2/5 m r^2, kg m^2, (N,)
        "inv_mass",  # 1/kg, (N,)
        "inv_inertia",  # 1/(kg m^2), (N,)
        "material",  # material index, (N,) int64
        "v_drift",  # velocity of the last drift under drag, m/s, (N, 3) or (0, 3)
        "v_past",  # the velocity predictor's k last half-step velocities, newest first, m/s,
        # (k, N, 3); k = 0 (velocity Verlet): (0, N, 3)
        "omega_past",  # the same of the angular velocities, rad/s, (k, N, 3)
        "v_pred",  # predicted velocity at the current full step, m/s, (N, 3) or (0, 3)
        "omega_pred",  # predicted angular velocity, rad/s, (N, 3) or (0, 3)
    ],
)
"""The velocity predictor (kernels/predictor.py, integrator.scheme = 'trvp') keeps the
half-step velocities of the k steps before, in the order of stepping: going forward those
of the earlier steps, reversed those of the later ones."""

Pairs = namedtuple(
    "Pairs",
    [
        "count",  # [pairs in the list, pairs the last build needed], int64 (2,)
        "i",  # first particle of each pair (i < j), sorted by (i, j), int32 (P,)
        "j",  # second particle, int32 (P,)
        "force",  # contact force on i from j at the current step, N, (P, 3)
        "history",  # elastic shear force on i, N, (P, 3): the contact history
        "moment",  # floating point: n x force, the moment about i's centre over its lever arm
        # (Hanley 2020 Eq 5), N, (P, 3); fixed point takes it from `normal`
        "overlap",  # overlap at the current step (< 0: apart), m, (P,)
        "destroyed",  # shear force destroyed this step (0: none): Coulomb cap, separation; N (P,)
        "rolling",  # rolling moment on i: the rolling history, N m, (P, 3)
        "rolled",  # rolling moment destroyed this step: its limit or separation, N m, (P,)
        "normal_new",  # reversed step: the contact normal the unwound history lies across
        "normal",  # fixed point with shear: each pair's contact normal at the current
        # positions (zero apart), which the next forward step turns its histories from and
        # the gather takes n x force from, (P, 3)
        "earlier",  # a run with the information tape and shear: the pairs whose shear history
        # the reversed step would miss at the earlier positions, listed by a forward pair
        # loop that predicts it (`kernels.tape.predict`; columns `pairs.MISSED` to
        # `pairs.SPREAD`), (P, 7), on private pages of its own (`memory.untouched`): only the
        # rows listed are written, and its pages go back before each call (`io.tape.Recorder`)
        "first",  # the pairs (q, j) of particle q are slots first[q] to first[q + 1], int32
        # (N + 1,)
        "start",  # CSR offsets into `slots` of each particle's pairs (p, q), p < q, int32
        # (N + 1,)
        "slots",  # the slots of the pairs (p, q) of each particle q, ascending in p, int32 (P,)
        "x_built",  # positions at the last build, single precision (a rebuild's test allows
        # for it: `neighbours.BUILT_ROUNDING`), m, float32 (N, 3)
        "blocks",  # working rows of the pair loop, a block for each thread of numba's pool
        # (a chunk of the list each, `pairs.pair_loop`; forces.py)
        "foreign",  # whether each particle has a partner in an earlier chunk of the pair
        # loop's last call on more than one chunk, which sums it apart
        # (`pairs.sum_foreign`), bool (N,)
        "balance",  # each chunk of the pair loop's list in its last call on more than
        # one: its share of the pairs, the nanoseconds its thread took, its first particle
        # (`pairs.balanced`), (threads of numba's pool, 3)
        "partials",  # partial sums of each block of particles (sums.py)
    ],
)
"""history, overlap and destroyed have length P with a tangential law, else 0; with one,
moment has length P in floating point and normal in fixed point (0 the other); rolling
and rolled length P with a rolling law, else 0; normal_new has length P in a reversed run
with a tangential law, else 0; earlier length P in fixed point with a tangential law and
the information tape, else 0."""

Walls = namedtuple(
    "Walls",
    [
        "kind",  # the number of its shape (revdem_cli.wall_shapes), (W,)
        "point",  # a point on the plane or the cylinder axis now, m, (W, 3)
        "origin",  # `point` at the start of the stage, m, (W, 3)
        "axis",  # plane: unit normal into the domain; cylinder: unit axis, (W, 3)
        "radius",  # cylinder radius, m, (W,)
        "velocity",  # m/s, (W, 3)
        "material",  # material index, (W,)
        "force",  # force on the particle from the wall, N, (N, W, 3)
        "torque",  # moment on the particle (of that force, and rolling), N m, (N, W, 3)
        "overlap",  # m, (N, W)
        "history",  # elastic shear force on the particle, N, (N, W, 3)
        "destroyed",  # shear force destroyed this step, N, (N, W)
        "rolling",  # rolling moment on the particle, N m, (N, W, 3); (0, W, 3) without rolling
        "rolled",  # rolling moment destroyed this step, N m, (N, W); (0, W) without rolling
        "normal_new",  # reversed step, as in Pairs, (N, W, 3)
    ],
)

Cell = namedtuple(
    "Cell",
    [
        "periodic",  # 1 for each periodic axis, int64 (3,)
        "length",  # edge lengths L of the periodic box [0, L), m, (3,)
        "start",  # L at the start of the stage, m, (3,)
        "rate",  # dL/dt over the current step, m/s, (3,)
        "mid",  # L at the middle of the current step, m, (3,)
        "force",  # inertial servo: the force on each edge at the current step, N, (3,)
        "control",  # cell.FIXED, STRAIN_RATE or STRESS for each axis, int64 (3,)
        "target",  # stress axes: the stress to hold, Pa (compression > 0), (3,)
        "built",  # L at the last pair-list build, m, (3,)
        "stress",  # average stress (Hanley 2020 Eq 23) at the current step, Pa, (3, 3)
        "servo",  # cell.PROPORTIONAL or cell.INERTIAL
        "mass",  # inertial servo: mass of an edge, kg
        "gain",  # proportional servo: strain rate per relative stress error, 1/s
    ],
)

Fixed = namedtuple(
    "Fixed",
    [
        "x",  # positions on their grid (a deforming cell: cell coordinates), int64 (N, 3)
        "v",  # velocities on their grid, int64 (N, 3)
        "omega",  # angular velocities on their grid, int64 (N, 3)
        "length",  # cell edges on their grid (inertial servo), int64 (3,)
        "rate",  # their rates on their grid, int64 (3,)
        "grid",  # grid steps, see kernels.fixed: X, Y, Z, VELOCITY, ..., EDGE_RATE, (9,)
        "overflow",  # [1 + quantity, particle] of the first value to leave its grid, (2,)
    ],
)
"""The integer state of fixed-point arithmetic (kernels/fixed.py); every array has length 0
in floating-point runs."""

CONTACT = (
    "normal",  # number of the normal law (revdem_cli.laws)
    "tangential",  # number of the tangential law, laws.NONE for frictionless spheres
    "rolling",  # number of the rolling law, laws.NONE without rolling resistance
    "mu",  # Coulomb friction coefficient (inf: no sliding)
    "beta_n",  # normal viscous damping, fraction of critical
    "beta_t",  # tangential viscous damping, fraction of critical
    "history_grid",  # fixed-point arithmetic: 2^-fixed.HISTORY_BITS; 0 in floating point
    "force_grid",  # fixed-point arithmetic: the force grid's step, N; 0 in floating point
)
ContactLaw = namedtuple("ContactLaw", CONTACT + PARAMETERS)
"""The compiled record of a contact: the fields of CONTACT, then every law's coefficients by
name (laws.PARAMETERS, 0 where not given). Flat: numba's parallel loops take no nested
records."""

Moduli = namedtuple(
    "Moduli",
    [
        "estar",  # effective Young's modulus E* of each material pair, Pa, (M, M)
        "gstar",  # effective shear modulus G* of each material pair, Pa, (M, M)
    ],
)

Dynamics = namedtuple(
    "Dynamics",
    [
        "gravity",  # m/s^2, (3,)
        "local_damping",  # gamma_l of Hanley 2020 Eq 21
        "drag",  # gamma_d of Hanley 2020 Eq 25 (1: none)
    ],
)

Stepping = namedtuple(
    "Stepping",
    [
        "dt",  # time step, s
        "skin",  # neighbour skin, m
        "first_step",  # the stage's first step (int)
        "last_step",  # the stage's last step (int)
        "every",  # observables every this many steps from the first (int)
        "overlap_limit",  # deepest overlap allowed / the smaller radius of a contact
        "halt",  # int64 [1]: nonzero asks the loop to stop at the next whole step
    ],
)
"""How the compiled stage loop steps a stage (`integrate.advance`); steps are integers. `halt`
is read at every step: the thread that watches for signals sets it while the loop runs in
the main thread (`checkpoint.watching`)."""
