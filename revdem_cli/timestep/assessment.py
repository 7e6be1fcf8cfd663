"""All criteria for one particle pair, set beside the integrator's own limits, and the Δt to use."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from revdem_cli.timestep import criteria, rigid_pair, verify
from revdem_cli.timestep.criteria import Contact
from revdem_cli.timestep.engine_pair import engine_limit
from revdem_cli.timestep.shapes import Body

AGREEMENT_RTOL = 1e-3  # the integration resolves a stability limit to a few 1e-4
CONSERVATIVE_RATIO = 1.01
"""An integrated limit of the bodies' own dynamics this far above the reference (well past the
integrations' resolution) says the criteria are conservative for the pair."""


@dataclass(frozen=True)
class Estimate:
    """One time step: `dt` in s, None where the criterion does not apply, inf for no limit."""

    key: str
    label: str
    source: str
    dt: float | None
    not_applicable: str = "overdamped"
    """Why `dt` is None: the contact is "overdamped" or "critically damped" for it."""

    @property
    def reason(self) -> str | None:
        """Why there is no time step: where it does not apply, has no limit, or is never
        stable (an integrated limit of 0); None where there is one."""
        if self.dt is None:
            return f"does not apply: {self.not_applicable}"
        if math.isinf(self.dt):
            return "no limit"
        return "never stable" if self.dt == 0.0 else None


@dataclass(frozen=True)
class Assessment:
    """Criteria (formulas), checks (the integrators' limits) and the recommended Δt.

    `reference` is the stability limit every translation criterion is compared with: the
    smallest integrated limit when checks ran, the velocity-Verlet formula otherwise.
    `inverse_mass` is A_max, the shear direction's inverse mass and the one the damping
    number N scales with; `normal_inverse_mass` the normal direction's (`criteria.inverse_masses`:
    1/m₁ + 1/m₂ for two spheres, A_max otherwise).
    """

    bodies: tuple[Body, Body]
    contact: Contact
    damping_number: float
    omega_max: float | None
    inverse_mass: float
    normal_inverse_mass: float
    criteria: tuple[Estimate, ...]
    checks: tuple[Estimate, ...]
    reference: Estimate
    recommended: float
    findings: tuple[str, ...]

    def to_dict(self) -> dict:
        """Plain JSON-ready data; infinite time steps become None."""

        def estimate(e: Estimate) -> dict:
            found = {"label": e.label, "source": e.source, "dt": _finite(e.dt)}
            return found if e.reason is None else found | {"dt": None, "reason": e.reason}

        def estimates(items):
            return {e.key: estimate(e) for e in items}

        return {
            "particles": [asdict(b) | {"b_max": criteria.b_max(b)} for b in self.bodies],
            "contact": asdict(self.contact) | {"damping_number": self.damping_number},
            "omega_max": self.omega_max,
            "a_max": self.inverse_mass,
            "a_normal": self.normal_inverse_mass,
            "criteria": estimates(self.criteria),
            "checks": estimates(self.checks),
            "reference": self.reference.key,
            "recommended_dt": _finite(self.recommended),
            "findings": list(self.findings),
        }


def _finite(value: float | None) -> float | None:
    return None if value is None or math.isinf(value) else value


def ratio_to(reference: Estimate, estimate: Estimate) -> float | None:
    """A translation estimate over the reference limit; None where there is nothing to compare."""
    if not estimate.dt or estimate.key == "rotation" or not reference.dt:
        return None  # none, or never stable (0): no ratio to show
    return estimate.dt / reference.dt


def _translation(formula, contact: Contact, inverse_masses: tuple[float, float]) -> float | None:
    """A per-direction criterion, each direction with its own inverse mass, taken in its more
    restrictive direction."""
    return criteria.smallest(formula(k, c, a) for k, c, a in contact.directions(inverse_masses))


def _undamped_source(contact: Contact, inverse_masses: tuple[float, float]) -> str:
    """Eq 48, 2/√(k_n A_max), where the stricter direction gives it; else Eq 47 with that
    direction's own stiffness and inverse mass (k_s > k_n, or two spheres' normal A_n)."""
    stiffest = max(k * a for k, _, a in contact.directions(inverse_masses))
    return "Peng 2020 Eq 48" if stiffest == contact.kn * inverse_masses[1] else "Peng 2020 Eq 47"


