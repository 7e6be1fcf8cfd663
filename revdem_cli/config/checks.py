"""Cross-field checks of a scenario: how its fields fit together. They generate no spheres
and read nothing of the machine (`geometry` and `host` do those, at the edge)."""

from __future__ import annotations

import math

MAX_STEPS = 2**62
"""Most steps of a run: steps are 64-bit integers everywhere, and stay far from their end."""

TAPE_NEEDS = {"arithmetic": "fixed", "scheme": "verlet"}
"""What the information tape (reversal.tape) needs of [integrator]: integers to record, and
velocity Verlet, the velocity predictor's history being what the tape does not record."""


class FieldError(ValueError):
    """A consistency error located at a field path inside the scenario."""

    def __init__(self, path: str, message: str):
        super().__init__(f"{path}: {message}")


def check_consistency(scenario) -> None:
    """How the fields of a scenario fit together: names that refer to materials, walls and
    stages exist and are unique, one reversed stage and the last, stop conditions that can
    be met, the cell and its servo, the container of [solid_fraction]; FieldError at the
    first that does not. What a run would carry out without its doing what it says is
    `check_given`'s."""
    for path, material in _materials_named(scenario):
        if material not in scenario.materials:
            raise FieldError(
                path, f"unknown material '{material}' (known: {', '.join(scenario.materials)})"
            )
    check_particles_from(scenario)
    check_wall_materials(scenario)
    wall_names = [w.name for w in scenario.walls]
    check_solid_fraction(scenario)
    check_stop_conditions(scenario)
    for i, stage in enumerate(scenario.stages):
        for name in stage.wall_velocities:
            if name not in wall_names:
                raise FieldError(
                    f"stages[{i}].wall_velocities.{name}",
                    f"no wall is named '{name}' (walls: {', '.join(wall_names) or 'none'})",
                )
    for i, wall in enumerate(scenario.walls):
        if wall_names.index(wall.name) != i:
            raise FieldError(f"walls[{i}].name", f"wall name '{wall.name}' is used twice")
    names = [stage.name for stage in scenario.stages]
    for i, name in enumerate(names):
        if names.index(name) != i:
            raise FieldError(f"stages[{i}].name", f"stage name '{name}' is used twice")
    reversed_stages = [i for i, stage in enumerate(scenario.stages) if stage.reverse]
    if len(reversed_stages) > 1:
        marked = " and ".join(f"stages[{i}]" for i in reversed_stages)
        raise FieldError(
            f"stages[{reversed_stages[0]}].reverse",
            f"only one stage can be reversed, the last; {marked} are marked (reversal.all_stages "
            "reverses every stage)",
        )
    if reversed_stages and reversed_stages[0] != len(scenario.stages) - 1:
        raise FieldError(
            f"stages[{reversed_stages[0]}].reverse", "the reversed stage must be the last stage"
        )
    check_cell(scenario)
    check_step_total(scenario)
    check_automatic_dt(scenario)
    check_scheme(scenario)
    check_tape(scenario)
    check_figures(scenario)


