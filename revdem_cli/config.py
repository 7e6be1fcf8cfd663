"""Scenario files (TOML or YAML) as validated pydantic models.

Everything is SI. Loading goes through `load_scenario`, which turns every problem into an
`InputError` naming the file and the field path, e.g. ``collision.toml: particles[1].radius:
must be greater than 0``.
"""

from __future__ import annotations

import math
import os
import re
import sys
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    create_model,
    model_validator,
)

from revdem_cli import laws
from revdem_cli.errors import InputError

if TYPE_CHECKING:
    from revdem_cli.build.spheres import Spheres


def _number(value):
    """A number as the file wrote it: true/false and text are not numbers (pydantic would
    read true as 1 and "0.005" as 0.005)."""
    if isinstance(value, bool):
        raise ValueError(f"Input should be a valid number, not {str(value).lower()}")
    if isinstance(value, str):
        raise ValueError(f"Input should be a valid number, not the text {value[:40]!r}")
    return value


Float = Annotated[float, BeforeValidator(_number)]
FloatOrInf = Annotated[float, Field(allow_inf_nan=True), BeforeValidator(_number)]
Int = Annotated[int, BeforeValidator(_number)]
Vector3 = Annotated[tuple[Float, Float, Float], Field(description="three components (x, y, z)")]


class _Model(BaseModel):
    model_config = ConfigDict(
        extra="forbid", allow_inf_nan=False, frozen=True, ser_json_inf_nan="constants"
    )


class Material(_Model):
    """An elastic material; Young's modulus follows as E = 2G(1 + nu)."""

    density: Float = Field(gt=0, description="mass density, kg/m^3")
    shear_modulus: Float = Field(gt=0, description="shear modulus G, Pa")
    poisson_ratio: Float = Field(gt=-1, lt=0.5, description="Poisson's ratio nu, -")


def _choice(family: str) -> object:
    """The [contact] field that chooses the law of a family, from the laws found."""
    info = laws.FAMILIES[family]
    names = (["none"] if info.optional else []) + list(laws.LAWS[family])
    described = "; ".join(f"'{name}', {law.SUMMARY}" for name, law in laws.LAWS[family].items()) + (
        "; 'none'" if info.optional else ""
    )
    kind = Literal[tuple(names)]
    if info.optional:
        return (kind, Field(default="none", description=f"{family} law: {described}"))
    return (kind, Field(description=f"{family} law: {described}"))


class _Contact(_Model):
    """The parts of a contact that belong to no one law: Coulomb friction, viscous damping
    and how a wall's moduli combine."""

    friction: FloatOrInf | None = Field(
        default=None,
        ge=0,
        description="Coulomb friction coefficient mu, -; inf for no sliding",
    )
    normal_damping: Float = Field(
        default=0.0, ge=0, description="viscous normal damping, fraction of critical, -"
    )
    tangential_damping: Float = Field(
        default=0.0, ge=0, description="viscous tangential damping, fraction of critical, -"
    )
    wall_moduli: Literal["combined", "wall"] = Field(
        default="combined",
        description="E* and G* of a sphere on a wall: 'combined', from both materials (Hertz, "
        "Mindlin); 'wall', from the wall's material alone, as if the sphere were of it too "
        "(LAMMPS fix wall/gran, whose contact parameters belong to the wall)",
    )

    @model_validator(mode="after")
    def _parameters_match_laws(self) -> _Contact:
        for field in laws.fields():
            owners = laws.owners(field)
            chosen = [(f, n) for f, n in owners if getattr(self, laws.FAMILIES[f].selector) == n]
            given = getattr(self, field) is not None
            if given and not chosen:
                laws_named = " or ".join(f"{laws.FAMILIES[f].selector} = '{n}'" for f, n in owners)
                raise ValueError(f"{field} belongs to {laws_named}")
            for family, name in chosen:
                law = laws.LAWS[family][name]
                if field in law.REQUIRED and not given:
                    selector = laws.FAMILIES[family].selector
                    description = law.FIELDS[field].description
                    raise ValueError(f"{selector} = '{name}' needs {field}: {description}")
        if self.tangential != "none" and self.friction is None:
            raise ValueError("a tangential law needs friction (mu; inf for no sliding)")
        if self.rolling != "none" and self.tangential == "none":
            raise ValueError(
                "rolling resistance needs a tangential law: the spheres turn only under "
                "contact moments, which frictionless contacts do not make"
            )
        if self.friction is not None and math.isnan(self.friction):
            raise ValueError("friction must be a number or inf")
        return self


ContactLaw = create_model(
    "ContactLaw",
    __base__=_Contact,
    __doc__="Contact between spheres and between spheres and walls: a law of each family "
    "(revdem_cli/laws), each with its coefficients (Hanley 2020 Eq 6-10).",
    **{info.selector: _choice(family) for family, info in laws.FAMILIES.items()},
    **{name: (Float | None, info) for name, info in laws.fields().items()},
)


