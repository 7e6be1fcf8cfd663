"""Two rigid superquadrics (ellipsoids included) in one linear spring-dashpot contact.

Orientation is a unit quaternion q = (w, x, y, z) whose matrix (Peng 2020 Eq 7-8) maps the
body frame to the world; angular momentum is kept in the body frame, π = I ω_L, with the
principal moments I on the body axes.

Contact detection: the Perram-Wertheim contact function (Perram & Wertheim 1985, J Comput
Phys 58:409), with each body's shape function G = f^ε1, Barr's inside-outside function
raised to the power that makes it homogeneous of degree two in the body coordinates
(G = 1 on the surface). The point x* and weight λ solve λ ∇G₁ + (1 - λ) ∇G₂ = 0,
G₁(x*) = G₂(x*) = S: the bodies scaled by √S about their centres touch at x* with a common
normal. The overlap along that normal is δ = (x₂ - x₁)·n (1/√S - 1) (negative: a gap) and the
contact point is the midpoint of the two bodies' deepest points along it.

Time stepping: velocity Verlet for the centres (half kick, drift, forces, half kick, the
engine's order) and, for the orientations, the symmetric splitting of the free rigid body
into rotations about the body axes, each exact (Dullweber, Leimkuhler & McLachlan 1997,
J Chem Phys 107:5840; in quaternions the NO_SQUISH scheme of Miller et al. 2002, J Chem
Phys 116:8649): time-reversible, symplectic, and a product of unit quaternions, so |q| = 1
to round-off. Euler's equations (Peng 2020 Eq 11-12) are what this splitting integrates.
"""

import math

import numpy as np

from revdem_cli.kernels import inline, jit

SOLVER_TOL = 1e-14  # relative size of the last Newton step at convergence
SOLVER_ITERATIONS = 60
BISECTIONS = 200  # the cold start's bisection on λ
HESSIAN_FLOOR = 1e-6  # body coordinates / semi-axis below which a pointed tip's curvature is capped

SPLITTING_AXES = (2, 1, 0, 1, 2)  # body axes of the symmetric splitting, z y x y z
SPLITTING_FRACTIONS = (0.5, 0.5, 1.0, 0.5, 0.5)  # of the step, each

STABLE, UNSTABLE, NOT_CONVERGED = 0, 1, 2
"""What a trial found: bounded, growing, or a contact the solver could not find."""


@inline
def quaternion_product(p, q):
    """Hamilton product p q of quaternions (w, x, y, z)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


@jit
def rotation_matrix(q):
    """The body-to-world rotation matrix of the unit quaternion q (Peng 2020 Eq 7)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    matrix = np.empty((3, 3))
    matrix[0, 0] = w * w + x * x - y * y - z * z  # Peng 2020 Eq 7
    matrix[0, 1] = 2.0 * (x * y - w * z)
    matrix[0, 2] = 2.0 * (x * z + w * y)
    matrix[1, 0] = 2.0 * (x * y + w * z)
    matrix[1, 1] = w * w - x * x + y * y - z * z
    matrix[1, 2] = 2.0 * (y * z - w * x)
    matrix[2, 0] = 2.0 * (x * z - w * y)
    matrix[2, 1] = 2.0 * (y * z + w * x)
    matrix[2, 2] = w * w - x * x - y * y + z * z
    return matrix


@inline
def _turn(vector, axis, angle):
    """`vector` rotated by `angle` about coordinate axis `axis` (0, 1, 2)."""
    out = vector.copy()
    i, j = (axis + 1) % 3, (axis + 2) % 3
    c, s = math.cos(angle), math.sin(angle)
    out[i] = c * vector[i] - s * vector[j]
    out[j] = s * vector[i] + c * vector[j]
    return out


@jit
def free_rotation(q, momentum, moments, dt):
    """The free rigid body over dt: rotations about the body axes z, y, x, y, z for dt/2, dt/2,
    dt, dt/2, dt/2, each exact (Dullweber, Leimkuhler & McLachlan 1997). Returns (q, π)."""
    q = (q[0], q[1], q[2], q[3])
    for k in range(5):
        axis, fraction = SPLITTING_AXES[k], SPLITTING_FRACTIONS[k]
        angle = fraction * dt * momentum[axis] / moments[axis]  # ω_L = I⁻¹ π (Peng 2020 Eq 11)
        sine = math.sin(0.5 * angle)
        turn = (math.cos(0.5 * angle), sine * (axis == 0), sine * (axis == 1), sine * (axis == 2))
        q = quaternion_product(q, turn)
        momentum = _turn(momentum, axis, -angle)  # dπ/dt = π × ω_L (Peng 2020 Eq 11)
    return np.array(q), momentum