def _damped_state(pairs) -> str:
    """ "critically damped" where each (c, critical c) pair that is not underdamped is at its
    critical value (to 1e-12), else "overdamped"."""
    beyond = [(c, critical) for c, critical in pairs if c >= critical * (1.0 - 1e-12)]
    exact = all(math.isclose(c, critical, rel_tol=1e-12) for c, critical in beyond)
    return "critically damped" if exact else "overdamped"


def _criteria(body1, body2, contact, inverse_masses, omega_max, order=0) -> tuple[Estimate, ...]:
    damped = contact.cn > 0.0 or contact.cs > 0.0
    mass = min(body1.mass, body2.mass)
    directions = contact.directions(inverse_masses)
    items = (
        Estimate(
            "amplification",
            "amplification matrix",
            "Peng 2020 Eq 46" if damped else _undamped_source(contact, inverse_masses),
            _translation(criteria.dt_amplification, contact, inverse_masses),
        ),
        Estimate(
            "belytschko",
            "Belytschko, 2/ω",
            "Peng 2020 Eq 34" if damped else "Peng 2020 Eq 35",
            _translation(criteria.dt_belytschko, contact, inverse_masses),
            _damped_state((c, criteria.critical_damping(k, a)) for k, c, a in directions),
        ),
        Estimate(
            "collision",
            "collision time (Silbert)",
            "Peng 2020 Eq 36",
            criteria.dt_collision(contact.kn, contact.cn, mass),
            # Eq 36's root vanishes at c_n² = 8 k_n m
            _damped_state([(contact.cn, math.sqrt(8.0 * contact.kn * mass))]),
        ),
        Estimate(
            "velocity_verlet",
            "velocity-Verlet limit",
            "Eq 30, velocity Verlet",
            _translation(criteria.dt_velocity_verlet, contact, inverse_masses),
        ),
    )
    if order:

        def limit(k: float, c: float, a: float) -> float:
            return criteria.dt_velocity_predictor(k, c, a, order)

        items += (
            Estimate(
                "velocity_predictor",
                f"velocity-Verlet limit, trvp k = {order}",
                "Eq 30, velocity Verlet, Kolafa & Lisal 2011",
                _translation(limit, contact, inverse_masses),
            ),
        )
    if omega_max is None:
        return items
    rotation = criteria.dt_rotation(omega_max, criteria.b_max(body1), criteria.b_max(body2))
    return items + (
        Estimate("rotation", f"rotation, ω_max = {omega_max:g} rad/s", "Peng 2020 Eq 56", rotation),
    )


def _check_in_range(items: tuple[Estimate, ...], body1: Body, body2: Body) -> None:
    """FloatingPointError where a criterion is not what its formula gives for positive finite
    inputs, a positive finite Δt or None where it does not apply (∞ only for the rotation of
    bodies without gyroscopic coupling, B_max = 0, Peng 2020 Eq 56): a product or a square
    that left float64 on the way gives NaN, ∞ or 0 instead, without raising."""
    uncoupled = criteria.b_max(body1) + criteria.b_max(body2) == 0.0
    for e in items:
        allowed_infinite = e.key == "rotation" and uncoupled
        if e.dt is not None and not (e.dt > 0.0 and (math.isfinite(e.dt) or allowed_infinite)):
            raise FloatingPointError(f"{e.key}: Δt {e.dt} outside float64's range")


def _integrated(body1, body2, contact, order=0) -> tuple[Estimate, ...]:
    """The limits the engine's verifiers find, leaving out those that do not apply; with a
    velocity predictor of `order`, the engine's limit with it too."""
    found = [
        Estimate(
            f"{key}_integrated",
            f"{label} limit, integrated",
            source,
            verifier(body1, body2, contact),
        )
        for key, (label, source, verifier) in verify.ENGINE_VERIFIERS.items()
    ]
    if order:
        label = f"revdem engine, spheres, trvp k = {order}"
        limit = engine_limit(body1, body2, contact, order)
        found.append(Estimate("engine_predictor_integrated", label, "kernels.integrate", limit))
    return tuple(e for e in found if e.dt is not None)