class Damping(_Model):
    """Damping of particle motion (Hanley 2020 §3.1, §5.2)."""

    local: Float = Field(default=0.0, ge=0, lt=1, description="local damping gamma_l of Eq 21, -")
    drag: Float = Field(
        default=1.0,
        gt=0,
        le=1,
        description="drag factor gamma_d of Eq 25 applied to the half-step velocity, -; 1: none",
    )


class Wall(_Model):
    """An infinite plane, or the inside of an infinite cylinder, moving at a fixed velocity."""

    name: str = Field(pattern=r"^[A-Za-z0-9_-]+$", description="wall name, used for its force")
    type: Literal["plane", "cylinder"] = Field(description="'plane' or 'cylinder' (inside)")
    material: str = Field(description="name of a material in [materials]")
    point: Vector3 = Field(description="a point on the plane, or on the cylinder axis, m")
    normal: Vector3 = Field(
        description="plane: normal pointing into the domain; cylinder: axis direction (-)"
    )
    radius: Float | None = Field(default=None, gt=0, description="cylinder radius, m")
    velocity: Vector3 = Field(default=(0.0, 0.0, 0.0), description="wall velocity, m/s")

    @model_validator(mode="after")
    def _shape(self) -> Wall:
        if math.hypot(*self.normal) == 0:
            raise ValueError("normal must not be zero")
        squared = sum(c * c for c in self.normal)  # as the engine normalises it
        if not sys.float_info.min <= squared < math.inf:
            raise ValueError(
                f"normal {list(self.normal)} is too {'short' if squared < 1 else 'long'} to "
                "normalise in floating point; give a direction such as [0, 0, 1]"
            )
        if (self.type == "cylinder") != (self.radius is not None):
            raise ValueError("a cylinder needs a radius, a plane has none")
        return self


class Particle(_Model):
    """One sphere given explicitly."""

    material: str = Field(description="name of a material in [materials]")
    radius: Float = Field(gt=0, description="radius, m")
    position: Vector3 = Field(description="centre position, m")
    velocity: Vector3 = Field(default=(0.0, 0.0, 0.0), description="velocity, m/s")
    angular_velocity: Vector3 = Field(
        default=(0.0, 0.0, 0.0), description="angular velocity, rad/s"
    )


class Region(_Model):
    """Where generated spheres go: a vertical cylinder (axis along z) or a box."""

    shape: Literal["cylinder", "box"] = Field(description="'cylinder' or 'box'")
    origin: Vector3 = Field(description="cylinder: centre of its base; box: lower corner, m")
    radius: Float | None = Field(default=None, gt=0, description="cylinder radius, m")
    height: Float | None = Field(default=None, gt=0, description="cylinder height, m")
    size: Vector3 | None = Field(default=None, description="box edge lengths, m")

    @model_validator(mode="after")
    def _dimensions(self) -> Region:
        if self.shape == "cylinder" and (self.radius is None or self.height is None):
            raise ValueError("a cylinder needs radius and height")
        if self.shape == "box" and (self.size is None or min(self.size) <= 0):
            raise ValueError("a box needs a size with three positive edge lengths")
        return self

    @property
    def extent(self) -> tuple[float, float, float]:
        """(radius, height, 0) of a cylinder, or the edge lengths of a box, m."""
        return (self.radius, self.height, 0.0) if self.shape == "cylinder" else self.size


MAX_GENERATED = 20_000_000
"""Most spheres one [[packings]] or [[lattices]] entry generates."""


class Packing(_Model):
    """Spheres with radii drawn uniformly from [radius_min, radius_max], placed at random
    without overlap inside a region (random sequential addition), from a seeded generator."""

    count: Int = Field(gt=0, le=MAX_GENERATED, description="number of spheres")
    material: str = Field(description="name of a material in [materials]")
    radius_min: Float = Field(gt=0, description="smallest radius, m")
    radius_max: Float = Field(gt=0, description="largest radius, m")
    region: Region
    seed: Int = Field(default=0, ge=0, description="seed of the random generator")
    velocity: Vector3 = Field(default=(0.0, 0.0, 0.0), description="initial velocity, m/s")

    @model_validator(mode="after")
    def _radii(self) -> Packing:
        if self.radius_max < self.radius_min:
            raise ValueError("radius_max must not be below radius_min")
        return self

    def spheres(self, materials: tuple[str, ...]) -> Spheres:
        """The generated spheres; raises PackingError if the region cannot take them."""
        import numpy as np

        from revdem_cli.build.packing import place_spheres
        from revdem_cli.build.spheres import uniform

        rng = np.random.default_rng(self.seed)
        radii = rng.uniform(self.radius_min, self.radius_max, self.count)
        region = self.region
        centres = place_spheres(radii, region.shape, region.origin, region.extent, self.seed + 1)
        material = materials.index(self.material)
        return uniform(self.count, radii, material, materials, centres, self.velocity)


