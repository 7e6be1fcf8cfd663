"""The revdem engine itself on one linear sphere contact: its largest stable Δt, by bisection.

Two free spheres cannot be held in one contact: the contact only pushes, and gravity
accelerates both alike, so a pair in contact flies apart within half a contact period
(π/ω, about 1.6 steps at the critical Δt of 2/ω). A lasting contact needs a load, and a load
needs a third body; a third contact on either sphere would stiffen its modes. So the engine
runs a light sphere resting under gravity on a heavy sphere that rests on a plane: the light
sphere has one contact, and the heavy one is nearly immovable.

A contact between spheres sees the pair only through its inverse masses: A_n = 1/m₁ + 1/m₂
along the normal and A_t = A_n + r₁²/I₁ + r₂²/I₂ = 7/2 A_n across it (Peng 2020 Eq 26,
I = 2/5 m r²). The light sphere's mass is chosen so that the engine's pair has the A_n, and
hence the A_t, of the two given spheres; the heavy sphere's own wall contact then moves the
contact frequencies by a relative amount of order (m_light/M)², 1e-6 here.

The light sphere starts at its resting overlap with a normal velocity and, with shear
springs, a tangential velocity and spin in the shape of the fast tangential mode (contact
point and centre moving together at 7/2 : 1, not the rolling mode). A Δt is stable when the
kinetic energy stays within GROWTH times its starting value for STEPS steps: above the
limit it grows by (1 + √(8ε))² a step at Δt = (1 + ε) × limit, about 7e9-fold over a trial
at ε = 1e-6.
"""

from __future__ import annotations

import math

import numpy as np

from revdem_cli.kernels.contact import viscous_coefficient
from revdem_cli.timestep.criteria import Contact
from revdem_cli.timestep.shapes import Body

HEAVY = 1e3  # mass of the heavy sphere times A_n
PRELOAD = 1e-8  # resting overlap of the light sphere / its radius
KICK = 1e-4  # starting normal amplitude / resting overlap (grows as 1/√(1 - (Δt/limit)²))
STEPS = 4000  # steps per trial Δt
GROWTH = 2.0  # kinetic energy / its starting value that counts as unstable


def _sphere(position, velocity=(0.0, 0.0, 0.0), spin=(0.0, 0.0, 0.0), **particle) -> dict:
    return {"position": position, "velocity": velocity, "angular_velocity": spin, **particle}


def _contact_law(contact: Contact, inverse_mass: float) -> dict:
    """The engine's contact law: damping as a fraction of 2√(k m*), m* = 1/A_n."""
    law = {
        "model": "linear",
        "kn": contact.kn,
        "normal_damping": contact.cn / viscous_coefficient(1.0, 1.0 / inverse_mass, contact.kn),
    }
    if contact.ks == 0.0:
        return law
    return law | {
        "tangential": "linear",
        "ks": contact.ks,
        "friction": math.inf,
        "tangential_damping": contact.cs / viscous_coefficient(1.0, 1.0 / inverse_mass, contact.ks),
    }


def resting_pair(body1: Body, body2: Body, contact: Contact, order: int = 0):
    """The engine's scenario: a light sphere (radius of body1) on a heavy one (radius of body2),
    stepped by velocity Verlet (order 0) or with the velocity predictor of that order.

    Masses: M = HEAVY/A_n and 1/m_light = A_n - 1/M, so the pair's A_n is that of body1 and
    body2. Both rest at their equilibrium overlaps under gravity along -z on the plane z = 0.
    """
    from revdem_cli.config import Scenario

    inverse_mass = 1.0 / body1.mass + 1.0 / body2.mass
    heavy = HEAVY / inverse_mass
    light = 1.0 / (inverse_mass - 1.0 / heavy)
    r_light, r_heavy = body1.half_lengths[0], body2.half_lengths[0]
    gravity = PRELOAD * r_light * contact.kn / light
    z_heavy = r_heavy - (heavy + light) * gravity / contact.kn
    z_light = z_heavy + r_heavy + r_light - PRELOAD * r_light
    normal = KICK * PRELOAD * r_light * math.sqrt(contact.kn * inverse_mass)
    tangential = normal if contact.ks else 0.0
    # spin -5/2 v/r about y: the contact point moves at 7/2 v, the fast tangential mode
    spin = (0.0, -2.5 * tangential / r_light, 0.0)
    elastic = {"shear_modulus": 1e9, "poisson_ratio": 0.2}  # not used by the linear law

    def material(mass, radius):
        return {"density": mass / (4.0 / 3.0 * math.pi * radius**3)} | elastic

    return Scenario.model_validate(
        {
            "name": "resting_pair",
            "materials": {"light": material(light, r_light), "heavy": material(heavy, r_heavy)},
            "contact": _contact_law(contact, inverse_mass),
            "particles": [
                _sphere((0.0, 0.0, z_heavy), material="heavy", radius=r_heavy),
                _sphere(
                    (0.0, 0.0, z_light),
                    (tangential, 0.0, normal),
                    spin,
                    material="light",
                    radius=r_light,
                ),
            ],
            "walls": [
                {
                    "name": "floor",
                    "type": "plane",
                    "material": "heavy",
                    "point": (0.0, 0.0, 0.0),
                    "normal": (0.0, 0.0, 1.0),
                }
            ],
            "gravity": (0.0, 0.0, -gravity),
            "integrator": {"dt": 1.0}  # each trial sets its own
            | ({"scheme": "trvp", "trvp_order": order} if order else {}),
            "stages": [{"name": "rest", "steps": STEPS}],
        }
    )


def engine_is_stable(scenario, dt: float) -> bool:
    """Whether the engine keeps the kinetic energy of `scenario` within GROWTH of its start."""
    from revdem_cli.io.tape import no_tape
    from revdem_cli.kernels.integrate import OK, advance
    from revdem_cli.stage import Model, stepping_bundles
    from revdem_cli.state import empty_events, initial_state

    model = Model.of(scenario)
    state = initial_state(scenario)
    start = model.observe(state, model.dynamics)[model.layout.column("kinetic_energy")]
    obs, steps = model.buffers(STEPS)
    stepping = model.stepping(dt, 0, STEPS, 1)._replace(overlap_limit=np.inf)  # by energy alone
    bundles = stepping_bundles(state, model, model.dynamics, model.law)
    status, _, rows, _ = advance(
        *bundles, empty_events(), no_tape(), stepping, 0, STEPS, STEPS, obs, steps
    )
    kinetic = obs[:rows, model.layout.column("kinetic_energy")]
    return status == OK and bool(np.all(kinetic <= GROWTH * start))


def engine_limit(body1: Body, body2: Body, contact: Contact, order: int = 0) -> float | None:
    """Largest Δt at which the revdem engine keeps a sphere contact bounded; None unless
    both bodies are spheres. `contact.ks == 0` is a frictionless contact (no shear springs);
    `order`: that of the velocity predictor the damping reads (0: velocity Verlet)."""
    from revdem_cli.timestep.verify import largest_stable_dt

    if body1.shape != "sphere" or body2.shape != "sphere":
        return None
    scenario = resting_pair(body1, body2, contact, order)
    inverse_mass = 1.0 / body1.mass + 1.0 / body2.mass
    guess = 1.0 / math.sqrt(max(contact.kn, contact.ks) * inverse_mass)
    return largest_stable_dt(lambda dt: engine_is_stable(scenario, dt), guess)
