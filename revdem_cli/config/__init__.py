"""Scenarios in layers: `schema` (pure pydantic models), `checks` (how a scenario's fields
fit together; run by the schema's validation), `geometry` (its spheres, generated and
checked where they start), `host` (whether a run fits this machine; `revdem run` alone) and
`loader` (TOML and YAML files, `--set`, errors naming the file and the field path).

Validating a stored scenario (`Scenario.model_validate_json`) runs the schema and
`checks.check_consistency` only: what `checks.check_given` refuses in a scenario given, a
run's outputs stored before keep, and stay readable.
"""

from revdem_cli.config.loader import (
    apply_overrides,
    describe_validation_error,
    dotted,
    fields_apart,
    load_scenario,
    parse_text,
    read_value,
    scenario_from_data,
    scenario_from_text,
    set_field,
)
from revdem_cli.config.schema import (
    AxisMotion,
    CellMotion,
    Contact,
    Damping,
    Integrator,
    Lattice,
    Material,
    Neighbours,
    Output,
    Packing,
    Particle,
    ParticlesFrom,
    PeriodicCell,
    Region,
    Reversal,
    Scenario,
    SolidFraction,
    Stage,
    StopWhen,
    Wall,
)

__all__ = [
    "AxisMotion",
    "CellMotion",
    "Contact",
    "Damping",
    "Integrator",
    "Lattice",
    "Material",
    "Neighbours",
    "Output",
    "Packing",
    "Particle",
    "ParticlesFrom",
    "PeriodicCell",
    "Region",
    "Reversal",
    "Scenario",
    "SolidFraction",
    "Stage",
    "StopWhen",
    "Wall",
    "apply_overrides",
    "dotted",
    "fields_apart",
    "describe_validation_error",
    "load_scenario",
    "parse_text",
    "read_value",
    "scenario_from_data",
    "scenario_from_text",
    "set_field",
]