class Lattice(_Model):
    """Spheres of one radius on a face-centred cubic lattice: cells[0] x cells[1] x cells[2]
    cubic unit cells of edge `spacing`, four spheres each (a corner and three face centres),
    numbered cell by cell with z fastest."""

    type: Literal["fcc"] = Field(default="fcc", description="'fcc', face-centred cubic")
    material: str = Field(description="name of a material in [materials]")
    radius: Float = Field(gt=0, description="radius, m")
    cells: tuple[Int, Int, Int] = Field(description="unit cells along x, y and z")
    spacing: Float | None = Field(
        default=None,
        gt=0,
        description="edge of the cubic unit cell, m; default 2 sqrt(2) radius, neighbours touching",
    )
    origin: Vector3 = Field(default=(0.0, 0.0, 0.0), description="corner of the first cell, m")
    velocity: Vector3 = Field(default=(0.0, 0.0, 0.0), description="initial velocity, m/s")
    random_velocity: Float = Field(
        default=0.0,
        ge=0,
        description="each velocity component gets a uniform random addition in [-this, this], "
        "m/s, from a generator seeded with `seed`",
    )
    seed: Int = Field(default=0, ge=0, description="seed of the random velocities")

    @model_validator(mode="after")
    def _size(self) -> Lattice:
        if min(self.cells) < 1:
            raise ValueError("cells: at least one unit cell along each axis")
        if self.count > MAX_GENERATED:
            raise ValueError(f"cells: {self.count} spheres, more than {MAX_GENERATED}")
        return self

    @property
    def count(self) -> int:
        return 4 * self.cells[0] * self.cells[1] * self.cells[2]

    @property
    def lattice_constant(self) -> float:
        return self.spacing or 2.0 * math.sqrt(2.0) * self.radius

    def spheres(self, materials: tuple[str, ...]) -> Spheres:
        import numpy as np

        from revdem_cli.build.spheres import fcc_positions, uniform

        x = fcc_positions(self.cells, self.lattice_constant, self.origin)
        v = np.array(self.velocity) + np.random.default_rng(self.seed).uniform(
            -self.random_velocity, self.random_velocity, x.shape
        )
        return uniform(len(x), self.radius, materials.index(self.material), materials, x, v)


class Integrator(_Model):
    """Velocity-Verlet time integration (Hanley 2020 Eq 1-3, 11-12)."""

    dt: Float = Field(gt=0, description="time step, s")
    arithmetic: Literal["float", "fixed"] = Field(
        default="float",
        description="number representation of the state: 'float' (float64), or 'fixed': "
        "positions, velocities, angular velocities and servo-driven cell edges as 64-bit "
        "integers on fixed grids, so that a conservative run reverses bit for bit",
    )
    overlap_limit: Float = Field(
        default=0.5,
        gt=0,
        description="deepest overlap allowed, as a fraction of the smaller radius of a "
        "contact; checked with non-finite values at every observables row, a deeper one "
        "stops the run as blown up",
    )


class Neighbours(_Model):
    """Verlet pair list built from cell lists."""

    skin: Float | None = Field(
        default=None,
        gt=0,
        description="extra search distance beyond contact, m; default: 10 % of the largest radius",
    )


class WallForce(_Model):
    """A wall and a force magnitude."""

    wall: str = Field(description="wall name")
    force: Float = Field(gt=0, description="magnitude of the force on the wall, N")


class WallTravel(_Model):
    """A wall and a distance."""

    wall: str = Field(description="wall name")
    distance: Float = Field(gt=0, description="distance the wall has moved in this stage, m")


class StopWhen(_Model):
    """A condition that ends a stage at the first observables row (every `observables_every`
    steps) where it holds, with a trajectory frame there; the stage's `steps` is then the
    most it may run. Exactly one condition is given."""

    kinetic_energy_below: Float | None = Field(
        default=None, gt=0, description="total kinetic energy below this, J"
    )
    wall_force_above: WallForce | None = Field(
        default=None, description="the force on a wall above a magnitude"
    )
    wall_travel_above: WallTravel | None = Field(
        default=None, description="a wall has moved further than a distance since the stage began"
    )
    solid_fraction_above: Float | None = Field(
        default=None, gt=0, lt=1, description="the solid fraction of [solid_fraction] above this"
    )

    @model_validator(mode="after")
    def _one(self) -> StopWhen:
        if sum(getattr(self, name) is not None for name in type(self).model_fields) != 1:
            raise ValueError(f"give exactly one of {', '.join(type(self).model_fields)}")
        return self

    @property
    def wall(self) -> str | None:
        """The wall the condition watches, if any."""
        watched = self.wall_force_above or self.wall_travel_above
        return watched.wall if watched else None


class SolidFraction(_Model):
    """Solid fraction of a container closed by a cylinder and two planes across its axis:
    the spheres' volume over pi R^2 times the distance between the planes (caps cut off by
    the walls are not subtracted: they are below 1 % at the overlaps of a packing at rest)."""

    cylinder: str = Field(description="name of the cylinder wall")
    planes: tuple[str, str] = Field(description="names of the two plane walls closing it")