@jit
def shape_function(shape, u):
    """G = f^ε1 of a superquadric at body coordinates u, its gradient and Hessian.

    f = (|x/a|^(2/ε2) + |y/b|^(2/ε2))^(ε2/ε1) + |z/c|^(2/ε1) (Barr 1981). The Hessian's
    coordinates are floored at HESSIAN_FLOOR of each semi-axis, where a pointed shape
    (ε > 1) has unbounded curvature; G and its gradient are exact.
    """
    a, b, c, eps1, eps2 = shape[0], shape[1], shape[2], shape[3], shape[4]
    s, t = 2.0 / eps2, 2.0 / eps1
    r = t / s
    semi = (a, b, c)
    ax = np.abs(u) / np.array(semi)
    sign = np.sign(u)
    planar = ax[0] ** s + ax[1] ** s
    f = planar**r + ax[2] ** t  # Barr 1981, the inside-outside function
    # first derivatives of f
    df = np.zeros(3)
    scaled = planar ** (r - 1.0) if planar > 0.0 else (1.0 if r == 1.0 else 0.0)
    for i in range(2):
        df[i] = t * scaled * ax[i] ** (s - 1.0) * sign[i] / semi[i]
    df[2] = t * ax[2] ** (t - 1.0) * sign[2] / c
    # second derivatives of f, from coordinates kept off a pointed tip
    hx = np.maximum(ax, HESSIAN_FLOOR) if s < 2.0 or t < 2.0 else ax
    hp = hx[0] ** s + hx[1] ** s
    hscaled = hp ** (r - 1.0) if hp > 0.0 else (1.0 if r == 1.0 else 0.0)
    hf = np.zeros((3, 3))
    for i in range(2):
        share = hx[i] ** s / hp if hp > 0.0 else 0.0
        hf[i, i] = t * hscaled * hx[i] ** (s - 2.0) * ((r - 1.0) * s * share + s - 1.0)
        hf[i, i] /= semi[i] ** 2
    if hp > 0.0 and r != 1.0:
        cross = t * (r - 1.0) * s * hscaled * (hx[0] * hx[1]) ** (s - 1.0) / hp
        hf[0, 1] = hf[1, 0] = cross * sign[0] * sign[1] / (a * b)
    hf[2, 2] = t * (t - 1.0) * hx[2] ** (t - 2.0) / c**2
    # G = f^(2/t), homogeneous of degree two
    power = 2.0 / t
    g = f**power
    if f == 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    dg = power * f ** (power - 1.0) * df
    hg = power * f ** (power - 1.0) * (hf + (power - 1.0) * np.outer(df, df) / f)
    return g, dg, hg


@jit
def _world_shape(shape, position, rotation, x):
    """G, ∇G and the Hessian of one body at the world point x."""
    g, dg, hg = shape_function(shape, rotation.T @ (x - position))
    return g, rotation @ dg, rotation @ hg @ rotation.T


@jit
def _newton_step(shapes, positions, rotations, x, weight):
    """One Newton step on λ ∇G₁ + (1 - λ) ∇G₂ = 0, G₁ = G₂ (Schur complement on λ)."""
    g1, d1, h1 = _world_shape(shapes[0], positions[0], rotations[0], x)
    g2, d2, h2 = _world_shape(shapes[1], positions[1], rotations[1], x)
    residual = weight * d1 + (1.0 - weight) * d2
    matrix = weight * h1 + (1.0 - weight) * h2
    coupling = d1 - d2
    m_residual = np.linalg.solve(matrix, residual)
    m_coupling = np.linalg.solve(matrix, coupling)
    d_weight = (g1 - g2 - coupling @ m_residual) / (coupling @ m_coupling)
    return -m_residual - d_weight * m_coupling, d_weight


@jit
def _minimiser(shapes, positions, rotations, weight):
    """The point minimising λ G₁ + (1 - λ) G₂ (convex), by damped Newton from the centres."""
    x = (1.0 - weight) * positions[0] + weight * positions[1]
    size = shapes[0, :3].max() + shapes[1, :3].max()
    for _ in range(SOLVER_ITERATIONS):
        g1, d1, h1 = _world_shape(shapes[0], positions[0], rotations[0], x)
        g2, d2, h2 = _world_shape(shapes[1], positions[1], rotations[1], x)
        step = -np.linalg.solve(weight * h1 + (1.0 - weight) * h2, weight * d1 + (1 - weight) * d2)
        value = weight * g1 + (1.0 - weight) * g2
        length = 1.0
        for _ in range(60):  # backtrack until the convex function decreases
            trial = x + length * step
            t1 = _world_shape(shapes[0], positions[0], rotations[0], trial)[0]
            t2 = _world_shape(shapes[1], positions[1], rotations[1], trial)[0]
            if weight * t1 + (1.0 - weight) * t2 <= value:
                break
            length *= 0.5
        x = x + length * step
        if np.abs(length * step).max() <= SOLVER_TOL * size:
            break
    return x


