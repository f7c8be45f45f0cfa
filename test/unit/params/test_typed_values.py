"""The typed value classes: generated from the schemas, up to date, and what derive() makes.

``src/servo_axis/params/values.py`` and ``src/servo_axis/plugins/values.py``
are written by ``scripts/typed_values.py``; a schema changed without running
it fails here. The class of an outside extension is made at run time
(:func:`~servo_axis.params.typed.derive`): for every shipped schema it must
give the fields the generated class has.
"""

from __future__ import annotations

import dataclasses
import runpy
from pathlib import Path

import pytest

from servo_axis.params import schemas, typed
from servo_axis.params import values as node_values
from servo_axis.params.param import Param, check_values
from servo_axis.params.registry import REGISTRIES
from servo_axis.plugins import values as plugin_values

REPO = Path(__file__).resolve().parents[3]
SCRIPT = REPO / "scripts" / "typed_values.py"

NODE_CLASSES = {
    "plant": (node_values.PlantValues, schemas.PLANT),
    "feedback": (node_values.FeedbackValues, schemas.FEEDBACK),
    "feedforward": (node_values.FeedforwardValues, schemas.FEEDFORWARD),
    "learning": (node_values.LearningValues, schemas.LEARNING),
    "identifier": (node_values.IdentifierValues, schemas.IDENTIFIER),
    "recorder": (node_values.RecorderValues, schemas.RECORDER),
}
KIND_BASES = {
    "plant model": node_values.PlantValues,
    "feedforward term": node_values.FeedforwardValues,
    "learning law": node_values.LearningValues,
    "identification method": node_values.IdentifierValues,
}


def test_the_generated_modules_are_up_to_date() -> None:
    rendered = runpy.run_path(str(SCRIPT))["rendered"]()
    assert set(rendered) == {
        REPO / "src/servo_axis/params/values.py",
        REPO / "src/servo_axis/plugins/values.py",
    }
    for path, text in rendered.items():
        assert path.read_text() == text, f"{path} is stale: run scripts/typed_values.py"


def test_derive_gives_each_generated_class_its_fields() -> None:
    shared = typed.derive("S", (typed.Values,), schemas.SHARED)
    assert typed.tree_of(shared) == typed.tree_of(node_values.SharedValues)
    for cls, schema in NODE_CLASSES.values():
        made = typed.derive("N", (node_values.SharedValues,), schema)
        assert typed.tree_of(made) == typed.tree_of(cls), cls.__name__
    checked = 0
    for kind, registry in REGISTRIES.items():
        for name in (n for n in registry if registry.shipped(n)):
            entry = registry[name]
            made = typed.derive("E", (KIND_BASES[kind],), entry.schema)
            expected = entry.values if entry.values is not None else KIND_BASES[kind]
            assert typed.tree_of(made) == typed.tree_of(expected), name
            checked += 1
    assert checked >= 13


def test_every_shipped_extension_with_keys_names_its_generated_class() -> None:
    for registry in REGISTRIES.values():
        for name in (n for n in registry if registry.shipped(n)):
            entry = registry[name]
            if entry.schema:
                assert entry.values is not None, name
                assert entry.values.__module__ == plugin_values.__name__, name
                assert set(typed.keys_of(entry.values)) >= set(entry.schema), name


def test_each_field_carries_the_unit_and_range_of_its_key() -> None:
    by_attr = {f.name: f for f in dataclasses.fields(node_values.FeedbackDobKeys)}
    assert by_attr["cutoff_hz"].metadata == {"unit": "Hz", "range": "> 0"}
    assert by_attr["sensor"].metadata["range"] == "one of 'encoder', 'scale'"
    text = (REPO / "src/servo_axis/params/values.py").read_text()
    meaning = schemas.FEEDBACK["dob.cutoff_hz"].meaning
    assert f"``dob.cutoff_hz`` (Hz, > 0): {meaning[:40]}" in text


def test_values_read_as_attributes_and_as_a_mapping_of_dotted_keys() -> None:
    schema = {**schemas.SHARED, **schemas.FEEDBACK}
    flat = check_values(schema, {"dob.cutoff_hz": 60, "limits.travel_m": 0.5}, "feedback")
    values = typed.from_flat(node_values.FeedbackValues, flat)
    assert values.dob.cutoff_hz == 60.0 and values["dob.cutoff_hz"] == 60.0
    assert values.limits.travel_m == 0.5 and values.limits["travel_m"] == 0.5
    assert (
        values.nominal.torque_constant_Nm_per_A
        == schema["nominal.torque_constant_Nm_per_A"].default
    )
    # A list is a tuple as an attribute (frozen), a list through the mapping (as before).
    assert values.external_roles == ("",) and values["external_roles"] == [""]
    assert set(values) == set(schema) and len(values) == len(schema)
    assert values == flat and dict(values) == flat and values.as_dict() == flat
    with pytest.raises(dataclasses.FrozenInstanceError):
        values.bandwidth_hz = 1.0  # type: ignore[misc]
    changed = values.with_keys({"dob.enabled": True})
    assert changed.dob.enabled and not values.dob.enabled and changed.dob.cutoff_hz == 60.0
    with pytest.raises(KeyError):
        values.with_keys({"dob.no_such_key": 1})
    with pytest.raises(KeyError):
        values["dob"]  # a group, not a key