class Cell(_Model):
    """A periodic box [0, Lx) x [0, Ly) x [0, Lz), repeated in x, y and z: a sphere leaving
    through a face comes back through the opposite one, and contacts reach across faces to
    the nearest image. Stages may move its edges (`stages[].cell`), carrying the spheres
    with them affinely."""

    size: Vector3 = Field(description="edge lengths Lx, Ly, Lz of the box, m")
    servo: Literal["inertial", "proportional"] = Field(
        default="inertial",
        description="how an edge holds a stress: 'inertial', the edge is a mass driven by "
        "(stress - target) x face area, stepped with the spheres (exactly reversible); "
        "'proportional', dL/dt = gain (stress - target) / target L (Hanley 2020 §3.2.3)",
    )
    servo_mass: Float | None = Field(
        default=None, gt=0, description="inertial servo: mass of each moving edge, kg"
    )
    servo_gain: Float | None = Field(
        default=None,
        gt=0,
        description="proportional servo: strain rate per relative stress error, 1/s",
    )

    @model_validator(mode="after")
    def _positive(self) -> Cell:
        if min(self.size) <= 0:
            raise ValueError("size: the three edge lengths must be positive")
        return self


class AxisMotion(_Model):
    """How one edge of the periodic cell moves during a stage: at a prescribed strain rate,
    or holding a normal stress with the servo of [cell]. Exactly one is given."""

    strain_rate: Float | None = Field(
        default=None,
        description="dL/dt divided by L at the start of the stage, 1/s (< 0 compresses)",
    )
    stress: Float | None = Field(
        default=None, gt=0, description="normal stress to hold, Pa (compression positive)"
    )

    @model_validator(mode="after")
    def _one(self) -> AxisMotion:
        if (self.strain_rate is None) == (self.stress is None):
            raise ValueError("give exactly one of strain_rate, stress")
        return self


class CellMotion(_Model):
    """Motion of the periodic cell's edges during a stage; an edge not given stays fixed."""

    x: AxisMotion | None = None
    y: AxisMotion | None = None
    z: AxisMotion | None = None

    def axes(self) -> list[AxisMotion | None]:
        return [self.x, self.y, self.z]

    def moving(self) -> bool:
        return any(
            a is not None and (a.stress is not None or a.strain_rate != 0.0) for a in self.axes()
        )


class Stage(_Model):
    """A named stretch of the run with its own step count and output intervals."""

    name: str = Field(min_length=1, description="stage name, used in output and progress")
    steps: Int = Field(gt=0, description="number of time steps")
    output_every: Int = Field(
        default=100, gt=0, description="write a trajectory frame every this many steps"
    )
    observables_every: Int | None = Field(
        default=None,
        gt=0,
        description="record observables every this many steps; default: output_every",
    )
    reverse: bool = Field(
        strict=True,
        default=False,
        description="save the end of this stage as the restart and run it backwards in time",
    )
    dt: Float | None = Field(
        default=None, gt=0, description="time step of this stage, s; default: integrator.dt"
    )
    damping: Damping | None = Field(
        default=None, description="damping during this stage; default: [damping]"
    )
    stop_when: StopWhen | None = Field(
        default=None,
        description="end the stage early, at the first observables row where this holds",
    )
    wall_velocities: dict[str, Vector3] = Field(
        default_factory=dict,
        description="velocity of named walls during this stage, m/s; the others move at the "
        "velocity given in [[walls]]",
    )
    cell: CellMotion | None = Field(
        default=None, description="motion of the periodic cell's edges; default: all fixed"
    )

    @property
    def observable_interval(self) -> int:
        return self.observables_every or self.output_every


class Reversal(_Model):
    """Tolerances that decide whether a reversed run reproduced the forward one."""

    position_tolerance_rel: Float = Field(
        default=1e-10, gt=0, description="largest position error divided by the smallest diameter"
    )
    velocity_tolerance: Float = Field(default=1e-9, gt=0, description="largest velocity error, m/s")
    angular_velocity_tolerance: Float = Field(
        default=1e-6, gt=0, description="largest angular velocity error, rad/s"
    )


class Output(_Model):
    """What is written besides the trajectories."""

    figures: list[Literal["speed", "forces", "velocity_z", "wall_forces", "stress_ratios"]] = Field(
        default_factory=list,
        description="figures written beside the trajectories, forward and reversed overlaid: "
        "'speed' = |v| of each particle, 'forces' = largest normal and shear contact force, "
        "'velocity_z' = vertical velocity of each particle, all against time; 'wall_forces' "
        "= z force on each plane wall against the solid fraction (or against time); "
        "'stress_ratios' = principal stress ratios and coordination number against the "
        "compression of a periodic cell",
    )
    particle_stress: bool = Field(
        strict=True,
        default=False,
        description="write each sphere's stress (Hanley 2020 Eq 22) at every frame, "
        "particles/all/stress [F, N, 3, 3], Pa",
    )
    checkpoint_interval: Float = Field(
        default=60.0,
        ge=0,
        description="wall-clock time between checkpoints, s, each taken at an output frame "
        "(0: at every frame); `revdem run --resume` continues from the newest",
    )


