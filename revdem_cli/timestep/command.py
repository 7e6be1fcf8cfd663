"""`revdem dt`: critical time steps of two convex, centrally symmetric particles in contact."""

from __future__ import annotations

import contextlib
import math
import sys
from dataclasses import astuple, dataclass, replace
from pathlib import Path
from typing import Annotated

import typer

from revdem_cli.errors import InputError, WriteFailed, given_options
from revdem_cli.options import file_to_read, named_file, named_folder

SHAPES = ("sphere", "ellipsoid", "superquadric", "polyhedron")
SIZES = {
    "sphere": ("radius",),
    "ellipsoid": ("semi_axes",),
    "superquadric": ("semi_axes", "exponents"),
    "polyhedron": ("vertices",),
}
"""The options that size a particle of each shape (`_Particle`'s fields)."""
SWEEPABLE = ("kn", "ks", "density", "damping", "omega-max")
MAX_SWEEP = 10_000
"""Most values one --sweep takes (each one an assessment, several with --verify)."""


@dataclass(frozen=True)
class _Particle:
    """The options that describe one particle, as given."""

    shape: str | None
    radius: float | None
    semi_axes: tuple[float, float, float] | None
    exponents: tuple[float, float] | None
    vertices: Path | None
    density: float | None

    def or_else(self, first: _Particle) -> _Particle:
        """These options, with every one not given taken from `first`."""
        return _Particle(
            *(a if a is not None else b for a, b in zip(astuple(self), astuple(first), strict=True))
        )


def _positive(option: str, value: float | None) -> float:
    if value is None:
        raise InputError(f"{option} is required")
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{option} must be a positive number, got {value:g}")
    return value


def _non_negative(option: str, value: float) -> float:
    if not (math.isfinite(value) and value >= 0.0):
        raise InputError(f"{option} must be zero or positive, got {value:g}")
    return value


def _a(shape: str) -> str:
    """`shape` with its indefinite article: a sphere, an ellipsoid."""
    return f"{'an' if shape[0] in 'aeiou' else 'a'} {shape}"


def _check_sizes(given: _Particle, shape: str | None, prefix: str) -> None:
    """InputError for a size option `given` that a particle of `shape` does not take (an
    option silently left unused would leave its user believing it counted)."""
    if shape not in SIZES:
        return  # `_described` names the shape
    for name in ("radius", "semi_axes", "exponents", "vertices"):
        if getattr(given, name) is not None and name not in SIZES[shape]:
            takes = ", ".join(f"--{prefix}{size.replace('_', '-')}" for size in SIZES[shape])
            raise InputError(
                f"--{prefix}{name.replace('_', '-')} does not size {_a(shape)}; it takes {takes}"
            )


def _representable(particle: _Particle, prefix: str):
    """The Body the options describe where its volume, mass, moments and half-lengths are
    positive finite float64 numbers, else None."""
    try:
        body = _described(particle, prefix)
        sizes = (body.volume, body.mass, *body.moments, *body.half_lengths)
    except ArithmeticError:  # a size whose powers leave float64 on the way
        return None
    return body if all(math.isfinite(v) and v > 0.0 for v in sizes) else None


def _body(particle: _Particle, prefix: str):
    """The Body the options describe, its volume, mass, moments and half-lengths positive
    finite float64 numbers; InputError names the options at fault: a superquadric's
    exponents where the ellipsoid of its semi-axes is representable (below about 1e-154,
    (2/ε)² in `shapes._superquadric_octant_integral` overflows), else its size."""
    body = _representable(particle, prefix)
    if body is not None:
        return body
    ellipsoid = replace(particle, shape="ellipsoid", exponents=None)
    if particle.shape == "superquadric" and _representable(ellipsoid, prefix) is not None:
        fault, advice = "exponents", "give exponents above about 1e-150"
    else:
        size = {"sphere": "radius", "polyhedron": "vertices"}.get(particle.shape, "semi-axes")
        fault, advice = size, "give sizes in metres within about 1e-60 to 1e60"
    raise InputError(
        f"--{prefix}{fault} with --{prefix}density {particle.density:g}: the "
        f"{particle.shape}'s volume, mass and moments of inertia are not all positive "
        f"finite float64 numbers; {advice}"
    )