def test_derive_extends_a_group_of_the_base_and_merges_several_bases() -> None:
    # An outside method's keys in the identifier node's groups, and a group of its own.
    extra: dict[str, Param] = {
        "initial.mass_kg": Param(1.0, unit="kg", above=0.0, meaning="m"),
        "observer.gains": Param([1.0, 2.0], meaning="L"),
        "observer.nested.class": Param("a", meaning="a keyword as a key part"),
    }
    made = typed.derive("OutsideMethodValues", (node_values.IdentifierValues,), extra)
    schema = {**schemas.SHARED, **schemas.IDENTIFIER, **extra}
    values = typed.from_flat(made, check_values(schema, {"observer.gains": [3, 4]}, "identifier"))
    assert values.initial.unbalance_Nm == 0.1 and values.initial.mass_kg == 1.0  # type: ignore[attr-defined]
    assert isinstance(values.initial, node_values.IdentifierInitialKeys)
    assert values.observer.gains == (3.0, 4.0)  # type: ignore[attr-defined]
    assert values["observer.nested.class"] == "a"
    assert values.observer.nested.class_ == "a"  # type: ignore[attr-defined]
    assert set(values) == set(schema)
    # Terms' classes merged into one, each term's keys a group of its own.
    both = typed.derive("Both", (plugin_values.MncValues, plugin_values.GmsValues), {})
    ff = {**schemas.SHARED, **schemas.FEEDFORWARD}
    for cls in (plugin_values.MncValues, plugin_values.GmsValues):
        ff.update({k: p for k, p in _schema_of(cls).items()})
    merged = typed.from_flat(both, check_values(ff, {"mnc.enabled": True}, "feedforward"))
    assert isinstance(merged, plugin_values.MncValues) and isinstance(
        merged, plugin_values.GmsValues
    )
    assert merged.mnc.enabled and merged.gms.file == ""


def test_a_key_no_attribute_can_name_or_that_clashes_is_refused() -> None:
    for bad in ({"items": Param(1.0)}, {"a.keys": Param(1.0)}, {"a.1x": Param(1.0)}):
        with pytest.raises(ValueError, match="cannot name an attribute"):
            typed.derive("Bad", (node_values.SharedValues,), bad)
    with pytest.raises(ValueError, match="given twice"):
        typed.derive("Bad", (node_values.SharedValues,), {"nominal": Param(1.0)})
    with pytest.raises(ValueError, match="is a group of keys"):
        typed.nest({"a.b": Param(1.0), "a": Param(2.0)})


def _schema_of(cls: type[typed.Group]) -> dict[str, Param]:
    """The schema of a generated term class (its keys beyond its node's)."""
    registry = REGISTRIES["feedforward term"]
    return dict(registry[cls.__name__.removesuffix("Values").lower()].schema)


def test_a_node_gets_the_class_of_its_model_law_method_and_terms() -> None:
    from servo_axis.params.factories import checked_values

    assert type(checked_values("plant", {})) is plugin_values.BallScrewValues
    tilt = checked_values("plant", {"model": "tilting_table", "unbalance_Nm": 0.2})
    assert type(tilt) is plugin_values.TiltingTableValues and tilt.unbalance_Nm == 0.2
    assert type(checked_values("learning", {"law": "rptc"})) is node_values.LearningValues
    assert type(checked_values("identifier", {})) is plugin_values.DlpidValues
    assert type(checked_values("identifier", {"method": "marc"})) is node_values.IdentifierValues
    assert type(checked_values("recorder", {})) is node_values.RecorderValues
    ff = checked_values("feedforward", {"mnc.enabled": True})
    for cls in (
        plugin_values.MncValues,
        plugin_values.GmsValues,
        plugin_values.SigmoidValues,
        plugin_values.FrictionTableValues,
        plugin_values.ExcitationValues,
    ):
        assert isinstance(ff, cls)
    assert ff.mnc.enabled and not ff.gms.enabled


def test_an_extension_without_a_class_gets_one_made_and_a_stale_class_is_refused() -> None:
    from servo_axis.params.factories import PLANT_MODELS, checked_values
    from servo_axis.params.registry import PlantModelEntry

    schema = {
        "torque_constant_Nm_per_A": Param(1.0, unit="N m/A", above=0.0, meaning="K_T"),
        "spring.stiffness_N_per_m": Param(1e6, unit="N/m", above=0.0, meaning="k"),
    }
    PLANT_MODELS.register("made_here", PlantModelEntry(schema=schema, build=lambda v, r: None))
    try:
        values = checked_values("plant", {"model": "made_here", "spring.stiffness_N_per_m": 2e6})
        assert isinstance(values, node_values.PlantValues)
        assert values.spring.stiffness_N_per_m == 2e6  # type: ignore[attr-defined]
        assert type(values).__name__ == "MadeHereValues"
        stale = PlantModelEntry(
            schema=schema, build=lambda v, r: None, values=plugin_values.TiltingTableValues
        )
        with pytest.raises(ValueError, match="and the schema differ in key"):
            PLANT_MODELS.register("stale_class", stale)
    finally:
        PLANT_MODELS.unregister("made_here")