@jit
def cold_contact(shapes, positions, rotations):
    """(x*, λ) from no earlier solution: bisection on λ (G₁ - G₂ falls with λ), then Newton
    (`solve_contact`, which the next force computation repeats and checks)."""
    low, high = 0.0, 1.0
    for _ in range(BISECTIONS):
        weight = 0.5 * (low + high)
        x = _minimiser(shapes, positions, rotations, weight)
        g1 = _world_shape(shapes[0], positions[0], rotations[0], x)[0]
        g2 = _world_shape(shapes[1], positions[1], rotations[1], x)[0]
        if g1 > g2:
            low = weight
        else:
            high = weight
        if high - low <= 1e-6:
            break
    solution = np.empty(4)
    solution[:3] = x
    solution[3] = 0.5 * (low + high)
    solve_contact(shapes, positions, rotations, solution)
    return solution


@jit
def solve_contact(shapes, positions, rotations, solution):
    """Newton on (x*, λ) from `solution`, updated in place; whether it converged."""
    size = shapes[0, :3].max() + shapes[1, :3].max()
    for _ in range(SOLVER_ITERATIONS):
        step, d_weight = _newton_step(shapes, positions, rotations, solution[:3], solution[3])
        solution[:3] += step
        solution[3] += d_weight
        if not (0.0 < solution[3] < 1.0) or not np.isfinite(solution).all():
            return False
        if np.abs(step).max() <= SOLVER_TOL * size and abs(d_weight) <= SOLVER_TOL:
            return True
    return False


@jit
def contact_geometry(shapes, positions, rotations, solution):
    """Each body's deepest point along the contact normal, the unit normal (from body 1 to
    body 2) and the overlap δ of a solved contact."""
    x = solution[:3]
    g1, d1, _ = _world_shape(shapes[0], positions[0], rotations[0], x)
    normal = d1 / np.sqrt(d1 @ d1)
    root = math.sqrt(g1)
    overlap = (positions[1] - positions[0]) @ normal * (1.0 / root - 1.0)  # (x₂ - x₁)·n (1/√S - 1)
    deepest = np.empty((2, 3))
    for i in range(2):
        deepest[i] = positions[i] + (x - positions[i]) / root
    return deepest, normal, overlap


@jit
def _contact_force(bodies, law, moments, rotations, anchors, point, normal, overlap):
    """Force on body 2 at the contact (body 1 takes its reaction) and the tangential stretch.

    Peng 2020 Eq 29 in each direction, F = -k x - c ẋ. Bonded (law[4] = 1): the normal
    spring also pulls (δ < 0), and the tangential spring joins the two material points that
    met at the start (`anchors`, body frames). Otherwise a collision: the normal
    spring-dashpot in compression only, frictionless.
    """
    positions, velocities, momenta = bodies[0], bodies[1], bodies[3]
    kn, ks, cn, cs = law[0], law[1], law[2], law[3]
    relative = np.zeros(3)
    for i in range(2):
        # ω_G = R ω_L (Peng 2020 Eq 15-16, R body to world as in `_half_kick`)
        spin = rotations[i] @ (momenta[i] / moments[i])
        velocity = velocities[i] + np.cross(spin, point - positions[i])
        relative += velocity if i == 1 else -velocity
    normal_speed = relative @ normal
    if law[4] == 0.0:
        if overlap <= 0.0:
            return np.zeros(3), 0.0
        return (kn * overlap - cn * normal_speed) * normal, 0.0
    tangential_speed = relative - normal_speed * normal
    stretch = positions[1] + rotations[1] @ anchors[1] - positions[0] - rotations[0] @ anchors[0]
    tangential = stretch - (stretch @ normal) * normal
    force = (kn * overlap - cn * normal_speed) * normal - ks * tangential - cs * tangential_speed
    return force, math.sqrt(tangential @ tangential)


@jit
def rotations_of(quaternions):
    """The rotation matrices of both bodies."""
    rotations = np.empty((2, 3, 3))
    for i in range(2):
        rotations[i] = rotation_matrix(quaternions[i])
    return rotations