def _described(particle: _Particle, prefix: str):
    """The Body the options describe; InputError names the option at fault."""
    from revdem_cli.timestep import shapes

    def option(name: str) -> str:
        return f"--{prefix}{name}"

    if particle.shape not in SHAPES:
        given = "is required" if particle.shape is None else f"got {particle.shape!r}"
        raise InputError(f"{option('shape')} must be one of {', '.join(SHAPES)}; {given}")
    density = _positive(option("density"), particle.density)
    if particle.shape == "sphere":
        return shapes.sphere(_positive(option("radius"), particle.radius), density)
    if particle.shape == "polyhedron":
        if particle.vertices is None:
            raise InputError(f"{option('vertices')} is required for a polyhedron")
        vertices = shapes.read_vertices(particle.vertices)
        return shapes.polyhedron(vertices, density, source=f"vertex file {particle.vertices}")
    if particle.semi_axes is None:
        raise InputError(f"{option('semi-axes')} is required for {_a(particle.shape)}")
    a, b, c = (_positive(option("semi-axes"), value) for value in particle.semi_axes)
    if particle.shape == "ellipsoid":
        return shapes.ellipsoid(a, b, c, density)
    if particle.exponents is None:
        raise InputError(f"{option('exponents')} is required for a superquadric")
    if not all(0.0 < e <= 2.0 for e in particle.exponents):
        raise InputError(f"{option('exponents')} must lie in (0, 2] for a convex superquadric")
    return shapes.superquadric(a, b, c, *particle.exponents, density)


@dataclass(frozen=True)
class _Case:
    """Everything one assessment needs, as given on the command line."""

    first: _Particle
    other: _Particle
    kn: float | None
    ks: float | None
    damping: float
    omega_max: float | None
    trvp_order: int = 0

    def with_value(self, name: str, value: float) -> _Case:
        """This case with one sweepable option set to `value`."""
        if name == "density":
            return replace(self, first=replace(self.first, density=value))
        return replace(self, **{name.replace("-", "_"): value})

    def assess(self, check: bool):
        from revdem_cli.timestep.assessment import assess

        other = self.other.or_else(self.first)
        _check_sizes(self.first, self.first.shape, "")
        _check_sizes(self.other, other.shape, "other-")
        first, other = _body(self.first, ""), _body(other, "other-")
        kn = _positive("--kn", self.kn)
        ks = _non_negative("--ks", self.ks if self.ks is not None else kn)
        _non_negative("--damping", self.damping)
        if self.omega_max is not None:
            _positive("--omega-max", self.omega_max)
        if not 0 <= self.trvp_order <= 4:
            raise InputError(
                f"--trvp-order must be 0 (velocity Verlet) to 4, got {self.trvp_order}"
            )
        try:
            return assess(
                first, other, kn, ks, self.damping, self.omega_max, check, self.trvp_order
            )
        except ArithmeticError:  # a product, square or quotient left float64 on the way
            raise self._outside_float64(first, other, kn) from None

    def _outside_float64(self, first, other, kn: float) -> InputError:
        """The error for criteria that left float64's range, naming the options whose
        products do: k A_max enters every translation criterion times 4 and under a root,
        2 k_n Eq 36 on its own, c A_max squared (Peng 2020 Eq 26, 30, 34, 36, 46), ω_max
        B_max divides 2 (Eq 54, 56)."""
        from revdem_cli.timestep.criteria import a_max, b_max, damping_from_number

        largest = sys.float_info.max
        inverse_mass = a_max(first, other)
        stiffnesses = {"kn": kn, "ks": self.ks}  # --ks not given is --kn
        named = [
            f"--{name} {k:g}"
            for name, k in stiffnesses.items()
            if k and not (0.0 < k * inverse_mass <= largest / 4.0 and 2.0 * k <= largest)
        ]
        damping = damping_from_number(self.damping, kn, inverse_mass) * inverse_mass
        if not damping * damping <= largest:
            named.append(f"--damping {self.damping:g}")
        if self.omega_max is not None:
            coupling = self.omega_max * (b_max(first) + b_max(other))
            if coupling and not 2.0 / largest <= coupling <= largest:
                named.append(f"--omega-max {self.omega_max:g}")
        given = ", ".join(named) + " with " if named else ""
        return InputError(
            f"{given}the particles' sizes and densities (A_max = {inverse_mass:.3g} 1/kg, "
            "Peng 2020 Eq 26) give numbers outside float64's range in the criteria (a product "
            "or a square overflows or underflows); give SI values closer to 1"
        )


PARTICLE_FIELDS = tuple(_Particle.__dataclass_fields__)
"""What describes a particle: shape, radius, semi_axes, exponents, vertices, density."""


