"""The parameter schemas: meanings, defaults, the scenario files and the range checks."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml

from servo_axis.core.errors import ParameterFileError
from servo_axis.params.param import Param
from servo_axis.params.registry import FEEDFORWARD_TERMS, feedforward_terms, parameter_sections
from servo_axis.params.scenario import flatten
from servo_axis.params.schemas import (
    FEEDBACK,
    FEEDFORWARD,
    IDENTIFIER,
    LEARNING,
    PLANT,
    RECORDER,
    REFERENCE,
    SENSOR,
    SHARED,
)
from servo_axis.plugins.ball_screw import BALL_SCREW
from servo_axis.plugins.dlpid import DLPID_FRICTION
from servo_axis.plugins.elastic_ball_screw import ELASTIC_BALL_SCREW
from servo_axis.plugins.ilc import ILC, PILC
from servo_axis.plugins.tilting_table import TILTING_TABLE

# The suite's own: a plugin installed beside it has its own schemas.
SECTIONS = parameter_sections(shipped_only=True)
SHIPPED_TERMS = [(n, e) for n, e in feedforward_terms() if FEEDFORWARD_TERMS.shipped(n)]
TERMS = {k: p for _, entry in SHIPPED_TERMS for k, p in entry.schema.items()}

REPO = Path(__file__).resolve().parents[3]
CONFIGS = sorted((REPO / "config").glob("*.yaml"))

#: The schema of each section of a scenario file (by its last path component).
NODE_SCHEMAS: dict[str, Mapping[str, Param]] = {
    "**": SHARED,
    "plant": {**PLANT, **BALL_SCREW, **TILTING_TABLE, **ELASTIC_BALL_SCREW},
    "feedback": FEEDBACK,
    "feedforward": {**FEEDFORWARD, **TERMS},
    "learning": {**LEARNING, **ILC, **PILC},
    "identifier": {**IDENTIFIER, **DLPID_FRICTION},
    "recorder": RECORDER,
}

ALL = [
    pytest.param(title, name, param, id=f"{title}:{name}")
    for title, schema in SECTIONS.items()
    for name, param in schema.items()
]


def is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def is_numeric(param: Param) -> bool:
    d = param.default
    return is_number(d) or (isinstance(d, list) and bool(d) and is_number(d[0]))


def is_float(param: Param) -> bool:
    d = param.default
    return isinstance(d, float) or (isinstance(d, list) and bool(d) and isinstance(d[0], float))


def names(key: str) -> str:
    """Pattern of an error message naming the full dotted ``key``."""
    return re.escape(f"parameter '{key}'")


def config_values() -> Iterator[Any]:
    for path in CONFIGS:
        for section, body in yaml.safe_load(path.read_text()).items():
            node = section.rsplit("/", 1)[-1]
            for key, value in flatten(body["ros__parameters"]).items():
                yield pytest.param(node, key, value, id=f"{path.stem}:{section}:{key}")


def just_outside(param: Param) -> list[tuple[str, object]]:
    """(bound, value) pairs just outside each bound of a numeric parameter."""
    integer = not is_float(param)
    cases: list[tuple[str, object]] = []
    if param.minimum is not None:
        b = param.minimum
        cases.append((f">= {b}", int(b) - 1 if integer else math.nextafter(b, -math.inf)))
    if param.above is not None:
        cases.append((f"> {param.above}", int(param.above) if integer else float(param.above)))
    if param.maximum is not None:
        b = param.maximum
        cases.append((f"<= {b}", int(b) + 1 if integer else math.nextafter(b, math.inf)))
    if param.below is not None:
        cases.append((f"< {param.below}", int(param.below) if integer else float(param.below)))
    return cases


BOUND_CASES = [
    pytest.param(name, param, value, id=f"{title}:{name}:{bound}")
    for title, schema in SECTIONS.items()
    for name, param in schema.items()
    if is_numeric(param)
    for bound, value in just_outside(param)
]

FLOAT_PARAMS = [
    pytest.param(name, param, id=f"{title}:{name}")
    for title, schema in SECTIONS.items()
    for name, param in schema.items()
    if is_float(param)
]


def test_the_configs_are_found() -> None:
    assert len(CONFIGS) >= 10


def test_sections_cover_every_schema() -> None:
    expected = [
        SHARED,
        PLANT,
        BALL_SCREW,
        ELASTIC_BALL_SCREW,
        TILTING_TABLE,
        FEEDBACK,
        FEEDFORWARD,
        *(entry.schema for _, entry in SHIPPED_TERMS),
        LEARNING,
        {**ILC, **PILC},
        ILC,
        IDENTIFIER,
        DLPID_FRICTION,
        RECORDER,
    ]
    assert [dict(s) for s in SECTIONS.values()] == [dict(s) for s in expected]
    # After the learning node's own keys (where depends on the installed terms).
    after = list(SECTIONS).index("learning") + 1
    assert list(SECTIONS)[after : after + 2] == [
        "learning (laws pilc_bf, pilc_bfft)",
        "learning (law silc)",
    ]
    assert not set(FEEDFORWARD) & set(TERMS)
    assert not set(IDENTIFIER) & set(DLPID_FRICTION)
    assert not set(PLANT) & set(BALL_SCREW) and not set(PLANT) & set(TILTING_TABLE)
    assert not set(PLANT) & set(ELASTIC_BALL_SCREW)
    assert not set(LEARNING) & (set(ILC) | set(PILC)) and not set(ILC) & set(PILC)
    assert not set(SHARED) & {k for s in NODE_SCHEMAS.values() if s is not SHARED for k in s}


def test_sensor_and_reference_are_shared() -> None:
    assert FEEDBACK["sensor"] is SENSOR and LEARNING["sensor"] is SENSOR
    for schema in (FEEDFORWARD, LEARNING):
        assert list(schema)[: len(REFERENCE)] == list(REFERENCE)
        assert all(schema[k] is p for k, p in REFERENCE.items())
    assert list(LEARNING)[len(REFERENCE)] == "law"
    assert next(iter(PLANT)) == "model"


@pytest.mark.parametrize(("title", "name", "param"), ALL)
def test_every_parameter_has_a_meaning(title: str, name: str, param: Param) -> None:
    assert isinstance(param, Param)
    assert param.meaning.strip(), f"{title}: '{name}' has no meaning"
    assert "\n" not in param.meaning


@pytest.mark.parametrize(("title", "name", "param"), ALL)
def test_every_default_passes_its_own_check(title: str, name: str, param: Param) -> None:
    checked = param.check(name, param.default)
    assert checked == param.default and type(checked) is type(param.default)


def test_defaults_that_must_not_drift() -> None:
    assert BALL_SCREW["encoder.resolution"].default == 2.0 * math.pi / 2**20
    for key in ("modes.frequency_hz", "modes.zeta", "modes.a"):
        assert BALL_SCREW[key].default == [0.0]
    assert SHARED["control_period_s"].default == 1e-3
    assert SENSOR.default == "encoder"


@pytest.mark.parametrize(("node", "key", "value"), list(config_values()))
def test_every_config_value_passes_its_schema(node: str, key: str, value: object) -> None:
    schema = NODE_SCHEMAS[node]
    assert key in schema, f"unknown key '{key}' in section '{node}'"
    schema[key].check(key, value)


@pytest.mark.parametrize(("name", "param", "value"), BOUND_CASES)
def test_a_value_just_outside_a_bound_is_rejected(name: str, param: Param, value: object) -> None:
    given: object = [value] if isinstance(param.default, list) else value
    with pytest.raises(ParameterFileError, match=names(name)):
        param.check(name, given)


@pytest.mark.parametrize(("name", "param"), FLOAT_PARAMS)
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nan_and_inf_are_rejected(name: str, param: Param, bad: float) -> None:
    given: object = [bad] if isinstance(param.default, list) else bad
    with pytest.raises(ParameterFileError, match=names(name)):
        param.check(name, given)


def test_choices_are_enforced() -> None:
    for title, schema in SECTIONS.items():
        for name, param in schema.items():
            if param.choices is None:
                continue
            assert param.default in param.choices, f"{title}: {name}"
            with pytest.raises(ParameterFileError, match=names(name)):
                param.check(name, "no-such-choice")