@jit
def compute_forces(bodies, loads, law, shapes, moments, anchors, solution):
    """Forces and world moments on both bodies (`loads`), from the contact of the state.

    Returns (converged, δ, |tangential stretch|); `solution` is updated in place.
    """
    positions = bodies[0]
    rotations = rotations_of(bodies[2])
    converged = solve_contact(shapes, positions, rotations, solution)
    deepest, normal, overlap = contact_geometry(shapes, positions, rotations, solution)
    point = 0.5 * (deepest[0] + deepest[1])
    force, stretch = _contact_force(
        bodies, law, moments, rotations, anchors, point, normal, overlap
    )
    loads[0][1] = force
    loads[0][0] = -force
    for i in range(2):  # one line of action: angular momentum is conserved
        loads[1][i] = np.cross(point - positions[i], loads[0][i])  # Peng 2020 Eq 3-4
    return converged, overlap, stretch


@jit
def _half_kick(bodies, loads, masses, dt):
    """v += Δt/2 F/m; π += Δt/2 Rᵀ M_G (M_L = Rᵀ M_G: Peng 2020 Eq 5-6, whose R of Eq 7 maps
    the body's axes to the world's, so that the world-to-body map is its transpose, as
    `timestep.contact_kinematics` says)."""
    for i in range(2):
        rotation = rotation_matrix(bodies[2][i])
        bodies[1][i] += 0.5 * dt * loads[0][i] / masses[i]
        bodies[3][i] += 0.5 * dt * (rotation.T @ loads[1][i])


@jit
def step(bodies, loads, law, shapes, moments, masses, anchors, solution, dt):
    """One velocity-Verlet step of both bodies; a step of -dt undoes a step of dt.

    `bodies`: positions, velocities, quaternions (w, x, y, z) and body-frame angular momenta
    π = I ω_L, each an array with a row a body; `loads`: forces and world moments.
    Returns what `compute_forces` does.
    """
    _half_kick(bodies, loads, masses, dt)
    for i in range(2):
        bodies[0][i] += dt * bodies[1][i]
        q, momentum = free_rotation(bodies[2][i], bodies[3][i], moments[i], dt)
        bodies[2][i] = q
        bodies[3][i] = momentum
    result = compute_forces(bodies, loads, law, shapes, moments, anchors, solution)
    _half_kick(bodies, loads, masses, dt)
    return result


@jit
def stability_trial(bodies, loads, law, shapes, moments, masses, anchors, solution, dt, steps):
    """`steps` steps; the largest contact displacement √(δ² + |stretch|²) over the first and
    the second half, and a status: STABLE when all steps ran (the caller compares the
    halves), UNSTABLE when the displacement left float64 or exceeded the body size
    (law[5] of it), NOT_CONVERGED when the contact was lost to the solver."""
    early, late = 0.0, 0.0
    limit = law[5] * max(shapes[0, :3].max(), shapes[1, :3].max())
    for n in range(steps):
        converged, overlap, stretch = step(
            bodies, loads, law, shapes, moments, masses, anchors, solution, dt
        )
        size = math.sqrt(overlap * overlap + stretch * stretch)
        if not size <= limit:
            return UNSTABLE, early, late
        if not converged:
            return NOT_CONVERGED, early, late
        if n < steps // 2:
            early = max(early, size)
        else:
            late = max(late, size)
    return STABLE, early, late


@jit
def observe(bodies, law, moments, masses, overlap, stretch):
    """Energy (kinetic, both rotational parts, and the springs'), world linear and angular
    momentum, in one row of 7."""
    row = np.zeros(7)
    spring = overlap if law[4] != 0.0 else max(overlap, 0.0)
    energy = 0.5 * law[0] * spring * spring + 0.5 * law[1] * stretch * stretch
    for i in range(2):
        velocity, momentum = bodies[1][i], bodies[3][i]
        energy += 0.5 * masses[i] * (velocity @ velocity) + 0.5 * np.sum(momentum**2 / moments[i])
        linear = masses[i] * velocity
        row[1:4] += linear
        spin = rotation_matrix(bodies[2][i]) @ momentum  # L = R π
        row[4:7] += np.cross(bodies[0][i], linear) + spin
    row[0] = energy
    return row


@jit
def trajectory(bodies, loads, law, shapes, moments, masses, anchors, solution, dt, steps, every):
    """`steps` steps (dt < 0: backwards); `observe`'s row every `every` steps, the first
    before any step, and whether the contact solver converged at every step."""
    rows = np.empty((steps // every + 1, 7))
    converged, overlap, stretch = compute_forces(
        bodies, loads, law, shapes, moments, anchors, solution
    )
    rows[0] = observe(bodies, law, moments, masses, overlap, stretch)
    for n in range(1, steps + 1):
        ok, overlap, stretch = step(
            bodies, loads, law, shapes, moments, masses, anchors, solution, dt
        )
        converged = converged and ok
        if n % every == 0:
            rows[n // every] = observe(bodies, law, moments, masses, overlap, stretch)
    return rows, converged