class Scenario(_Model):
    """A complete revdem experiment."""

    _spheres: Spheres | None = PrivateAttr(default=None)

    name: str = Field(
        pattern=r"^[A-Za-z0-9_.-]+$", description="run name, used for output file names"
    )
    description: str = Field(default="", description="free text")
    materials: dict[str, Material] = Field(min_length=1, description="materials by name")
    contact: ContactLaw = Field(description="contact law between particles")
    particles: list[Particle] = Field(default_factory=list, description="spheres given one by one")
    packings: list[Packing] = Field(
        default_factory=list, description="spheres generated at random in regions"
    )
    lattices: list[Lattice] = Field(default_factory=list, description="spheres on lattices")
    walls: list[Wall] = Field(default_factory=list, description="walls")
    cell: Cell | None = Field(default=None, description="periodic boundaries in x, y and z")
    gravity: Vector3 = Field(
        default=(0.0, 0.0, 0.0), description="gravitational acceleration, m/s^2"
    )
    damping: Damping = Field(default_factory=Damping)
    integrator: Integrator
    neighbours: Neighbours = Field(default_factory=Neighbours)
    stages: list[Stage] = Field(min_length=1, description="stages run in order")
    solid_fraction: SolidFraction | None = Field(
        default=None, description="record the solid fraction of a container as an observable"
    )
    reversal: Reversal = Field(default_factory=Reversal)
    output: Output = Field(default_factory=Output)

    def _sphere_sources(self) -> tuple[tuple[str, list], ...]:
        """The tables that make spheres, with their field names."""
        return (
            ("particles", self.particles),
            ("packings", self.packings),
            ("lattices", self.lattices),
        )

    @model_validator(mode="after")
    def _consistent(self) -> Scenario:
        for kind, items in (*self._sphere_sources(), ("walls", self.walls)):
            for i, item in enumerate(items):
                if item.material not in self.materials:
                    raise _FieldError(
                        f"{kind}[{i}].material",
                        f"unknown material '{item.material}' (known: {', '.join(self.materials)})",
                    )
        self._check_wall_materials()
        wall_names = [w.name for w in self.walls]
        self._check_solid_fraction()
        for i, stage in enumerate(self.stages):
            stop = stage.stop_when
            if stop and stop.wall is not None and stop.wall not in wall_names:
                condition = "wall_force_above" if stop.wall_force_above else "wall_travel_above"
                raise _FieldError(
                    f"stages[{i}].stop_when.{condition}.wall", f"no wall is named '{stop.wall}'"
                )
            if stop and stop.solid_fraction_above and self.solid_fraction is None:
                raise _FieldError(
                    f"stages[{i}].stop_when.solid_fraction_above",
                    "needs a [solid_fraction] table saying which walls close the container",
                )
            for name in stage.wall_velocities:
                if name not in wall_names:
                    raise _FieldError(
                        f"stages[{i}].wall_velocities.{name}",
                        f"no wall is named '{name}' (walls: {', '.join(wall_names) or 'none'})",
                    )
        for i, wall in enumerate(self.walls):
            if wall_names.index(wall.name) != i:
                raise _FieldError(f"walls[{i}].name", f"wall name '{wall.name}' is used twice")
        names = [stage.name for stage in self.stages]
        for i, name in enumerate(names):
            if names.index(name) != i:
                raise _FieldError(f"stages[{i}].name", f"stage name '{name}' is used twice")
        reversed_stages = [i for i, stage in enumerate(self.stages) if stage.reverse]
        if len(reversed_stages) > 1:
            raise _FieldError(
                f"stages[{reversed_stages[1]}].reverse", "only one stage can be reversed"
            )
        if reversed_stages and reversed_stages[0] != len(self.stages) - 1:
            raise _FieldError(
                f"stages[{reversed_stages[0]}].reverse", "the reversed stage must be the last stage"
            )
        self._check_cell()
        self._check_step_counts()
        self._check_memory()
        self._generate()
        self._check_inside_cell()
        self._check_overlaps()
        self._check_walls()
        return self

    def _check_wall_materials(self) -> None:
        """With contact.wall_moduli = 'wall' a wall's material sets its contacts alone, so no
        sphere may be of it: a sphere pair of that material would be ambiguous."""
        if self.contact.wall_moduli != "wall":
            return
        spheres = {
            item.material: f"{kind}[{i}]"
            for kind, items in self._sphere_sources()
            for i, item in enumerate(items)
        }
        for i, wall in enumerate(self.walls):
            if wall.material in spheres:
                raise _FieldError(
                    f"walls[{i}].material",
                    f"with contact.wall_moduli = 'wall' a wall needs a material of its own; "
                    f"'{wall.material}' is also the material of {spheres[wall.material]}",
                )

    def _check_cell(self) -> None:
        """Stages move the cell only if there is one, and hold a stress only with the
        parameter of its servo; walls and a periodic cell do not go together."""
        if self.cell is not None and self.walls:
            raise _FieldError("walls", "walls cannot be combined with a periodic [cell]")
        for i, stage in enumerate(self.stages):
            if stage.cell is None:
                continue
            if self.cell is None:
                raise _FieldError(f"stages[{i}].cell", "needs a periodic [cell] to move")
            holds = any(a is not None and a.stress is not None for a in stage.cell.axes())
            needed = "servo_mass" if self.cell.servo == "inertial" else "servo_gain"
            if holds and getattr(self.cell, needed) is None:
                raise _FieldError(
                    f"cell.{needed}",
                    f"stages[{i}] holds a stress with the {self.cell.servo} servo, which "
                    f"needs {needed}",
                )

    def _check_inside_cell(self) -> None:
        """Every sphere starts inside the periodic box, which is more than twice as wide as
        the contact reach (2 r_max + skin), so that two spheres touch through one image."""
        import numpy as np

        if self.cell is None:
            return
        x = self._spheres.position
        size = np.array(self.cell.size)
        outside = np.nonzero(((x < 0.0) | (x >= size)).any(axis=1))[0]
        if len(outside):
            where, sphere = self._where(int(outside[0]))
            raise _FieldError(
                where, f"{sphere} starts outside the cell [0, L) of size {list(size)}"
            )
        r_max = float(self._spheres.radius.max())
        reach = 2.0 * r_max + (self.neighbours.skin or 0.1 * r_max)
        for axis, edge in zip("xyz", size, strict=True):
            if edge <= 2.0 * reach:
                raise _FieldError(
                    "cell.size",
                    f"edge {axis} = {edge:.4g} m is not more than twice the contact reach "
                    f"2 r_max + skin = {reach:.4g} m",
                )

    def _check_step_counts(self) -> None:
        """Steps are counted exactly (the engine carries them as float64 too); the steps of a
        stage's frames are listed, and the observables recorded between two frames buffered,
        in memory."""
        total = 0
        for i, stage in enumerate(self.stages):
            total += stage.steps
            if total > MAX_STEPS:
                raise _FieldError(
                    f"stages[{i}].steps",
                    f"the stages add up to {total} steps, more than {MAX_STEPS} (2^53), the "
                    "most a step counter holds exactly",
                )
            frames = stage.steps // stage.output_every + 2
            if frames * BYTES_PER_FRAME > memory_bytes() // 2:
                raise _FieldError(
                    f"stages[{i}].output_every",
                    f"{stage.steps} steps with a frame every {stage.output_every} make {frames} "
                    f"frames, whose list alone needs {_size(frames * BYTES_PER_FRAME)} of memory, "
                    f"more than half of the {_size(memory_bytes())} here; write frames less often",
                )
            rows = stage.output_every // stage.observable_interval + 2
            needed = rows * 8 * (OBSERVABLE_COLUMNS + 6 * len(self.walls))
            if needed > memory_bytes() // 2:
                field = "observables_every" if stage.observables_every else "output_every"
                raise _FieldError(
                    f"stages[{i}].{field}",
                    f"{rows} rows of observables between two frames (output_every / "
                    f"observables_every) need {_size(needed)} of memory, more than half of the "
                    f"{_size(memory_bytes())} here; record observables less often or write "
                    "frames more often",
                )

    def _check_memory(self) -> None:
        """Refuse, before generating anything, more spheres than this machine's memory holds."""
        per_sphere = BYTES_PER_SPHERE + BYTES_PER_SPHERE_AND_WALL * len(self.walls)
        memory = memory_bytes()
        count = len(self.particles)
        generated = [(f"packings[{k}].count", p) for k, p in enumerate(self.packings)]
        generated += [(f"lattices[{k}].cells", g) for k, g in enumerate(self.lattices)]
        for field, source in generated:
            count += source.count
            if count * per_sphere > memory:
                raise _FieldError(
                    field,
                    f"{count} spheres would need about {_size(count * per_sphere)} of memory "
                    f"({per_sphere} bytes each), more than the {_size(memory)} of this machine",
                )

    def _check_solid_fraction(self) -> None:
        """The container of [solid_fraction]: a cylinder and two planes across its axis."""
        if self.solid_fraction is None:
            return
        walls = {w.name: w for w in self.walls}
        wanted = [("cylinder", self.solid_fraction.cylinder, "cylinder")] + [
            (f"planes[{k}]", name, "plane") for k, name in enumerate(self.solid_fraction.planes)
        ]
        for field, name, kind in wanted:
            if name not in walls or walls[name].type != kind:
                raise _FieldError(f"solid_fraction.{field}", f"no {kind} wall is named '{name}'")
        axis = walls[self.solid_fraction.cylinder].normal
        for k, name in enumerate(self.solid_fraction.planes):
            normal = walls[name].normal
            cross = math.hypot(
                axis[1] * normal[2] - axis[2] * normal[1],
                axis[2] * normal[0] - axis[0] * normal[2],
                axis[0] * normal[1] - axis[1] * normal[0],
            )
            if cross > 1e-9 * math.hypot(*axis) * math.hypot(*normal):
                raise _FieldError(
                    f"solid_fraction.planes[{k}]",
                    f"plane '{name}' is not perpendicular to the axis of the cylinder",
                )

    def _generate(self) -> None:
        import numpy as np

        from revdem_cli.build.packing import PackingError
        from revdem_cli.build.spheres import Spheres

        materials = tuple(self.materials)
        given = Spheres(
            np.array([p.radius for p in self.particles], dtype=np.float64),
            np.array([p.position for p in self.particles], dtype=np.float64).reshape(-1, 3),
            np.array([p.velocity for p in self.particles], dtype=np.float64).reshape(-1, 3),
            np.array([p.angular_velocity for p in self.particles], dtype=np.float64).reshape(-1, 3),
            np.array([materials.index(p.material) for p in self.particles], dtype=np.int64),
            materials,
        )
        parts = [given]
        for i, packing in enumerate(self.packings):
            try:
                parts.append(packing.spheres(materials))
            except PackingError as exc:
                raise _FieldError(f"packings[{i}]", str(exc)) from None
        parts += [lattice.spheres(materials) for lattice in self.lattices]
        spheres = Spheres.join(parts, materials)
        if not len(spheres):
            raise _FieldError(
                "particles", "no spheres: give [[particles]], [[packings]] or [[lattices]]"
            )
        self._spheres = spheres

    @property
    def spheres(self) -> Spheres:
        """Every sphere of the scenario as arrays: those given one by one, then the packings'
        and the lattices'."""
        return self._spheres

    def _check_overlaps(self) -> None:
        """Spheres may touch, or overlap by up to 1 % of the smaller radius (a contact already
        loaded), no more; in a periodic cell, through the nearest image."""
        import numpy as np
        from scipy.spatial import cKDTree

        x, r = self._spheres.position, self._spheres.radius
        size = np.array(self.cell.size) if self.cell else None
        pairs = cKDTree(x, boxsize=size).query_pairs(2.0 * r.max(), output_type="ndarray")
        if not len(pairs):
            return
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        i, j = pairs[:, 0], pairs[:, 1]
        d = x[j] - x[i]
        if size is not None:
            d -= size * np.round(d / size)
        gap = np.linalg.norm(d, axis=1) - r[i] - r[j]
        bad = np.nonzero(gap < -1e-2 * np.minimum(r[i], r[j]))[0]
        if len(bad):
            k = bad[0]
            where, sphere = self._where(int(j[k]))
            raise _FieldError(
                where, f"{sphere} overlaps {self._where(int(i[k]))[1]} by {-gap[k]:.3g} m"
            )

    def _check_walls(self) -> None:
        """Every sphere starts inside the walls: its centre on the inner side of every plane
        and inside every cylinder, reaching past a wall by at most 1 % of its radius."""
        import numpy as np

        if not self.walls:
            return
        x, r = self._spheres.position, self._spheres.radius
        for wall in self.walls:
            normal = np.array(wall.normal) / max(abs(c) for c in wall.normal)
            axis = normal / np.linalg.norm(normal)
            with np.errstate(all="ignore"):
                along = (x - np.array(wall.point)) @ axis
                if wall.type == "plane":
                    past = r - along
                else:
                    rho = np.linalg.norm(x - np.array(wall.point) - along[:, None] * axis, axis=1)
                    past = r - (wall.radius - rho)
                outside = np.nonzero(~(past <= 1e-2 * r))[0]
            if len(outside):
                j = int(outside[0])
                where, sphere = self._where(j)
                side = (
                    "on the inner side of every plane (where its normal points)"
                    if wall.type == "plane"
                    else "inside every cylinder"
                )
                raise _FieldError(
                    where,
                    f"{sphere} (radius {r[j]:.3g} m) reaches {past[j]:.3g} m past the {wall.type} "
                    f"wall '{wall.name}', more than 1 % of its radius: spheres must start {side}",
                )

    def _where(self, index: int) -> tuple[str, str]:
        """(field path, name) of sphere `index` of `spheres`: particles[i].position and
        'sphere i', or packings[k] and 'sphere m of packings[k]'."""
        if index < len(self.particles):
            return f"particles[{index}].position", f"sphere {index}"
        index -= len(self.particles)
        sources = [("packings", k, p) for k, p in enumerate(self.packings)]
        sources += [("lattices", k, g) for k, g in enumerate(self.lattices)]
        for kind, k, source in sources:
            if index < source.count:
                return f"{kind}[{k}]", f"sphere {index} of {kind}[{k}]"
            index -= source.count
        raise IndexError(index)

    @property
    def reversed_stage(self) -> Stage | None:
        return next((stage for stage in self.stages if stage.reverse), None)


