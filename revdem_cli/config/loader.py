"""Scenario files (TOML or YAML) into validated scenarios: parsing, `--set` overrides, and
every problem as an `InputError` naming the file and the field path, e.g. ``collision.toml:
particles[1].radius: must be greater than 0``."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from pydantic import BaseModel, ValidationError

from revdem_cli.config.checks import FieldError, check_given
from revdem_cli.config.geometry import check_spheres
from revdem_cli.config.host import check_host
from revdem_cli.config.schema import Scenario
from revdem_cli.errors import InputError, check_regular


def _field_path(location: tuple) -> str:
    path = ""
    for part in location:
        if isinstance(part, int):
            path += f"[{part}]"
        else:
            path += f".{part}" if path else str(part)
    return path


def describe_validation_error(error: ValidationError, model: type[BaseModel] = Scenario) -> str:
    """The most useful problem of a validation error of `model` as `field.path: message`,
    and how many more: an unknown field whose name is close to one of its table's (a
    misspelling, whose hint says what was meant) before any other, and a required field it
    stands for not counted again as missing."""
    errors = error.errors()
    meant = {e["loc"]: _meant(model, e["loc"]) for e in errors if e["type"] == "extra_forbidden"}
    stands_for = {location[:-1] + (name,) for location, name in meant.items() if name}
    errors = [e for e in errors if not (e["type"] == "missing" and e["loc"] in stands_for)]
    first = next((e for e in errors if meant.get(e["loc"])), errors[0])
    errors = [first] + [e for e in errors if e is not first]
    message = first["msg"].removeprefix("Value error, ")
    path = _field_path(first["loc"])
    if first["type"] == "missing" and isinstance(first["loc"][-1], int):  # a short tuple
        short = [e for e in errors if e["type"] == "missing" and e["loc"][:-1] == first["loc"][:-1]]
        errors = [e for e in errors if e not in short[1:]]  # one problem, not one an item
        path = _field_path(first["loc"][:-1])
        message = f"{len(first['input']) + len(short)} values needed, {len(first['input'])} given"
    elif first["type"] == "missing":
        message = "missing required field"
    elif first["type"] == "extra_forbidden":
        name = meant[first["loc"]]
        message = "unknown field" + (f" (did you mean {name}?)" if name else "")
    text = f"{path}: {message}" if path else message
    more = len(errors) - 1
    return text + (f" (and {more} more problem{'s' * (more > 1)})" if more else "")


def _meant(model: type[BaseModel], location: tuple) -> str | None:
    """The field of the table of `model` at `location` whose name is closest to the unknown
    one there; None where none is close."""
    import difflib
    import typing

    for part in location[:-1]:
        fields = getattr(model, "model_fields", None)
        if fields is not None and isinstance(part, str) and part in fields:
            model = fields[part].annotation
        elif typing.get_origin(model) in (list, tuple, dict):
            model = typing.get_args(model)[-1]
        else:
            return None
        while typing.get_origin(model) is typing.Union or type(model).__name__ == "UnionType":
            options = [a for a in typing.get_args(model) if a is not type(None)]
            if len(options) != 1:
                return None
            model = options[0]
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        return None
    close = difflib.get_close_matches(str(location[-1]), list(model.model_fields), n=1)
    return close[0] if close else None


_YAML_FLOAT = re.compile(r"^(?:[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+|[-+]?inf)$", re.I)
"""A float with an exponent and no dot, 1e-7, and inf as TOML writes it: PyYAML (YAML 1.1)
reads them as text."""


def _yaml_loader():
    """PyYAML's safe loader, reading 1e-7 as the number YAML 1.2 says it is, and refusing a
    key given twice in one mapping (YAML 1.2 says keys are unique; PyYAML keeps the last)."""
    import yaml

    class Loader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=deep)
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"the key {key!r} is given twice", key_node.start_mark
                    )
                seen.add(key)
            return super().construct_mapping(node, deep=deep)

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML_FLOAT, list("-+0123456789iI"))
    return Loader


MAX_DEPTH = 64
"""Deepest nesting of tables and lists a scenario file may have (a scenario needs 4)."""


def _depth(value, limit: int = MAX_DEPTH) -> int:
    """How deeply tables and lists nest in `value`, counted up to `limit + 1`."""
    stack, deepest = [(value, 0)], 0
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if deepest > limit:
            break
        children = (
            node.values() if isinstance(node, dict) else node if isinstance(node, list) else ()
        )
        stack.extend((child, depth + 1) for child in children)
    return deepest


def parse_text(text: str, suffix: str, origin: str) -> dict:
    """Parse scenario text as TOML or YAML, chosen by the file suffix."""
    if suffix in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.load(text, Loader=_yaml_loader())
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f" at line {mark.line + 1}" if mark else ""
            problem = f": {exc.problem}" if getattr(exc, "problem", None) else ""
            raise InputError(f"{origin}: not valid YAML{where}{problem}") from None
        except RecursionError:
            raise InputError(f"{origin}: nested more than {MAX_DEPTH} levels deep") from None
    elif suffix == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{origin}: not valid TOML: {exc}") from None
        except RecursionError:
            raise InputError(f"{origin}: nested more than {MAX_DEPTH} levels deep") from None
    else:
        raise InputError(f"{origin}: unknown scenario format '{suffix}' (use .toml, .yaml or .yml)")
    if not isinstance(data, dict):
        raise InputError(f"{origin}: a scenario must be a table of fields")
    if _depth(data) > MAX_DEPTH:
        raise InputError(f"{origin}: nested more than {MAX_DEPTH} levels deep")
    return data


def apply_overrides(data: dict, overrides: list[str], origin: str) -> dict:
    """Apply ``key.sub=value`` overrides, each value as `read_value` reads it, and an empty
    one, ``key.sub=``, as None: an optional field so given is unset (its default, or none:
    `stages.0.stop_when=`), as the API's None does; a key given twice is refused, as
    `revdem sweep` refuses it, not cut to its last value."""
    given: dict[str, str] = {}
    for item in overrides:
        name, raw = split_override(item)
        if name in given:
            raise InputError(f"--set {item}: {name} is given twice (also --set {given[name]})")
        given[name] = item
        value = read_value(raw, f"--set {item}") if raw.strip() else None
        set_field(data, name, value, "--set ")
    return data


def split_override(item: str) -> tuple[str, str]:
    """The field's path (`dotted`) and the value's text of a `--set` text `key=value`;
    InputError naming it if it is not key=value."""
    key, sep, raw = item.partition("=")
    if not sep or not key:
        raise InputError(f"--set {item}: expected key=value")
    return dotted(key), raw


def read_value(raw: str, where: str):
    """A `--set` value as a TOML value (1e-7, inf, [0, 0, 1], "text"), else as the text itself
    (hertz); InputError naming `where` if it opens a list, a table or quoted text that TOML
    cannot read ([bogus], [1, 2), which would else be taken for text."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        if raw.lstrip()[:1] in ("[", "{", '"', "'"):
            raise InputError(
                f"{where}: cannot read {raw.strip()} as a TOML value (a list of numbers "
                '[0, 0, 1], of text ["speed", "forces"]; a table {x = 1}; quoted text "a b")'
            ) from None
        return raw


def dotted(key: str) -> str:
    """A field's path as `--set` takes it, `stages.1.steps`, from that or from the path an
    error names, `stages[1].steps`."""
    return re.sub(r"\[(\d+)\]", r".\1", key.strip())


UNSET = "(unset)"
"""How `fields_apart` shows the value of a field one scenario does not set."""


def fields_apart(first: Scenario, second: Scenario) -> list[tuple[str, object, object]]:
    """(dotted path, first's value, second's) of each field where two scenarios differ, as
    `--set` would name it (lists by index), in the order of the paths; UNSET where one sets
    no such field. A field set to None is unset, and a table that is None has no fields: a
    stage's contact = {friction = 0} against none differs in stages.K.contact.friction
    alone."""

    def flat(value, path: str = "") -> dict[str, object]:
        if isinstance(value, dict | list):
            items = value.items() if isinstance(value, dict) else enumerate(value)
            fields = {}
            for key, inner in items:
                fields |= flat(inner, f"{path}.{key}" if path else str(key))
            return fields
        return {} if value is None else {path: value}

    a, b = (flat(s.model_dump(mode="json")) for s in (first, second))
    return [
        (key, a.get(key, UNSET), b.get(key, UNSET))
        for key in sorted(set(a) | set(b))
        if a.get(key, UNSET) != b.get(key, UNSET)
    ]


def set_field(data: dict, key: str, value, label: str = "") -> None:
    """Set the field at the dotted path `key` (`stages.0.steps`: list items by index) of a
    scenario's fields to `value`, making tables on the way; InputError naming `label` + key
    where the path goes through a value or past a list's end. `stages[0].steps`, as errors
    name a field, is taken too (`dotted`)."""
    key = dotted(key)
    node = data
    parts = key.split(".")
    for part in parts[:-1]:
        node = _child(node, part, key, label)
    last = parts[-1]
    if isinstance(node, list):
        node[_index(node, last, key, label)] = value
    else:
        node[last] = value


def _child(node, part: str, key: str, label: str):
    """The table or list `part` of `node` (a new table if it has none)."""
    if isinstance(node, list):
        child = node[_index(node, part, key, label)]
    else:
        child = node.setdefault(part, {})
    if not isinstance(child, dict | list):
        raise InputError(f"{label}{key}: '{part}' holds a value, not a table or a list")
    return child


def _index(node: list, part: str, key: str, label: str) -> int:
    if not part.isdigit() or int(part) >= len(node):
        raise InputError(f"{label}{key}: '{part}' is not an index of a list of {len(node)}")
    return int(part)


def read_particle_files(data: dict, base: Path, origin: str) -> None:
    """Each [[particles_from]] file's path made absolute (a relative one is relative to the
    scenario file, `base`) and its sphere count read from its header, so that the stored
    scenario says both and is checked again without the file."""
    from revdem_cli.io.lammps_data import read_header

    sources = data.get("particles_from")
    for k, source in enumerate(sources if isinstance(sources, list) else []):
        if not isinstance(source, dict) or not isinstance(source.get("lammps_data"), str):
            continue  # the schema names what is wrong
        path = (base / source["lammps_data"]).absolute()
        source["lammps_data"] = str(path)
        try:
            atoms = read_header(path)[0]
        except InputError as exc:
            raise InputError(f"{origin}: particles_from[{k}].lammps_data: {exc}") from None
        source.setdefault("count", atoms)


def check_no_kind(data: dict, origin: str) -> None:
    """A scenario file says no kind; InputError if this one does: a time-step study or a sweep
    file named with the command that runs it, another kind with the kinds known. A sweep
    file is read as TOML only (`sweep.read_sweep_file`): one in YAML is told so, not sent to
    `revdem sweep`, which took it for a scenario."""
    if "kind" not in data:
        return
    from revdem_cli import sweep
    from revdem_cli.timestep import study

    kinds = {
        study.KIND: ("a time-step study", "revdem run"),
        sweep.KIND: ("a sweep file", "revdem sweep"),
    }
    kind = data["kind"]
    if kind == sweep.KIND and not origin.lower().endswith(".toml"):
        toml = Path(origin).with_suffix(".toml").name
        raise InputError(
            f"{origin}: a sweep file is TOML, not {Path(origin).suffix or 'this'}; write it as "
            f'{toml} (kind = "sweep", scenario = "...", set = ["field=v1,v2"])'
        )
    if isinstance(kind, str) and kind in kinds:
        what, command = kinds[kind]
        raise InputError(
            f"{origin}: kind: '{kind}' is {what}, not a scenario; run it with {command}"
        )
    known = ", ".join(f"'{name}'" for name in kinds)
    raise InputError(
        f"{origin}: kind: unknown kind {kind!r:.60} (known: {known}; a scenario has none)"
    )


def scenario_from_text(
    text: str, suffix: str, origin: str, overrides: list[str] = (), host: bool = False
) -> Scenario:
    """A scenario from the text of a file, checked in layers: its schema and how its fields
    fit together, then what a run would carry out without its doing what it says
    (`checks.check_given`, which a stored scenario is not held to); with `host`, whether a
    run of it fits this machine (`revdem run`); then its spheres, generated and checked
    where they start."""
    data = apply_overrides(parse_text(text, suffix, origin), list(overrides), origin)
    return scenario_from_data(data, origin, Path(origin).parent, host)


def scenario_from_data(data: dict, origin: str, base: Path, host: bool = False) -> Scenario:
    """A scenario from its fields as parsed, checked as `scenario_from_text` says; files it
    names are relative to `base`. `origin` names it in error messages."""
    check_no_kind(data, origin)
    read_particle_files(data, base, origin)
    try:
        scenario = Scenario.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"{origin}: {describe_validation_error(exc)}") from None
    try:
        check_given(scenario)
        if host:
            check_host(scenario)
        check_spheres(scenario)
    except FieldError as exc:
        raise InputError(f"{origin}: {exc}") from None
    return scenario


def load_scenario(
    path: str | Path, overrides: list[str] = (), host: bool = False
) -> tuple[Scenario, str]:
    """Read and check a scenario file (`scenario_from_text`); returns the scenario and its
    text (kept in outputs)."""
    path = Path(path)
    text = read_scenario_text(path)
    return scenario_from_text(text, path.suffix.lower(), str(path), overrides, host), text


def read_scenario_text(path: Path) -> str:
    """The text of a scenario file; InputError naming it if it cannot be read."""
    check_regular(path, "scenario file")
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not a text file"
        raise InputError(f"{path}: cannot read scenario file ({reason})") from None
