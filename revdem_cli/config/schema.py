"""The scenario schema: pure pydantic models of a scenario file, each field with its unit.

A model checks its own fields (and, through `checks`, how the fields of a whole scenario fit
together), and nothing else: it generates no spheres and reads nothing of the machine, so
that a scenario stored in a file is validated again in a moment. The spheres it describes
are generated when first asked for (`Scenario.spheres`); `geometry` checks them and `host`
checks what a run of it needs of this machine, both at the edge (`loader`).
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PlainValidator,
    PrivateAttr,
    WithJsonSchema,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.json_schema import GenerateJsonSchema

from revdem_cli import laws, wall_shapes
from revdem_cli.config.checks import tape_needs

if TYPE_CHECKING:
    from revdem_cli.assembly.spheres import Spheres


def _number(value):
    """A number as the file wrote it: true/false and text are not numbers (pydantic would
    read true as 1 and "0.005" as 0.005)."""
    if isinstance(value, bool):
        raise ValueError(f"Input should be a valid number, not {str(value).lower()}")
    if isinstance(value, str):
        raise ValueError(f"Input should be a valid number, not the text {value[:40]!r}")
    return value


def _number_or_inf(value):
    """A number as `_number` takes it, which may be infinite but not NaN (pydantic would
    check NaN against the field's bounds and say it is out of them)."""
    if isinstance(_number(value), float) and math.isnan(value):
        raise ValueError("Input should be a finite number or inf")
    return value


def _time_step(value):
    """A time step as the file wrote it: a positive, finite number of seconds, or 'auto'."""
    if value == "auto":
        return value
    if isinstance(value, str):
        raise ValueError(
            f"Input should be a valid number of seconds or 'auto', not the text {value[:40]!r}"
        )
    if not isinstance(_number(value), int | float):
        raise ValueError("Input should be a valid number of seconds or 'auto'")
    if not math.isfinite(value):
        raise ValueError("Input should be a finite number")
    if value <= 0:
        raise ValueError("Input should be greater than 0")
    return float(value)


Float = Annotated[float, BeforeValidator(_number)]
TimeStep = Annotated[
    float | Literal["auto"],
    PlainValidator(_time_step),
    WithJsonSchema({"anyOf": [{"type": "number", "exclusiveMinimum": 0}, {"const": "auto"}]}),
]
"""A time step, s, or 'auto': chosen at the start of each stage (`packing.automatic_dt`)."""
FloatOrInf = Annotated[float, Field(allow_inf_nan=True), BeforeValidator(_number_or_inf)]
Int = Annotated[int, BeforeValidator(_number)]
Vector3 = Annotated[tuple[Float, Float, Float], Field(description="three components (x, y, z)")]


BOUNDS = {"ge": "minimum", "gt": "exclusiveMinimum", "le": "maximum", "lt": "exclusiveMaximum"}
"""A bound of a field as pydantic names it, and as JSON Schema does."""


class _StandardBounds(GenerateJsonSchema):
    """pydantic's JSON schema with every bound under JSON Schema's keyword. A bound on an
    optional field of a type with a validator of its own (`Float | None = Field(ge=0)`) is
    checked by a validator pydantic wraps round the type, which writes the bound into the
    schema under its own name ("ge": 0), a keyword JSON Schema does not know, so that an
    editor or a validator of scenario files ignored it; every other bound is written as
    "minimum" and the like."""

    def generate(self, schema, mode="validation"):
        return _standard_bounds(super().generate(schema, mode))


def _standard_bounds(node):
    """A JSON schema (a part of one) with the bounds of each number's schema (one that says
    its type: not `properties`, whose keys are field names) under JSON Schema's keywords."""
    if isinstance(node, list):
        return [_standard_bounds(item) for item in node]
    if not isinstance(node, dict):
        return node
    bounded = node.get("type") in ("number", "integer")
    return {
        (BOUNDS.get(key, key) if bounded else key): _standard_bounds(value)
        for key, value in node.items()
    }


class _Model(BaseModel):
    model_config = ConfigDict(
        extra="forbid", allow_inf_nan=False, frozen=True, ser_json_inf_nan="constants"
    )

    @classmethod
    def model_json_schema(cls, *args, schema_generator=_StandardBounds, **kwargs) -> dict:
        """pydantic's, with every bound under JSON Schema's keyword (`_StandardBounds`)."""
        return super().model_json_schema(*args, schema_generator=schema_generator, **kwargs)

    @model_validator(mode="before")
    @classmethod
    def _none_is_the_default(cls, data):
        """A field given as None (`--set gravity=`, the API's None, YAML's null) unset: it
        takes its default, where it has one that is not None (gravity, walls, output), as
        one whose default is None does; a field without a default stays refused."""
        if not isinstance(data, dict):
            return data
        fields = cls.model_fields
        return {
            key: value
            for key, value in data.items()
            if value is not None or key not in fields or fields[key].is_required()
        }


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


NORMAL_DAMPING = (
    "c_n = 2 beta_n sqrt(m* k_n), the fraction of critical of the pair's normal motion (Peng "
    "2020 Eq 29, 37)"
)
SHEAR_DAMPING = (
    "c_s = 2 beta_t sqrt(m* k_s), the fraction of critical of the spheres sliding without "
    "turning (free to turn, a pair's shear motion is critical at 2 sqrt(m* k_s / 3.5), Peng "
    "2020 Eq 26, 37)"
)


class _Contact(_Model):
    """The parts of a contact that belong to no one law: Coulomb friction, viscous damping
    and how a wall's moduli combine."""

    friction: FloatOrInf | None = Field(
        default=None,
        ge=0,
        description="Coulomb friction coefficient mu, -; inf for no sliding",
    )
    normal_damping: Float = Field(
        default=0.0, ge=0, description=f"viscous normal damping beta_n: {NORMAL_DAMPING}, -"
    )
    tangential_damping: Float = Field(
        default=0.0,
        ge=0,
        description=f"viscous tangential damping beta_t: {SHEAR_DAMPING}, -; needs a tangential "
        "law",
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
        return self


Contact = create_model(
    "Contact",
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


class _Wall(_Model):
    """A wall of one of the shapes of `revdem_cli.wall_shapes`, moving at a fixed velocity."""

    name: str = Field(pattern=r"^[A-Za-z0-9_-]+$", description="wall name, used for its force")
    material: str = Field(description="name of a material in [materials]")
    point: Vector3 = Field(description="a point of the wall, as its type says, m")
    normal: Vector3 = Field(description="the wall's direction, as its type says, -")
    velocity: Vector3 = Field(default=(0.0, 0.0, 0.0), description="wall velocity, m/s")

    @property
    def across_z(self) -> bool:
        """A plane whose normal lies nearest z: a platen, whose z force is its load (the
        `wall_forces` figure's); a side wall's z force is friction."""
        return self.type == "plane" and abs(self.normal[2]) == max(map(abs, self.normal))

    @model_validator(mode="after")
    def _shape(self) -> _Wall:
        if math.hypot(*self.normal) == 0:
            raise ValueError("normal must not be zero")
        squared = sum(c * c for c in self.normal)  # as the engine normalises it
        if not sys.float_info.min <= squared < math.inf:
            raise ValueError(
                f"normal {list(self.normal)} is too {'short' if squared < 1 else 'long'} to "
                "normalise in floating point; give a direction such as [0, 0, 1]"
            )
        shape = wall_shapes.SHAPES[self.type]
        for field in wall_shapes.fields():
            given = getattr(self, field) is not None
            if field in shape.REQUIRED and not given:
                raise ValueError(f"a {self.type} needs {field}: {shape.FIELDS[field].description}")
            if given and field not in shape.FIELDS:
                raise ValueError(f"a {self.type} has no {field}")
        return self


Wall = create_model(
    "Wall",
    __base__=_Wall,
    __doc__=_Wall.__doc__,
    type=(
        Literal[tuple(wall_shapes.SHAPES)],
        Field(
            description="; ".join(
                f"'{name}', {shape.SUMMARY}" for name, shape in wall_shapes.SHAPES.items()
            )
        ),
    ),
    **{name: (Float | None, info) for name, info in wall_shapes.fields().items()},
)


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


OVERLAP_AT_START = 0.01
"""How deep spheres may overlap where they start, of the smaller radius (a contact already
loaded; `geometry.check_overlaps`), but for a data file's own (`ParticlesFrom.max_overlap`)."""


class ParticlesFrom(_Model):
    """Spheres read from a file another code wrote: a LAMMPS data file of atom_style sphere
    in units si (`write_data`), its atoms numbered in space (or in the order of their ids,
    `order`), each keeping its id, with their diameters, positions (inside the box; in a
    periodic one from its lower corner, image flags set aside) and, where the file has them,
    velocities and angular velocities. A sphere's mass
    is its material's density times its volume: the density the file gives must be that
    material's."""

    lammps_data: str = Field(
        min_length=1, description="path of the LAMMPS data file, relative to the scenario file"
    )
    materials: dict[str, str] = Field(
        min_length=1, description="the material in [materials] of each LAMMPS atom type, by type"
    )

    @field_validator("materials", mode="before")
    @classmethod
    def _types_as_text(cls, value):
        """An atom type is a number: YAML's {1: glass} gives it as one, TOML's as text."""
        if isinstance(value, dict):
            return {
                str(k) if isinstance(k, int) and not isinstance(k, bool) else k: v
                for k, v in value.items()
            }
        return value

    periodic: bool = Field(
        strict=True,
        default=False,
        description="the file's box is the scenario's periodic [cell] (a data file does not "
        "say which axes are periodic): [cell] size must be its edges, and positions are "
        "taken relative to its lower corner",
    )
    max_overlap: float = Field(
        default=OVERLAP_AT_START,
        ge=0.0,
        le=0.5,
        description="how deep the file's spheres may overlap one another, of the smaller "
        "radius: a loaded packing (compressed, confined, as LAMMPS' read_data takes any) "
        "starts with its contacts' overlaps, a few %; spheres elsewhere start no deeper "
        "than 0.01, which catches two placed at one point",
    )
    order: Literal["space", "ids"] = Field(
        default="space",
        description="the spheres' order in memory, each keeping its atom id in every output: "
        "'space', numbered cell by cell in space, as [[packings]] are "
        "(`assembly.packing.spatial_order`), as LAMMPS sorts its atoms; 'ids', sphere k the "
        "atom of the k-th smallest id: atoms numbered as they were inserted at random step up "
        "to 3 times slower",
    )
    count: Int | None = Field(
        default=None,
        gt=0,
        le=MAX_GENERATED,
        description="number of spheres in the file, read from its header as the scenario is "
        "loaded (given, it must be the header's)",
    )


class Integrator(_Model):
    """Velocity-Verlet time integration (Hanley 2020 Eq 1-3, 11-12), optionally with a
    time-reversible velocity predictor for the damping forces (Kolafa & Lisal 2011)."""

    dt: TimeStep = Field(description="time step, s, or 'auto' (see dt_safety)")
    dt_safety: Float = Field(
        default=0.2,
        gt=0,
        le=1,
        description="with dt = 'auto', the fraction taken, at the start of each stage, of the "
        "smallest of the critical time step of the packing then (the largest eigenvalue of its "
        "mass and stiffness, as `revdem dt --restart`), the start-up estimate of contacts "
        "still to form (head-on impacts, Rayleigh) and the kinematic limit (half the skin a "
        "step), -; the start-up estimate is one contact's limit, which a sphere in many "
        "contacts lowers to 1/sqrt(12) of it at most (half in an fcc lattice): above 0.29, a "
        "stage that forms its packing (a pour, a lattice pressed from touching) may blow up",
    )
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
    scheme: Literal["verlet", "trvp"] = Field(
        default="verlet",
        description="how velocity-dependent forces (local damping Eq 21, viscous contact "
        "damping) read the velocity at a full step: 'verlet', the half-step velocity "
        "v(t - dt/2) as Hanley 2020 does; 'trvp', the time-reversible velocity predictor of "
        "Kolafa & Lisal 2011, sum_j b_j v(t - (j + 1/2) dt) over the last trvp_order + 1 "
        "half-step velocities",
    )
    trvp_order: int | None = Field(
        default=None,
        ge=1,
        le=4,
        description="order k of the time-reversible velocity predictor (k + 1 half-step "
        "velocities, error of the forward-reversed asymmetry O(dt^(2k+1))), -; with "
        "scheme = 'trvp' only, default 2",
    )

    @property
    def predictor_order(self) -> int:
        """k of the velocity predictor; 0 for velocity Verlet (the half-step velocity)."""
        if self.scheme == "verlet":
            return 0
        return 2 if self.trvp_order is None else self.trvp_order


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
        default=None,
        description="a wall has moved further than a distance since the stage began (one "
        "the stage moves: walls move at their velocity alone)",
    )
    solid_fraction_above: Float | None = Field(
        default=None,
        gt=0,
        lt=1,
        description="the solid fraction of [solid_fraction], or of the periodic [cell] (the "
        "spheres' volume over the cell's, 1 / (1 + void ratio)), above this",
    )
    after_steps: Int | None = Field(
        default=None,
        gt=0,
        description="steps of the stage before the condition is first checked, fewer than its "
        "steps, -: a pour from rest meets kinetic_energy_below at once without it",
    )

    @model_validator(mode="after")
    def _one(self) -> StopWhen:
        conditions = [name for name in type(self).model_fields if name != "after_steps"]
        if sum(getattr(self, name) is not None for name in conditions) != 1:
            raise ValueError(f"give exactly one of {', '.join(conditions)}")
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


SERVO_PARAMETERS = {
    "inertial": ("servo_mass", "too small"),
    "proportional": ("servo_gain", "too large"),
}
"""Each kind of servo of [cell]: the parameter only it has, and which way that parameter
makes an edge overshoot its target stress (a light edge mass, a high gain)."""


class PeriodicCell(_Model):
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

    @property
    def servo_parameter(self) -> str:
        """The parameter only this kind of servo has, which it needs to hold a stress."""
        return SERVO_PARAMETERS[self.servo][0]

    @model_validator(mode="after")
    def _positive(self) -> PeriodicCell:
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


class StageContact(_Model):
    """The Coulomb and viscous coefficients of [contact] during one stage; a field not given
    keeps its [contact] value. The laws and their moduli stay those of [contact]."""

    friction: FloatOrInf | None = Field(
        default=None,
        ge=0,
        description="Coulomb friction coefficient mu during this stage, -; inf for no sliding",
    )
    normal_damping: Float | None = Field(
        default=None,
        ge=0,
        description=f"viscous normal damping beta_n during this stage: {NORMAL_DAMPING}, -",
    )
    tangential_damping: Float | None = Field(
        default=None,
        ge=0,
        description=f"viscous tangential damping beta_t during this stage: {SHEAR_DAMPING}, -",
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
        description="record observables every this many steps; default: output_every; with "
        "stop_when, how often its condition is checked (at least once before the last step)",
    )
    reverse: bool = Field(
        strict=True,
        default=False,
        description="save the end of this stage as the restart and run it backwards in time",
    )
    dt: TimeStep | None = Field(
        default=None, description="time step of this stage, s, or 'auto'; default: integrator.dt"
    )
    damping: Damping | None = Field(
        default=None, description="damping during this stage; default: [damping]"
    )
    stop_when: StopWhen | None = Field(
        default=None,
        description="end the stage early, at the first observables row or frame where this holds",
    )
    wall_velocities: dict[str, Vector3] = Field(
        default_factory=dict,
        description="velocity of named walls during this stage, m/s; the others move at the "
        "velocity given in [[walls]]",
    )
    cell: CellMotion | None = Field(
        default=None, description="motion of the periodic cell's edges; default: all fixed"
    )
    contact: StageContact | None = Field(
        default=None,
        description="friction and viscous damping of the contacts during this stage; "
        "default: those of [contact]",
    )

    @property
    def observable_interval(self) -> int:
        return self.observables_every or self.output_every

    def wall_velocity(self, wall: Wall) -> Vector3:
        """The velocity of `wall` during this stage, m/s: its own in `wall_velocities`, else
        the one of [[walls]]. Walls move at it alone (from where the stage finds them)."""
        return self.wall_velocities.get(wall.name, wall.velocity)

    def held_stresses(self) -> dict[str, float]:
        """The stress, Pa, this stage holds on each axis of the cell with its servo, by axis
        ('x', 'y', 'z'); {} where it holds none."""
        axes = self.cell.axes() if self.cell is not None else [None] * 3
        return {axis: m.stress for axis, m in zip("xyz", axes, strict=True) if m and m.stress}


class Reversal(_Model):
    """Tolerances that decide whether a reversed run reproduced the forward one, and the
    information tape that makes it reproduce it exactly."""

    position_tolerance_rel: Float = Field(
        default=1e-10, gt=0, description="largest position error divided by the smallest diameter"
    )
    velocity_tolerance: Float = Field(default=1e-9, gt=0, description="largest velocity error, m/s")
    angular_velocity_tolerance: Float = Field(
        default=1e-6, gt=0, description="largest angular velocity error, rad/s"
    )
    tape: bool = Field(
        strict=True,
        default=False,
        description="record, going forward through the reversed stage, what its reversal "
        "cannot recompute (the information tape, `<name>.tape.h5` beside the restart), so "
        "that the reversal returns the starting integers bit for bit whatever friction, "
        "damping, drag, contact loss or a servo destroyed, and the bits they destroyed are "
        f"measured; needs {tape_needs()}",
    )
    all_stages: bool = Field(
        strict=True,
        default=False,
        description="reverse every stage back to the start, not only the last: each stage "
        "records its tape and leaves a restart at its end (`<name>.stage-K.restart.h5`, "
        "`.tape.h5`), and the reversed run goes on through them to step 0; needs tape = true",
    )


FIGURE_KINDS = (
    "speed", "forces", "velocity_z", "wall_forces", "stress_ratios", "contact_forces",
    "contact_normals", "information",
)  # fmt: skip
"""The figures `revdem_cli.report.figures.FIGURES` draws."""


class Output(_Model):
    """What is written besides the trajectories."""

    figures: list[Literal[FIGURE_KINDS]] = Field(
        default_factory=list,
        description="figures written beside the trajectories, forward and reversed overlaid: "
        "'speed' = |v| of each particle, 'forces' = largest normal and shear contact force, "
        "'velocity_z' = vertical velocity of each particle, all against time; 'wall_forces' "
        "= z force on each plane wall across z (a platen) against the solid fraction (or "
        "against time); "
        "'stress_ratios' = principal stress ratios and coordination number against the "
        "compression of a periodic cell; with contacts = true, at the end of the run: "
        "'contact_forces' = distribution of normal contact forces over their mean, semi-log; "
        "'contact_normals' = rose diagrams of the contact normals in the xz and xy planes; "
        "with reversal.tape = true, 'information' = the bits the reversed stage destroyed, "
        "by mechanism, summed and per step, against time or the compression of the cell",
    )
    particle_stress: bool = Field(
        strict=True,
        default=False,
        description="write each sphere's stress (Hanley 2020 Eq 22) at every frame, "
        "particles/all/stress [F, N, 3, 3], Pa",
    )
    contacts: bool = Field(
        strict=True,
        default=False,
        description="write every contact at every frame (connectivity/contacts: the pair or "
        "sphere and wall, contact point, normal and tangential force, overlap, sliding), for "
        "force chains (`revdem export`) and the contact figures",
    )

    @model_validator(mode="after")
    def _contact_figures(self) -> Output:
        for k, kind in enumerate(self.figures):
            if kind in self.figures[:k]:
                raise ValueError(f"figure '{kind}' is listed twice")
            if kind.startswith("contact_") and not self.contacts:
                raise ValueError(f"figure '{kind}' needs contacts = true")
        return self

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
    contact: Contact = Field(description="contact law between particles")
    particles: list[Particle] = Field(default_factory=list, description="spheres given one by one")
    packings: list[Packing] = Field(
        default_factory=list, description="spheres generated at random in regions"
    )
    lattices: list[Lattice] = Field(default_factory=list, description="spheres on lattices")
    particles_from: list[ParticlesFrom] = Field(
        default_factory=list, description="spheres read from files other codes wrote"
    )
    walls: list[Wall] = Field(default_factory=list, description="walls")
    cell: PeriodicCell | None = Field(default=None, description="periodic boundaries in x, y and z")
    gravity: Vector3 = Field(
        default=(0.0, 0.0, 0.0),
        description="gravitational acceleration, m/s^2; not with a periodic [cell], which has no "
        "walls to hold the spheres",
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
            ("particles_from", self.particles_from),
        )

    @model_validator(mode="after")
    def _consistent(self) -> Scenario:
        from revdem_cli.config.checks import check_consistency

        check_consistency(self)
        return self

    @property
    def sphere_count(self) -> int:
        """How many spheres the scenario makes, without making them."""
        return sum(
            len(items) if kind == "particles" else sum(item.count for item in items)
            for kind, items in self._sphere_sources()
        )

    @property
    def spheres(self) -> Spheres:
        """Every sphere of the scenario as arrays: those given one by one, then the packings'
        and the lattices', generated when first asked for (`geometry.generate`)."""
        if self._spheres is None:
            from revdem_cli.config.geometry import generate

            self._spheres = generate(self)
        return self._spheres

    def forget_spheres(self) -> None:
        """Drop the generated spheres, once a state holds them (`state.initial_state`), so that
        a run does not keep their starting positions and velocities twice; they are generated
        again if asked for."""
        self._spheres = None

    @property
    def servo(self) -> str | None:
        """The kind of the periodic cell's servo, 'inertial' or 'proportional'; None without
        a cell."""
        return self.cell.servo if self.cell else None

    @property
    def reversed_stage(self) -> Stage | None:
        return next((stage for stage in self.stages if stage.reverse), None)

    def stage_dt(self, stage: Stage) -> TimeStep:
        """The time step `stage` is given, s, or 'auto': its own, else [integrator]'s."""
        return stage.dt or self.integrator.dt
