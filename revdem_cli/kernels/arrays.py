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
    ],
)

Pairs = namedtuple(
    "Pairs",
    [
        "count",  # [pairs in the list, pairs the last build needed], int64 (2,)
        "i",  # first particle of each pair (i < j), sorted by (i, j), (P,)
        "j",  # second particle, (P,)
        "history",  # per-pair contact history (shear force on i), N, (P, 3)
        "force",  # contact force on i from j at the current step, N, (P, 3)
        "energy",  # elastic energy stored in the contact, J, (P,)
        "start",  # CSR offsets of each particle's pair slots, (N + 1,)
        "slots",  # pair slots of each particle, ascending, (2P,)
        "x_built",  # positions at the last build, m, (N, 3)
        "new_i",  # scratch for rebuilding, (P,)
        "new_j",  # scratch for rebuilding, (P,)
        "new_history",  # scratch for rebuilding, (P, 3)
    ],
)

ContactLaw = namedtuple(
    "ContactLaw",
    [
        "model",  # kernels.contact.HERTZ or LINEAR
        "kn",  # linear normal stiffness, N/m
        "estar",  # effective Young's modulus E* of each material pair, Pa, (M, M)
    ],
)