def assess_pair(
    first: dict, other: dict, kn, ks, damping, omega_max, trvp_order: int, verify: bool
) -> dict:
    """`revdem dt --json` of two particles, each a dict of some of PARTICLE_FIELDS (the
    other's not given taken from the first's), checked as the command line checks them."""

    def particle(given: dict) -> _Particle:
        return _Particle(**{name: given.get(name) for name in PARTICLE_FIELDS})

    case = _Case(particle(first), particle(other), kn, ks, damping, omega_max, trvp_order)
    return case.assess(verify).to_dict()


def _sweep_values(spec: str) -> tuple[str, list[float]]:
    """`name=start:stop:count` as the name and `count` evenly spaced values, each one the
    option takes (its ends are checked as the option is, naming --sweep)."""
    import numpy as np

    name, _, span = spec.partition("=")
    if name not in SWEEPABLE:
        raise InputError(f"--sweep {spec!r}: the parameter must be one of {', '.join(SWEEPABLE)}")
    try:
        start, stop, count = span.split(":")
        start, stop, count = float(start), float(stop), int(count)
    except ValueError:
        raise InputError(f"--sweep {spec!r}: expected {name}=START:STOP:COUNT") from None
    if not 1 <= count <= MAX_SWEEP:
        raise InputError(f"--sweep {spec!r}: COUNT must be between 1 and {MAX_SWEEP}")
    if count == 1 and start != stop:  # one value cannot reach STOP: it was dropped
        raise InputError(
            f"--sweep {spec!r}: COUNT 1 takes START alone; give START = STOP or a COUNT of 2 "
            "or more"
        )
    check = _non_negative if name in ("ks", "damping") else _positive  # as --ks, --damping
    for end in (start, stop):
        check(f"--sweep {spec!r}: {name}", end)
    values = np.linspace(start, stop, count)
    return name, values.tolist()


def _sweep_conflicts(ctx, spec: str, name: str) -> None:
    """InputError where an option sets what --sweep sweeps: the swept option itself, or
    --other-density, which leaves a swept --density to particle 1 alone."""
    swept = name.replace("-", "_")
    given = given_options(ctx, (swept,))
    if given:
        raise InputError(f"--sweep {spec!r} sets {given[0]}; leave out {given[0]}")
    if swept == "density" and given_options(ctx, ("other_density",)):
        raise InputError(
            f"--sweep {spec!r} sweeps both particles' density, and --other-density sets "
            "particle 2's; leave out --other-density"
        )


def _working(what: str, check: bool):
    """A spinner on standard error saying what `dt` is doing; with `check` (--verify: the
    pair integrated, seconds a case), first the line a run prints where numba's cache lacks
    the kernels it integrates with, which then compile (`progress.COMPILING`)."""
    from rich.console import Console

    from revdem_cli.kernels.integrate import advance
    from revdem_cli.kernels.rigid_pair import stability_trial
    from revdem_cli.report import progress

    console = Console(stderr=True)
    if check and not progress.kernels_compiled(advance, stability_trial):
        console.print(progress.COMPILING)
    return console.status(what)


def _sweep_row(assessment, name: str, value: float) -> dict:
    """One row of a --sweep's CSV: the value, A_max, the recommended Δt and every estimate."""
    row = {name: value, "a_max": assessment.inverse_mass, "recommended_dt": assessment.recommended}
    return row | {f"dt_{e.key}": e.dt for e in assessment.criteria + assessment.checks}


