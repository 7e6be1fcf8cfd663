"""Critical time step studies: Figures 3-6 of Peng, Burns & Hanley (2020) from a file.

A study file (TOML or YAML) says `kind = "critical_time_step"`; `revdem run` validates it
as a `TimestepStudy` and writes the chosen figures as PNG and CSV. Every parameter defaults
to the paper's value (Section 6), so a file with only kind and name reproduces the paper.
Loading turns every problem into an `InputError` naming the file and the field path, e.g.
``ellipsoid_dt.toml: particle.density: Input should be greater than 0``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from revdem_cli.config import apply_overrides, describe_validation_error, parse_text
from revdem_cli.errors import InputError, check_regular
from revdem_cli.timestep import shapes

KIND = "critical_time_step"

Exponent = Annotated[float, Field(gt=0, le=2)]
Length = Annotated[float, Field(gt=0)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Span(_Model):
    """`count` evenly spaced values from `start` to `stop`, both included."""

    start: float = Field(gt=0, description="first value, in the unit of the swept quantity")
    stop: float = Field(gt=0, description="last value, in the unit of the swept quantity")
    count: int = Field(ge=1, description="number of values, -")

    @model_validator(mode="after")
    def _ordered(self) -> Span:
        if self.stop < self.start:
            raise ValueError(f"stop ({self.stop:g}) must not be below start ({self.start:g})")
        return self

    def values(self):
        """The values as a NumPy array."""
        import numpy as np

        return np.linspace(self.start, self.stop, self.count)


class DampingSpan(Span):
    """As `Span`, from zero damping up."""

    start: float = Field(ge=0, description="first value, in the unit of the swept quantity")


class Particle(_Model):
    """The particle of Figures 4-6; each figure puts two identical ones in contact."""

    shape: Literal["ellipsoid", "superquadric"] = Field(
        default="ellipsoid",
        description="'ellipsoid' (the paper's), or 'superquadric' with exponents",
    )
    semi_axes: tuple[Length, Length, Length] = Field(
        default=(3.0, 2.0, 1.0),
        description="semi-axes a, b, c of Figures 4 and 5, m; Figure 6 sets them from its "
        "aspect ratios and volume",
    )
    exponents: tuple[Exponent, Exponent] | None = Field(
        default=None,
        description="superquadric exponents ε1, ε2 in (0, 2], -; 1, 1 is the ellipsoid",
    )
    density: float = Field(
        default=1000.0,
        gt=0,
        description="particle density of Figures 4 and 6, kg/m^3; Figure 5 sweeps it",
    )

    @model_validator(mode="after")
    def _exponents_match_shape(self) -> Particle:
        if self.shape == "superquadric" and self.exponents is None:
            raise ValueError("a superquadric needs exponents (ε1, ε2)")
        if self.shape == "ellipsoid" and self.exponents is not None:
            raise ValueError("exponents belong to shape = 'superquadric'")
        return self

    def body(self, density: float, semi_axes: tuple[float, float, float]) -> shapes.Body:
        """This particle's shape at `density` (kg/m³) with `semi_axes` (m)."""
        if self.shape == "superquadric":
            return shapes.superquadric(*semi_axes, *self.exponents, density)
        return shapes.ellipsoid(*semi_axes, density)


class Contact(_Model):
    """The linear spring-dashpot contact of Figures 4-6 (Peng 2020 Eq 29), k_s = k_n."""

    kn: float = Field(
        default=1e10,
        gt=0,
        description="contact stiffness k_n = k_s of Figures 5 and 6, N/m; Figure 4 sweeps it",
    )
    damping_numbers: tuple[Annotated[float, Field(ge=0)], ...] = Field(
        default=(0.0, 1.0, 2.0, 3.0, 4.0, 5.0),
        min_length=1,
        description="damping numbers N of Figures 4 and 5, one curve each: "
        "c_n = c_s = N sqrt(k_n / A_max) (Peng 2020 Section 6.2), -",
    )


def integrate_every(default: int, point: str):
    """The field of a figure that checks its criterion by integration at every n-th point of
    its sweep (`point`: what it sweeps)."""
    return Field(
        default=default,
        ge=0,
        description=f"find the velocity-Verlet limit by integration at every n-th {point}, "
        "the first included; 0 for none, -",
    )


def integrate_rigid_every(point: str):
    """The field of a figure that integrates the two rigid bodies at every n-th point of its
    sweep (`point`: what it sweeps); none by default."""
    return Field(
        default=0,
        ge=0,
        description="integrate the two rigid bodies (Figure 2 and 8 random configurations, "
        f"about 7 s a point and N) at every n-th {point}, the first included; 0 for none, -",
    )


class Figure3(_Model):
    """Two equal spheres, Δt √(k/m) against β = c/√(mk) (Peng 2020 Section 6.1, Eq 58-60)."""

    beta: DampingSpan = Field(
        default=DampingSpan(start=0.0, stop=3.0, count=301),
        description="damping β = c / sqrt(m k) of the two spheres, -",
    )
    integrate_every: int = integrate_every(25, "β")


class Figure4(_Model):
    """The particle pair against the contact stiffness (Peng 2020 Section 6.2)."""

    kn: Span = Field(
        default=Span(start=1e10, stop=1e11, count=37),
        description="contact stiffness k_n = k_s swept, N/m",
    )
    integrate_every: int = integrate_every(12, "k_n")
    integrate_rigid_every: int = integrate_rigid_every("k_n")


