"""The array bundles the kernels work on. Built and reallocated in Python, updated compiled."""

from collections import namedtuple

Particles = namedtuple(
    "Particles",
    [
        "x",  # positions, m, (N, 3)
        "v",  # velocities, m/s, (N, 3)
        "omega",  # angular velocities, rad/s, (N, 3)
        "f",  # net forces at the current full step, N, (N, 3)
        "torque",  # net moments at the current full step, N m, (N, 3)
        "radius",  # m, (N,)
        "mass",  # kg, (N,)
        "inertia",  # moment of inertia 2/5 m r^2, kg m^2, (N,)
        "inv_mass",  # 1/kg, (N,)
        "inv_inertia",  # 1/(kg m^2), (N,)
        "material",  # material index, (N,) int64
        "v_drift",  # velocity of the last drift, m/s, (N, 3): finds drag fixed points
    ],
)

Pairs = namedtuple(
    "Pairs",
    [
        "count",  # [pairs in the list, pairs the last build needed], int64 (2,)
        "i",  # first particle of each pair (i < j), sorted by (i, j), (P,)
        "j",  # second particle, (P,)
        "history",  # elastic shear force on i, N, (P, 3): the contact history
        "force",  # contact force on i from j at the current step, N, (P, 3)
        "torque_i",  # moment of the contact force about i's centre, N m, (P, 3)
        "torque_j",  # moment of the reaction about j's centre, N m, (P, 3)
        "normal",  # normal force magnitude (repulsive > 0), N, (P,)
        "energy",  # elastic energy stored in the contact, J, (P,)
        "slip",  # shear force removed by the Coulomb cap this step, N, (P,)
        "lost",  # shear force zeroed at separation this step, N, (P,)
        "pending",  # reversed step: shear force with Eq 10 and 9 undone, N, (P, 3)
        "normal_new",  # reversed step: the contact normal that `pending` lies across, (P, 3)
        "start",  # CSR offsets of each particle's pair slots, (N + 1,)
        "slots",  # pair slots of each particle, ascending, (2P,)
        "x_built",  # positions at the last build, m, (N, 3)
        "new_i",  # scratch for rebuilding, (P,)
        "new_j",  # scratch for rebuilding, (P,)
        "new_history",  # scratch for rebuilding, (P, 3)
    ],
)

Walls = namedtuple(
    "Walls",
    [
        "kind",  # walls.PLANE or walls.CYLINDER, (W,)
        "point",  # a point on the plane or the cylinder axis now, m, (W, 3)
        "origin",  # `point` at the start of the stage, m, (W, 3)
        "axis",  # plane: unit normal into the domain; cylinder: unit axis, (W, 3)
        "radius",  # cylinder radius, m, (W,)
        "velocity",  # m/s, (W, 3)
        "material",  # material index, (W,)
        "history",  # elastic shear force on the particle, N, (N, W, 3)
        "force",  # force on the particle from the wall, N, (N, W, 3)
        "torque",  # moment of that force about the particle's centre, N m, (N, W, 3)
        "normal",  # normal force magnitude, N, (N, W)
        "energy",  # elastic energy, J, (N, W)
        "slip",  # shear force removed by the Coulomb cap this step, N, (N, W)
        "lost",  # shear force zeroed at separation this step, N, (N, W)
        "pending",  # reversed step, as in Pairs, (N, W, 3)
        "normal_new",  # reversed step, as in Pairs, (N, W, 3)
    ],
)

ContactLaw = namedtuple(
    "ContactLaw",
    [
        "model",  # contact.HERTZ or contact.LINEAR
        "kn",  # linear normal stiffness, N/m
        "tangential",  # contact.NO_SHEAR, LINEAR_SHEAR or MINDLIN
        "ks",  # linear shear stiffness, N/m
        "mu",  # Coulomb friction coefficient (inf: no sliding)
        "beta_n",  # normal viscous damping, fraction of critical
        "beta_t",  # tangential viscous damping, fraction of critical
    ],
)

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