def _write_sweep(case: _Case, name: str, values: list[float], check: bool, out) -> None:
    import csv

    rows = []
    with _working(f"{name} = {values[0]:g}, 1 of {len(values)}", check) as shown:
        for k, value in enumerate(values):
            shown.update(f"{name} = {value:g}, {k + 1} of {len(values)}")
            rows.append(_sweep_row(case.with_value(name, value).assess(check), name, value))
    try:  # a path that cannot be opened is bad input; a write that fails, a failure
        stream = open(out, "w", newline="") if out else contextlib.nullcontext(sys.stdout)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write it ({exc.strerror})") from None
    try:
        with stream as opened:
            writer = csv.DictWriter(opened, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    except BrokenPipeError:  # standard output's reader went away: the command line ends it
        raise
    except OSError as exc:
        if out:
            out.unlink(missing_ok=True)
        raise WriteFailed(out or "standard output", exc) from None
    if out:
        typer.echo(f"wrote {len(rows)} rows to {out}")


def _seconds(dt: float | None, not_applicable: str = "overdamped") -> str:
    if dt is None:
        return f"n/a ({not_applicable})"
    if math.isinf(dt):
        return "∞"
    return "never stable" if dt == 0.0 else f"{dt:.4e}"


def _print_table(assessment) -> None:
    from rich.console import Console
    from rich.table import Table

    from revdem_cli.timestep.assessment import ratio_to
    from revdem_cli.timestep.criteria import b_max, critical_damping

    bodies = assessment.bodies
    particles = Table(title="Particles, in their principal frames")
    for heading in ("", "particle 1", "particle 2", "unit"):
        particles.add_column(heading)
    rows = [
        ("shape", [b.shape for b in bodies], ""),
        ("volume", [f"{b.volume:.6g}" for b in bodies], "m³"),
        ("mass", [f"{b.mass:.6g}" for b in bodies], "kg"),
        ("principal moments", [" ".join(f"{i:.4g}" for i in b.moments) for b in bodies], "kg m²"),
        ("half-lengths a b c", [" ".join(f"{h:.4g}" for h in b.half_lengths) for b in bodies], "m"),
        ("farthest point (Eq 26's a)", [f"{b.reach:.4g}" for b in bodies], "m"),
        ("B_max (Eq 54)", [f"{b_max(b):.4g}" for b in bodies], ""),
    ]
    for quantity, values, unit in rows:
        particles.add_row(quantity, *values, unit)

    contact, reference = assessment.contact, assessment.reference
    steps = Table(title="Critical time steps", caption=f"ratio: Δt ÷ {reference.label}")
    for heading in ("criterion", "source", "Δt (s)", "ratio"):
        steps.add_column(heading, no_wrap=heading != "source")
    for estimate in assessment.criteria + assessment.checks:
        ratio = ratio_to(reference, estimate)
        shown = "" if ratio is None else f"{ratio:.4g}"
        shown_dt = _seconds(estimate.dt, estimate.not_applicable)
        steps.add_row(estimate.label, estimate.source, shown_dt, shown)
    steps.add_section()
    steps.add_row(
        "[bold]recommended[/bold]", "", f"[bold]{_seconds(assessment.recommended)}[/bold]"
    )

    normal = ""
    if assessment.normal_inverse_mass != assessment.inverse_mass:
        normal = f", normal direction A_n = 1/m₁ + 1/m₂ = {assessment.normal_inverse_mass:.4e} 1/kg"
    console = Console()
    console.print(particles)
    console.print(
        f"A_max = {assessment.inverse_mass:.4e} 1/kg "
        f"= {assessment.inverse_mass * bodies[0].mass:.4g} / m₁ (Peng 2020 Eq 26){normal}; "
        f"k_n = {contact.kn:.4g} N/m, k_s = {contact.ks:.4g} N/m; "
        f"N = {assessment.damping_number:g}: c_n = c_s = {contact.cn:.4g} N s/m "
        f"(critical {critical_damping(contact.kn, assessment.inverse_mass):.4g}, Eq 37)",
        highlight=False,
    )
    console.print(steps)
    for finding in assessment.findings:
        console.print(f"• {finding}", highlight=False)


def _print_packing(report: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    assembly, mode = report["assembly"], report["assembly"]["mode"]
    console = Console()
    console.print(
        f"{report['restart']}: scenario {report['scenario']}, stage {report['stage']}, "
        f"step {report['step']}, {report['spheres']} spheres, {assembly['contacts']} contacts "
        f"({assembly['wall_contacts']} on walls)",
        highlight=False,
    )
    steps = Table(
        title="Critical time step of this packing", caption="ratio: Δt ÷ the assembly's limit"
    )
    for heading in ("estimate", "source", "Δt (s)", "ratio"):
        steps.add_column(heading, no_wrap=heading != "source")
    steps.add_row(
        "[bold]assembly[/bold]",
        f"2/ω_max, ω_max² the largest eigenvalue of M⁻¹K ({assembly['seconds']:.2f} s)",
        f"[bold]{_seconds(assembly['dt'])}[/bold]",
        f"{assembly['dt'] / assembly['damped_dt']:.4g}",
    )
    if assembly["mode_damping"] > 0.0:
        order = report["predictor_order"]
        read = f", read from the velocity predictor of order {order}" if order else ""
        steps.add_row(
            "assembly, damped",
            f"the top mode with its viscous damping φᵀCφ{read}",
            _seconds(assembly["damped_dt"]),
            "1",
        )
    engine = report.get("engine_integrated")
    if engine is not None and engine["measured"]:
        steps.add_row(
            "engine_integrated",
            f"bisection on the stepping loop: stable {engine['stable']:.6e}, "
            f"unstable {engine['unstable']:.6e} ({engine['steps']} steps a trial)",
            _seconds(engine["dt"]),
            f"{engine['ratio']:.4g}",
        )
    elif engine is not None:
        steps.add_row("engine_integrated", "not measured (below)", "–", "")
    steps.add_section()
    for key, estimate in report["estimates"].items():
        dt, ratio = estimate["dt"], estimate["ratio"]
        shown = "" if ratio is None else f"{ratio:.4g}"
        steps.add_row(key, estimate["label"], _seconds(math.inf if dt is None else dt), shown)
    console.print(steps)
    top = ", ".join(
        f"id {s['id']} ({s['share']:.2%}, {s['contacts']} contacts)" for s in mode["spheres"]
    )
    carriers = f"{mode['participation']:.4g}"
    console.print(
        f"• fastest mode: ω_max = {assembly['omega_max']:.6g} rad/s, carried by about "
        f"{carriers} sphere{'' if carriers == '1' else 's'}, "
        f"{mode['rotation_share']:.1%} of it rotation; "
        f"largest shares: {top}",
        highlight=False,
    )
    if engine is not None and not engine["measured"]:
        console.print(f"• {engine['reason']}", highlight=False)
    for key, estimate in report["estimates"].items():  # each ∞ above, and why
        if "reason" in estimate:
            console.print(f"• {key}: {estimate['reason']}", highlight=False)


def dt(
    ctx: typer.Context,
    shape: Annotated[
        str | None, typer.Option(help="sphere, ellipsoid, superquadric or polyhedron.")
    ] = None,
    radius: Annotated[float | None, typer.Option(help="Sphere radius (m).")] = None,
    semi_axes: Annotated[
        tuple[float, float, float] | None,
        typer.Option(help="Semi-axes a b c of an ellipsoid or superquadric (m)."),
    ] = None,
    exponents: Annotated[
        tuple[float, float] | None,
        typer.Option(help="Superquadric exponents ε1 ε2 in (0, 2]; 1 1 is the ellipsoid."),
    ] = None,
    vertices: Annotated[
        Path | None, typer.Option(help="Polyhedron vertex file: JSON, or one 'x y z' a line.")
    ] = None,
    density: Annotated[float | None, typer.Option(help="Particle density (kg/m³).")] = None,
    other_shape: Annotated[str | None, typer.Option(help="Shape of the second particle.")] = None,
    other_radius: Annotated[
        float | None, typer.Option(help="As --radius, second particle.")
    ] = None,
    other_semi_axes: Annotated[
        tuple[float, float, float] | None, typer.Option(help="As --semi-axes, second particle.")
    ] = None,
    other_exponents: Annotated[
        tuple[float, float] | None, typer.Option(help="As --exponents, second particle.")
    ] = None,
    other_vertices: Annotated[
        Path | None, typer.Option(help="As --vertices, second particle.")
    ] = None,
    other_density: Annotated[
        float | None, typer.Option(help="As --density, second particle.")
    ] = None,
    kn: Annotated[float | None, typer.Option(help="Normal contact stiffness k_n (N/m).")] = None,
    ks: Annotated[
        float | None,
        typer.Option(
            help="Shear contact stiffness k_s (N/m); default k_n; 0: frictionless, the shear "
            "direction (spring and dashpot) left out, which for two spheres leaves the normal "
            "one with A_n = 1/m1 + 1/m2."
        ),
    ] = None,
    damping: Annotated[
        float,
        typer.Option(
            help="Damping number N: c_n = c_s = N √(k_n/A_max), N/2 of critical across the "
            "contact (k_s = k_n); along two equal spheres' normal (A_n = 2/m, A_max = 7/m) "
            "N/(2√3.5), the engine's normal_damping β: β = 0.5 is N = 1.8708."
        ),
    ] = 0.0,
    omega_max: Annotated[
        float | None, typer.Option(help="Largest angular speed (rad/s), for the rotation Δt.")
    ] = None,
    trvp_order: Annotated[
        int,
        typer.Option(
            help="Damping read from the velocity predictor of this order (integrator.scheme = "
            "'trvp', 1 to 4): its limit, and with --verify the engine's with it; 0: none."
        ),
    ] = 0,
    verify: Annotated[
        bool, typer.Option("--verify", help="Find the integrators' own stability limits.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    sweep: Annotated[
        str | None,
        typer.Option(
            help="Sweep one of kn, ks, density, damping, omega-max: NAME=START:STOP:COUNT; "
            "the swept option is not given besides (density: nor --other-density)."
        ),
    ] = None,
    out: Annotated[
        str | None,
        typer.Option(parser=named_file, help="CSV file of a sweep (default stdout)."),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(
            "--force", help="Write over a file that --out names, or those --figures writes."
        ),
    ] = False,
    figures: Annotated[
        Path | None,
        typer.Option(
            parser=named_folder,
            help="Write Peng 2020 Figures 3-6, A2 and A4 (PNG and CSV) and Figure 2's "
            "mobilities (CSV) to this folder; those already there are kept unless --force.",
        ),
    ] = None,
    restart: Annotated[
        Path | None,
        typer.Option(
            parser=file_to_read,
            help="A restart or checkpoint of a sphere scenario: the critical time step of its "
            "packing (eigenvalues of M⁻¹K); --verify bisects the stepping loop's own limit.",
        ),
    ] = None,
) -> None:
    """Critical time step of two convex, centrally symmetric particles in contact.

    Criteria of Peng, Burns & Hanley (2020) beside the stability limit of the
    velocity-Verlet integrator; --verify also finds that limit by integrating.
    The second particle takes every --other-* option not given from the first.

    Example: revdem dt --shape ellipsoid --semi-axes 3 2 1 --density 1000 --kn 1e10
    """
    if figures is not None:
        given = given_options(ctx, beside=("figures", "force"))
        if given:
            raise InputError(
                "--figures writes Peng 2020's figures, not a packing's nor particles of your "
                f"own, and takes no other option but --force; leave out {', '.join(given)}"
            )
        from itertools import chain

        from revdem_cli.api import keep_outputs
        from revdem_cli.timestep import figures as paper
        from revdem_cli.timestep.study import PAPER

        files = paper.study_files(figures, PAPER, paper.PAPER_STEMS)
        keep_outputs([*files, *paper.appendix_files(figures)], force, "dt --figures")
        written = chain(
            paper.write_figures(figures, PAPER, paper.PAPER_STEMS),
            paper.write_appendix_figures(figures),
        )
        for path in written:  # each as it is written: the figures take seconds each
            typer.echo(f"wrote {path}")
        return
    if restart is not None:
        given = given_options(ctx, beside=("restart", "verify", "as_json"))
        if given:
            raise InputError(
                f"--restart takes the particles from the file; leave out {', '.join(given)} "
                "(beside it only --verify and --json count)"
            )
        from rich.console import Console

        from revdem_cli.timestep.packing import assess_restart

        with Console(stderr=True).status(f"reading {restart}") as shown:
            report = assess_restart(restart, verify, shown.update)
        if as_json:
            import json

            typer.echo(json.dumps(report, indent=2))
        else:
            _print_packing(report)
        return
    case = _Case(
        first=_Particle(shape, radius, semi_axes, exponents, vertices, density),
        other=_Particle(
            other_shape,
            other_radius,
            other_semi_axes,
            other_exponents,
            other_vertices,
            other_density,
        ),
        kn=kn,
        ks=ks,
        damping=damping,
        omega_max=omega_max,
        trvp_order=trvp_order,
    )
    if out is not None and sweep is None:
        raise InputError("--out names the CSV file of a --sweep; give --sweep too")
    if force and out is None:
        raise InputError(
            "--force writes over the file that --out names, or those --figures writes; give "
            "--out or --figures too"
        )
    if out is not None:
        from revdem_cli.io import refuse_overwriting

        refuse_overwriting("dt", out, not force)
        out = Path(out)
    if sweep is not None:
        if as_json:
            raise InputError("--sweep writes CSV; leave out --json")
        name, values = _sweep_values(sweep)
        _sweep_conflicts(ctx, sweep, name)
        _write_sweep(case, name, values, verify, out)
        return
    integrating = "integrating the pair: the engine's and the rigid bodies' limits"
    with _working(integrating, True) if verify else contextlib.nullcontext():
        assessment = case.assess(verify)
    if as_json:
        import json

        typer.echo(json.dumps(assessment.to_dict(), indent=2))
    else:
        _print_table(assessment)