def check_stop_conditions(scenario) -> None:
    """Each stage's stop condition can be met: it is first checked before the stage ends, the
    wall it watches exists, a wall whose travel it waits for moves in that stage (walls move
    only at their velocity, `Stage.wall_velocity`; a static wall's force may still rise), and
    a solid fraction has the container of [solid_fraction]."""
    names = [wall.name for wall in scenario.walls]
    for i, stage in enumerate(scenario.stages):
        stop = stage.stop_when
        if stop is None:
            continue
        path = f"stages[{i}].stop_when"
        if stop.after_steps is not None and stop.after_steps >= stage.steps:
            raise FieldError(
                f"{path}.after_steps",
                f"{stop.after_steps} must be below the stage's steps, {stage.steps}: the "
                "condition is first checked that many steps into the stage",
            )
        condition = "wall_force_above" if stop.wall_force_above else "wall_travel_above"
        if stop.wall is not None and stop.wall not in names:
            raise FieldError(f"{path}.{condition}.wall", f"no wall is named '{stop.wall}'")
        if stop.wall_travel_above:
            k = names.index(stop.wall)
            speed = math.hypot(*stage.wall_velocity(scenario.walls[k]))
            if speed == 0.0:
                raise FieldError(
                    f"{path}.wall_travel_above.wall",
                    f"wall '{stop.wall}' does not move in this stage: its velocity here is "
                    f"zero (stages[{i}].wall_velocities.{stop.wall}, else walls[{k}].velocity)",
                )
            dt = scenario.stage_dt(stage)
            distance = stop.wall_travel_above.distance
            if dt != "auto" and distance >= speed * stage.steps * dt:
                raise FieldError(
                    f"{path}.wall_travel_above.distance",
                    f"{distance:g} m is never reached: wall '{stop.wall}' moves "
                    f"{speed * stage.steps * dt:.6g} m in this stage ({speed:g} m/s for "
                    f"{stage.steps} steps of {dt:g} s)",
                )
        if stop.solid_fraction_above and scenario.solid_fraction is None and not scenario.cell:
            raise FieldError(
                f"{path}.solid_fraction_above",
                "needs a periodic [cell] (its solid fraction, 1 / (1 + void ratio)) or a "
                "[solid_fraction] table saying which walls close the container",
            )


def check_given(scenario) -> None:
    """What a run would carry out but without its doing what it says: friction or tangential
    damping without a tangential law (`check_tangential_fields`), a stop condition no
    observables row checks (`check_stop_rows`), gravity in a periodic cell. Refused in a
    scenario given (`loader.scenario_from_data`), not in one a run stored with its outputs,
    which stay readable whatever a later version refuses; FieldError at the first."""
    check_tangential_fields(scenario)
    for i, stage in enumerate(scenario.stages):
        if stage.stop_when is not None:
            check_stop_rows(stage, i)
    if scenario.cell is not None and any(scenario.gravity):
        raise FieldError(
            "gravity",
            f"{list(scenario.gravity)} m/s^2 with a periodic [cell]: every sphere falls "
            "together, for no wall or floor holds them (a cell takes no walls); leave gravity "
            "out",
        )


TANGENTIAL_FIELDS = {"friction": "cap", "tangential_damping": "damp"}
"""The coefficients of [contact] and of a stage's contact that act on a tangential law's
shear force, with what each does to it."""


def check_tangential_fields(scenario) -> None:
    """Friction and tangential damping, in [contact] or a stage's contact, only with a
    tangential law: frictionless spheres have no shear force for them to act on, and they
    would do nothing. A coefficient counts as given where it is not [contact]'s default
    (friction has none; tangential damping's is 0)."""
    if scenario.contact.tangential != "none":
        return
    contacts = [("contact", scenario.contact)]
    contacts += [(f"stages[{i}].contact", s.contact) for i, s in enumerate(scenario.stages)]
    for path, contact in contacts:
        for field, effect in TANGENTIAL_FIELDS.items():
            value = None if contact is None else getattr(contact, field)
            if value is not None and value != type(scenario.contact).model_fields[field].default:
                raise FieldError(
                    f"{path}.{field}",
                    "needs a tangential law in [contact] (tangential = 'mindlin', ...): "
                    f"frictionless spheres have no shear force for it to {effect}",
                )