def _rigid(body1, body2, contact) -> tuple[tuple[Estimate, ...], tuple[str, ...]]:
    """The two rigid bodies integrated (`rigid_pair`): each tangent configuration (Figure 2
    and the coaxial tips), the worst random draw, and the smallest of all as
    `rigid_body_integrated`; none where `rigid_pair` does not apply. With them, a sentence
    on every configuration whose contact the solver lost."""
    limits = rigid_pair.rigid_body_limits(body1, body2, contact)
    if limits is None:
        return (), (
            "Two rigid bodies are integrated only as superquadrics with exponents below 2 "
            "(smooth surfaces): not this pair.",
        )
    lost = tuple(
        f"Rigid pair, configuration {name}: the contact solver lost the contact (a flat face "
        "on a face, an edge or a vertex); it is left out of the integrated limit."
        for name, dt in limits.items()
        if dt is None
    )
    found = {name: dt for name, dt in limits.items() if dt is not None}
    if not found:
        return (), lost
    source = "kernels.rigid_pair, bonded contact"
    placed = {f"Figure 2{name}": name for name in "ABC"} | {"coaxial tips": "tips"}
    rows = tuple(
        Estimate(f"rigid_body_{name}_integrated", f"rigid pair, {words}", source, found[name])
        for words, name in placed.items()
        if name in found
    )
    drawn = {name: dt for name, dt in found.items() if name not in placed.values()}
    if drawn:
        worst = min(drawn, key=drawn.get)
        rows += (
            Estimate(
                "rigid_body_random_integrated",
                f"rigid pair, worst of {len(drawn)} draws",
                f"{source}, seed {rigid_pair.SEED}",
                drawn[worst],
            ),
        )
    smallest = Estimate(
        "rigid_body_integrated",
        "rigid pair, integrated",
        "smallest of the rigid pair's rows",
        min(found.values()),
    )
    return rows + (smallest,), lost


def _euler(body1, body2, contact) -> tuple[Estimate, ...]:
    return (
        Estimate(
            "eq40_real_eigenvalue",
            "Euler scheme, real λ = -1",
            "Peng 2020 Eq 40, 44",
            verify.eq40_real_eigenvalue_limit(body1, body2, contact),
        ),
        Estimate(
            "eq40_all_eigenvalues",
            "Euler scheme, all |λ| ≤ 1",
            "Peng 2020 Eq 40",
            verify.eq40_limit(body1, body2, contact),
        ),
    )


def _own_dynamics(checks) -> list[Estimate]:
    """The integrated limits of the bodies themselves under the scheme in use: the engine's,
    with the velocity predictor where one reads the damping, and under velocity Verlet the
    two rigid bodies'."""
    found = {c.key: c for c in checks}
    keys = ("engine_predictor_integrated",)
    if keys[0] not in found:
        keys = ("engine_integrated", "rigid_body_integrated")
    return [found[key] for key in keys if key in found]