MAX_STEPS = 2**53
"""Most steps of a run: the step counter is exact in float64 up to here."""

BYTES_PER_FRAME = 128
"""Memory the engine takes to list the step of a frame (a Python int in a list and a set)."""

OBSERVABLE_COLUMNS = 9
"""Columns of an observables row besides its 6 per wall: the step, 7 scalars and the solid
fraction (kernels.observables)."""

BYTES_PER_SPHERE = 2048
"""Memory a sphere takes in a run, bytes, with room to spare: 0.94 kB measured at a million
spheres with shear history (benchmarks/fcc_hertz.py: its arrays, its share of the pair list
and the scenario's copy of its starting state), twice that for a pair list that grows by
a quarter as a packing densifies and for the checks of a new scenario."""

BYTES_PER_SPHERE_AND_WALL = 160
"""Memory of the contact history of a sphere with a wall, bytes (5 vectors and 4 scalars)."""


def memory_bytes() -> int:
    """Physical memory of this machine, or the memory limit of its control group if that is
    lower, bytes."""
    memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
    except OSError:
        return memory
    return min(memory, int(limit)) if limit.isdigit() else memory


def _size(nbytes: float) -> str:
    """A byte count for people: 3.2 GB, 512 MB, 64 kB."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes:.0f} bytes"


class _FieldError(ValueError):
    """A consistency error located at a field path inside the scenario."""

    def __init__(self, path: str, message: str):
        super().__init__(f"{path}: {message}")


def _field_path(location: tuple) -> str:
    path = ""
    for part in location:
        if isinstance(part, int):
            path += f"[{part}]"
        else:
            path += f".{part}" if path else str(part)
    return path


def describe_validation_error(error: ValidationError) -> str:
    """The first problem of a validation error as `field.path: message`, and how many more."""
    first = error.errors()[0]
    message = first["msg"].removeprefix("Value error, ")
    path = _field_path(first["loc"])
    if first["type"] == "missing":
        message = "missing required field"
    elif first["type"] == "extra_forbidden":
        message = "unknown field"
    text = f"{path}: {message}" if path else message
    more = len(error.errors()) - 1
    return text + (f" (and {more} more problem{'s' * (more > 1)})" if more else "")


_YAML_FLOAT = re.compile(r"^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+|[-+]?inf)$", re.I)
"""A float with an exponent and no dot, 1e-7, and inf as TOML writes it: PyYAML (YAML 1.1)
reads them as text."""


def _yaml_loader():
    """PyYAML's safe loader, reading 1e-7 as the number YAML 1.2 says it is."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML_FLOAT, list("-+0123456789iI"))
    return Loader