def check_stop_rows(stage, i: int) -> None:
    """A stage's stop condition is checked at its observables rows, every observables_every
    steps from its start (its interval, as N is fix halt's in LIGGGHTS), from its after_steps
    on: at least one row comes before its last step, which ends the stage anyway."""
    every, after = stage.observable_interval, stage.stop_when.after_steps
    if -(-(after or 1) // every) * every < stage.steps:  # the first row from `after` on
        return
    given = "" if stage.observables_every else f" (default: output_every, {every})"
    since = f" from its after_steps, {after}," if after else ""
    raise FieldError(
        f"stages[{i}].observables_every",
        f"{every}{given} leaves stages[{i}].stop_when no observables row to be checked at"
        f"{since} before the stage's last step, {stage.steps}: it could never end the stage "
        f"early; give observables_every at most {stage.steps - (after or 1)}",
    )


def check_figures(scenario) -> None:
    """Each figure of [output] finds what it draws, where a scenario may lack it (the contact
    figures' `contacts = true` is checked by `Output` itself)."""
    needs = {
        "wall_forces": (
            any(wall.across_z for wall in scenario.walls),
            "a plane wall across z (it draws the z force on each, its load)",
        ),
        "stress_ratios": (
            scenario.cell is not None,
            "a periodic [cell] (it draws them against the cell's compression)",
        ),
        "information": (scenario.reversal.tape, "reversal.tape = true"),
    }
    for kind in scenario.output.figures:
        if kind in needs and not needs[kind][0]:
            raise FieldError("output.figures", f"'{kind}' needs {needs[kind][1]}")


def check_scheme(scenario) -> None:
    """trvp_order only with the predictor; drag, which Eq 25 applies as a factor on the
    half-step velocity rather than as a force, only with velocity Verlet."""
    integrator = scenario.integrator
    if integrator.scheme == "verlet":
        if integrator.trvp_order is not None:
            raise FieldError("integrator.trvp_order", "needs integrator.scheme = 'trvp'")
        return
    dampings = [("damping.drag", scenario.damping)]
    dampings += [(f"stages[{i}].damping.drag", s.damping) for i, s in enumerate(scenario.stages)]
    for path, damping in dampings:
        if damping is not None and damping.drag != 1.0:
            raise FieldError(
                path,
                "drag (Eq 25, a factor on the half-step velocity) needs integrator.scheme = "
                "'verlet'; with 'trvp' use viscous contact damping or local damping",
            )


def tape_needs(integrator=None) -> str:
    """What the information tape needs (`TAPE_NEEDS`) that `integrator` (a scenario's
    [integrator]; None: one that has none of it) lacks, in words, "integrator.arithmetic =
    'fixed' and integrator.scheme = 'verlet'"; "" where it lacks nothing."""
    return " and ".join(
        f"integrator.{field} = '{value}'"
        for field, value in TAPE_NEEDS.items()
        if integrator is None or getattr(integrator, field) != value
    )


def check_tape(scenario) -> None:
    """The information tape records integers: it needs fixed-point arithmetic, and the
    velocity predictor's history, which it does not record, left out (`TAPE_NEEDS`)."""
    if not scenario.reversal.tape:
        if scenario.reversal.all_stages:
            raise FieldError("reversal.all_stages", "needs reversal.tape = true")
        return
    if lacking := tape_needs(scenario.integrator):
        raise FieldError("reversal.tape", f"needs {lacking}")


def check_automatic_dt(scenario) -> None:
    """dt = 'auto' only in floating-point arithmetic, whose state does not depend on dt."""
    if scenario.integrator.arithmetic != "fixed":
        return
    given = [("integrator.dt", scenario.integrator.dt)]
    given += [(f"stages[{i}].dt", stage.dt) for i, stage in enumerate(scenario.stages)]
    for path, dt in given:
        if dt == "auto":
            raise FieldError(
                path,
                "'auto' needs integrator.arithmetic = 'float': fixed-point grids are made from "
                "the run's duration before it starts",
            )


def _materials_named(scenario) -> list[tuple[str, str]]:
    """(field path, material name) of every table that names a material: spheres, then
    walls."""
    named = []
    for kind, items in scenario._sphere_sources():
        for i, item in enumerate(items):
            if kind == "particles_from":
                named += [(f"{kind}[{i}].materials.{t}", m) for t, m in item.materials.items()]
            else:
                named.append((f"{kind}[{i}].material", item.material))
    return named + [(f"walls[{i}].material", w.material) for i, w in enumerate(scenario.walls)]


def check_particles_from(scenario) -> None:
    """Spheres read from a file: its atom types are whole numbers, its sphere count known
    (the loader reads it from the header), and a periodic box needs a [cell]."""
    for i, source in enumerate(scenario.particles_from):
        for atom_type in source.materials:
            if not atom_type.isdigit() or int(atom_type) < 1:
                raise FieldError(
                    f"particles_from[{i}].materials.{atom_type}",
                    "a LAMMPS atom type is a whole number from 1",
                )
        if source.count is None:
            raise FieldError(
                f"particles_from[{i}].count",
                "unknown: load the scenario from its file, which reads the header",
            )
        if source.periodic and scenario.cell is None:
            raise FieldError(f"particles_from[{i}].periodic", "a periodic box needs a [cell] table")


def check_wall_materials(scenario) -> None:
    """With contact.wall_moduli = 'wall' a wall's material sets its contacts alone, so no
    sphere may be of it: a sphere pair of that material would be ambiguous."""
    if scenario.contact.wall_moduli != "wall":
        return
    spheres = {
        material: path.removesuffix(".material")
        for path, material in _materials_named(scenario)
        if not path.startswith("walls")
    }
    for i, wall in enumerate(scenario.walls):
        if wall.material in spheres:
            raise FieldError(
                f"walls[{i}].material",
                f"with contact.wall_moduli = 'wall' a wall needs a material of its own; "
                f"'{wall.material}' is also the material of {spheres[wall.material]}",
            )


def check_cell(scenario) -> None:
    """Stages move the cell only if there is one, hold a stress only with the parameter of
    its servo, and strain it at a rate that leaves each edge a length; walls and a periodic
    cell do not go together."""
    if scenario.cell is not None and scenario.walls:
        raise FieldError("walls", "walls cannot be combined with a periodic [cell]")
    for i, stage in enumerate(scenario.stages):
        if stage.cell is None:
            continue
        if scenario.cell is None:
            raise FieldError(f"stages[{i}].cell", "needs a periodic [cell] to move")
        holds = bool(stage.held_stresses())
        needed = scenario.cell.servo_parameter
        if holds and getattr(scenario.cell, needed) is None:
            raise FieldError(
                f"cell.{needed}",
                f"stages[{i}] holds a stress with the {scenario.cell.servo} servo, which "
                f"needs {needed}",
            )
        dt = scenario.stage_dt(stage)
        for axis, motion in zip("xyz", stage.cell.axes(), strict=True):
            rate = None if motion is None else motion.strain_rate
            if rate is not None and dt != "auto" and 1.0 + rate * stage.steps * dt <= 0.0:
                raise FieldError(  # L = L0 (1 + rate t) from the stage's start
                    f"stages[{i}].cell.{axis}.strain_rate",
                    f"{rate:g} 1/s for {stage.steps} steps of {dt:g} s takes the edge to "
                    f"{1.0 + rate * stage.steps * dt:.3g} times its length at the stage's "
                    "start: below zero",
                )


def check_solid_fraction(scenario) -> None:
    """The container of [solid_fraction]: a cylinder and two planes across its axis."""
    if scenario.solid_fraction is None:
        return
    walls = {w.name: w for w in scenario.walls}
    wanted = [("cylinder", scenario.solid_fraction.cylinder, "cylinder")] + [
        (f"planes[{k}]", name, "plane") for k, name in enumerate(scenario.solid_fraction.planes)
    ]
    for field, name, kind in wanted:
        if name not in walls or walls[name].type != kind:
            raise FieldError(f"solid_fraction.{field}", f"no {kind} wall is named '{name}'")
    axis = walls[scenario.solid_fraction.cylinder].normal
    for k, name in enumerate(scenario.solid_fraction.planes):
        normal = walls[name].normal
        cross = math.hypot(
            axis[1] * normal[2] - axis[2] * normal[1],
            axis[2] * normal[0] - axis[0] * normal[2],
            axis[0] * normal[1] - axis[1] * normal[0],
        )
        if cross > 1e-9 * math.hypot(*axis) * math.hypot(*normal):
            raise FieldError(
                f"solid_fraction.planes[{k}]",
                f"plane '{name}' is not perpendicular to the axis of the cylinder",
            )


def check_step_total(scenario) -> None:
    """The stages add up to a number of steps the step counter holds."""
    total = 0
    for i, stage in enumerate(scenario.stages):
        total += stage.steps
        if total > MAX_STEPS:
            raise FieldError(
                f"stages[{i}].steps",
                f"the stages add up to {total} steps, more than {MAX_STEPS} (2^62), the most "
                "a step counter holds",
            )