def _findings(items, checks, reference, predictor: bool = False) -> tuple[str, ...]:
    """Plain sentences on every criterion that disagrees with the reference limit; the
    bodies' own dynamics, integrated with velocity Verlet, set beside it only where it is
    velocity Verlet's too (not the velocity predictor's, a `predictor` reference)."""
    lines = []
    for estimate in items:
        ratio = ratio_to(reference, estimate)
        if ratio is None or abs(ratio - 1.0) <= AGREEMENT_RTOL:
            continue
        verdict = "unsafe" if ratio > 1.0 else "stable but conservative"
        lines.append(
            f"{estimate.source} ({estimate.label}) is {ratio:.3g} × the reference, "
            f"{reference.label}: {verdict}."
        )
    rigid = next((c for c in checks if c.key == "rigid_body_integrated"), None)
    if rigid is not None:
        formulas = [e for e in items if e.dt is not None and e.key != "rotation"]
        above = [e for e in formulas if e.dt > rigid.dt * (1.0 + AGREEMENT_RTOL)]
        if len(above) == len(formulas):
            lines.append(
                f"The two rigid bodies integrated are stable only up to {rigid.dt:.4e} s, "
                "below every formula: no formula here is safe for this pair."
            )
        for estimate in above:
            lines.append(
                f"{estimate.source} ({estimate.label}) is {estimate.dt / rigid.dt:.3g} × the "
                f"limit of the two rigid bodies integrated ({rigid.dt:.4e} s): unsafe for them."
            )
    for own in () if predictor else _own_dynamics(checks):
        ratio = own.dt / reference.dt
        if ratio > CONSERVATIVE_RATIO:
            lines.append(
                f"The {own.label} ({own.dt:.4e} s), the bodies' own dynamics, is {ratio:.3g} × "
                f"the reference, {reference.label}: the criteria are conservative for this pair."
            )
    euler = {c.key: c.dt for c in checks}
    if "eq40_all_eigenvalues" in euler:
        stable_up_to = (
            "at no Δt"
            if euler["eq40_all_eigenvalues"] == 0.0
            else f"only up to {euler['eq40_all_eigenvalues']:.4e} s"
        )
        lines.append(
            f"The Euler scheme of Eq 40 is stable {stable_up_to}: its complex eigenvalues leave "
            f"the unit circle before its real eigenvalue reaches -1 at "
            f"{euler['eq40_real_eigenvalue']:.4e} s, the Δt of Eq 46."
        )
    return tuple(lines)


def assess(
    body1: Body,
    body2: Body,
    kn: float,
    ks: float,
    damping_number: float = 0.0,
    omega_max: float | None = None,
    check: bool = False,
    trvp_order: int = 0,
) -> Assessment:
    """Every criterion for the pair; with `check`, the integrators' own limits beside them.

    Damping follows the paper's number N: c_n = c_s = N √(k_n / A_max), c_s = 0 for a
    frictionless contact (ks = 0), which has no shear force. The recommended Δt
    is the smallest of the velocity-Verlet limit, the integrated limits (with `check`) and
    the rotation-dominant Δt (with omega_max). With `trvp_order` > 0 the damping reads the
    velocity predictor of that order (integrator.scheme = 'trvp'): its limit replaces the
    velocity-Verlet formula's in the recommendation, and the checks add the engine's with it.
    A criterion that leaves float64's range raises ArithmeticError (`_check_in_range`).
    """
    inverse_masses = criteria.inverse_masses(body1, body2)
    inverse_mass = inverse_masses[1]  # A_max
    damping = criteria.damping_from_number(damping_number, kn, inverse_mass)
    # frictionless (ks = 0): no shear spring and no shear dashpot
    contact = Contact(kn=kn, ks=ks, cn=damping, cs=damping if ks > 0.0 else 0.0)
    items = _criteria(body1, body2, contact, inverse_masses, omega_max, trvp_order)
    _check_in_range(items, body1, body2)
    rigid, lost = _rigid(body1, body2, contact) if check else ((), ())
    integrated = _integrated(body1, body2, contact, trvp_order) + rigid if check else ()
    checks = integrated + _euler(body1, body2, contact) if check else ()
    scheme = "velocity_predictor" if trvp_order else "velocity_verlet"
    formula = next(e for e in items if e.key == scheme)
    # the reference is the scheme's own: with the predictor, the engine's limit with it (for
    # spheres), else its formula; the velocity-Verlet limits integrated are another scheme's
    own = [e for e in integrated if (e.key == "engine_predictor_integrated") == bool(trvp_order)]
    reference = min(own, key=lambda e: e.dt) if own else formula
    limits = [formula, *integrated, *(e for e in items if e.key == "rotation")]
    return Assessment(
        bodies=(body1, body2),
        contact=contact,
        damping_number=damping_number,
        omega_max=omega_max,
        inverse_mass=inverse_mass,
        normal_inverse_mass=inverse_masses[0],
        criteria=items,
        checks=checks,
        reference=reference,
        recommended=min(e.dt for e in limits),
        findings=_findings(items, checks, reference, trvp_order > 0) + lost,
    )