def parse_text(text: str, suffix: str, origin: str) -> dict:
    """Parse scenario text as TOML or YAML, chosen by the file suffix."""
    if suffix in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.load(text, Loader=_yaml_loader())
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f" at line {mark.line + 1}" if mark else ""
            raise InputError(f"{origin}: not valid YAML{where}") from None
    elif suffix == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{origin}: not valid TOML: {exc}") from None
    else:
        raise InputError(f"{origin}: unknown scenario format '{suffix}' (use .toml, .yaml or .yml)")
    if not isinstance(data, dict):
        raise InputError(f"{origin}: a scenario must be a table of fields")
    return data


def apply_overrides(data: dict, overrides: list[str], origin: str) -> dict:
    """Apply ``key.sub=value`` overrides; values are read as TOML values, else as strings."""
    for item in overrides:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise InputError(f"--set {item}: expected key=value")
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw
        node = data
        parts = key.split(".")
        for part in parts[:-1]:
            node = _child(node, part, key)
        last = parts[-1]
        if isinstance(node, list):
            node[_index(node, last, key)] = value
        else:
            node[last] = value
    return data


def _child(node, part: str, key: str):
    if isinstance(node, list):
        return node[_index(node, part, key)]
    if not isinstance(node, dict):
        raise InputError(f"--set {key}: '{part}' is not inside a table")
    return node.setdefault(part, {})


def _index(node: list, part: str, key: str) -> int:
    if not part.isdigit() or int(part) >= len(node):
        raise InputError(f"--set {key}: '{part}' is not an index of a list of {len(node)}")
    return int(part)


def scenario_from_text(text: str, suffix: str, origin: str, overrides: list[str] = ()) -> Scenario:
    data = apply_overrides(parse_text(text, suffix, origin), list(overrides), origin)
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"{origin}: {describe_validation_error(exc)}") from None


def load_scenario(path: str | Path, overrides: list[str] = ()) -> tuple[Scenario, str]:
    """Read and validate a scenario file; returns the scenario and its text (kept in outputs)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not a text file"
        raise InputError(f"{path}: cannot read scenario file ({reason})") from None
    return scenario_from_text(text, path.suffix.lower(), str(path), overrides), text