class Figure5(_Model):
    """The particle pair against the particle density (Peng 2020 Section 6.3)."""

    density: Span = Field(
        default=Span(start=500.0, stop=5000.0, count=37),
        description="particle density swept, kg/m^3",
    )
    integrate_every: int = integrate_every(12, "density")
    integrate_rigid_every: int = integrate_rigid_every("density")


class Figure6(_Model):
    """The undamped pair against the aspect ratios at fixed volume (Peng 2020 Section 6.4)."""

    aspect_ratios: Span = Field(
        default=Span(start=1.0, stop=5.0, count=41),
        description="e1 = a/b and e2 = b/c, each over this span (the grid of both), -",
    )
    plotted_e2: tuple[Annotated[float, Field(ge=1)], ...] = Field(
        default=(1.0, 2.0, 3.0, 4.0, 5.0),
        min_length=1,
        description="e2 of the curves drawn against e1, each one of the aspect ratios, -",
    )
    volume: float = Field(default=8.0 * math.pi, gt=0, description="volume V of each particle, m^3")
    omega_max: float = Field(
        default=1.0,
        gt=0,
        description="largest angular speed of the rotation-dominant Δt (Eq 56), rad/s",
    )

    @model_validator(mode="after")
    def _ratios_are_ordered_and_drawn(self) -> Figure6:
        import numpy as np

        if self.aspect_ratios.start < 1.0:
            raise ValueError("aspect ratios start at 1 or above: a ≥ b ≥ c (Section 6.4)")
        grid = self.aspect_ratios.values()
        for e2 in self.plotted_e2:
            if not np.isclose(grid, e2).any():
                raise ValueError(f"plotted_e2 = {e2:g} is not one of the aspect ratios")
        return self


class TimestepStudy(_Model):
    """A critical time step study: which of Peng 2020 Figures 3-6 to write, and their inputs."""

    kind: Literal["critical_time_step"] = Field(
        description="what the file describes: 'critical_time_step' (a DEM scenario has no kind)"
    )
    name: str = Field(
        pattern=r"^[A-Za-z0-9_.-]+$",
        description="study name, used for output file names: <name>.figure3.png, ...",
    )
    description: str = Field(default="", description="free text")
    figures: tuple[Literal[3, 4, 5, 6], ...] = Field(
        default=(3, 4, 5, 6),
        min_length=1,
        description="which of the paper's Figures 3-6 to write, each once",
    )
    particle: Particle = Field(default_factory=Particle, description="particle of Figures 4-6")
    contact: Contact = Field(default_factory=Contact, description="contact of Figures 4-6")
    figure3: Figure3 = Field(default_factory=Figure3, description="Figure 3: damping, spheres")
    figure4: Figure4 = Field(default_factory=Figure4, description="Figure 4: stiffness")
    figure5: Figure5 = Field(default_factory=Figure5, description="Figure 5: density")
    figure6: Figure6 = Field(default_factory=Figure6, description="Figure 6: aspect ratios")

    @model_validator(mode="after")
    def _figures_once(self) -> TimestepStudy:
        if len(set(self.figures)) != len(self.figures):
            raise ValueError(f"figures {list(self.figures)}: name each figure once")
        return self


PAPER = TimestepStudy(
    kind=KIND, name="peng2020", description="Peng, Burns & Hanley 2020, Figures 3-6"
)


def _validated(data: dict, origin: str, overrides: list[str]) -> TimestepStudy:
    data = apply_overrides(data, list(overrides), origin)
    try:
        return TimestepStudy.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"{origin}: {describe_validation_error(exc, TimestepStudy)}") from None


def study_from_text(
    text: str, suffix: str, origin: str, overrides: list[str] = ()
) -> TimestepStudy:
    """Parse TOML or YAML text (chosen by `suffix`), apply `--set` overrides, validate."""
    return _validated(parse_text(text, suffix, origin), origin, overrides)


def read_study(path: str | Path, overrides: list[str] = ()) -> TimestepStudy | None:
    """The study in the file at `path`; None when the file says no `kind = "critical_time_step"`.

    A file that cannot be read is no study here: the scenario loader reports it.
    """
    path = Path(path)
    check_regular(path, "scenario file")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError):
        return None
    data = parse_text(text, path.suffix.lower(), str(path))
    if data.get("kind") != KIND:
        return None
    return _validated(data, str(path), overrides)


def _stems(study: TimestepStudy) -> dict[int, str]:
    """The file stem of each figure of the study: <name>.figure<n>."""
    return {number: f"{study.name}.figure{number}" for number in study.figures}


def study_outputs(study: TimestepStudy, out_dir: Path) -> list[Path]:
    """Every file `run_study` writes into `out_dir`."""
    from revdem_cli.timestep.figures import study_files

    return study_files(Path(out_dir), study, _stems(study))


def run_study(study: TimestepStudy, out_dir: Path) -> Iterator[Path]:
    """Write the study's figures into `out_dir` as <name>.figure<n>.png and .csv; each path
    once written."""
    from revdem_cli.timestep.figures import write_figures

    yield from write_figures(Path(out_dir), study, _stems(study))
