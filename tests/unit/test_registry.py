"""Records found by name (`registry`): a half-added law or wall shape never loads."""

from types import ModuleType

import pytest

from revdem_cli import laws, registry, wall_shapes

NAMES = ("NAME", "SUMMARY", "FIELDS", "REQUIRED")


def record(module_name: str, **attributes) -> ModuleType:
    module = ModuleType(module_name)
    defaults = {"NAME": "toy", "SUMMARY": "F = k d", "FIELDS": {"k_toy": None}, "REQUIRED": ()}
    for name, value in (defaults | attributes).items():
        setattr(module, name, value)
    return module


def test_a_record_is_entered_by_its_name():
    found = {}
    toy = record("laws.toy", REQUIRED=("k_toy",))
    registry.enter(found, toy, "a normal law", NAMES)
    assert found == {"toy": toy}


def test_what_a_record_lacks_is_named():
    toy = record("laws.toy")
    del toy.SUMMARY
    with pytest.raises(ImportError, match=r"^laws\.toy: a normal law must define SUMMARY$"):
        registry.enter({}, toy, "a normal law", NAMES)


def test_a_required_field_must_be_one_of_its_fields():
    toy = record("laws.toy", REQUIRED=("k_tyo",))  # misspelled: never asked for, read as None
    with pytest.raises(ImportError, match=r"REQUIRED names k_tyo, which its FIELDS lack"):
        registry.enter({}, toy, "a normal law", NAMES)


def test_a_name_taken_by_another_record_is_refused():
    found = {}
    registry.enter(found, record("laws.linear"), "a normal law", NAMES)
    with pytest.raises(ImportError, match=r"laws\.toy: a normal law named 'toy', as laws\.linear"):
        registry.enter(found, record("laws.toy"), "a normal law", NAMES)
    assert found["toy"].__name__ == "laws.linear"


def test_a_wall_shape_field_its_overlap_is_never_given_is_refused():
    wall_shapes.check_carried(wall_shapes.SHAPES["cylinder"])  # its radius is carried
    cone = record("wall_shapes.cone", FIELDS={"radius": None, "half_angle": None})
    with pytest.raises(ImportError, match=r"the field half_angle never reaches the compiled"):
        wall_shapes.check_carried(cone)


def test_the_shipped_records_are_found():
    assert list(laws.LAWS["normal"]) == ["hertz", "linear"]
    assert list(laws.LAWS["tangential"]) == ["linear", "mindlin"]
    assert list(wall_shapes.SHAPES) == ["cylinder", "plane"]
