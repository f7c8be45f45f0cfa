"""ROS parameters of the nodes: one schema per node, strict checking.

rclpy silently ignores undeclared keys of a parameter file (ROS_NOTES); a
typo must stop the node instead. Each node states its schema as a mapping
from the (dotted) parameter name to its default; the type of the default is
the type of the parameter. :func:`read_parameters` declares the schema,
rejects unknown keys and wrong types with a :class:`ParameterFileError`
naming the key, and returns plain values. Range checks are done by the
frozen dataclasses of :mod:`servo_axis.core` that the values feed.

Keys shared by every node (the ``/**`` block of a scenario file) are in
:data:`SHARED`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from rclpy.node import Node

from servo_axis.core.errors import ConfigError, ParameterFileError

#: Parameters every node accepts (a scenario's ``/**`` block).
SHARED: dict[str, object] = {
    "mode": "lockstep",
    "control_period_s": 1e-3,
    "duration_s": 2.0,
    "axis": "x",
    "lead_m_per_rad": 1.91e-3,
    "nominal.torque_constant_Nm_per_A": 0.715,
    "nominal.inertia_kgm2": 0.01,
    "nominal.damping_Nms_per_rad": 0.1,
    "scenario.name": "",
    "scenario.description": "",
}

#: Keys rclpy itself declares.
_BUILTIN = {"use_sim_time", "start_type_description_service"}

MODES = ("lockstep", "realtime")

T = TypeVar("T")


def coerce(name: str, default: object, value: object) -> object:
    """Check ``value`` against the type of ``default``; ints are accepted for floats.

    Raises
    ------
    ParameterFileError
        Naming ``name`` when the type is wrong.
    """
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
    elif isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif isinstance(default, float):
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
    elif isinstance(default, str):
        if isinstance(value, str):
            return value
    elif isinstance(default, list):
        if value is None:
            return []
        if isinstance(value, list | tuple):
            elem = default[0] if default else 0.0
            if isinstance(elem, str) and all(isinstance(v, str) for v in value):
                return [str(v) for v in value]
            if isinstance(elem, float) and all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in value
            ):
                return [float(v) for v in value]
    raise ParameterFileError(f"parameter '{name}': expected {_type_name(default)}, got {value!r}")


def _type_name(default: object) -> str:
    if isinstance(default, list):
        elem = default[0] if default else 0.0
        return "a list of strings" if isinstance(elem, str) else "a list of numbers"
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}[type(default)]


def read_parameters(node: Node, schema: Mapping[str, object]) -> dict[str, Any]:
    """Declare ``schema`` and :data:`SHARED` on ``node`` and return their values.

    Raises
    ------
    ParameterFileError
        For a key of the node's overrides (parameter file, ``-p``) that is not
        in the schema, or a value of the wrong type.
    """
    full = {**SHARED, **schema}
    # rclpy keeps the parameter-file values for this node here before any
    # declaration; it has no public accessor.
    overrides: dict[str, Any] = dict(node._parameter_overrides)
    unknown = sorted(set(overrides) - set(full) - _BUILTIN)
    if unknown:
        raise ParameterFileError(
            f"unknown parameter '{unknown[0]}' for node '{node.get_name()}'"
            + (f" (and {len(unknown) - 1} more: {unknown[1:]})" if len(unknown) > 1 else "")
        )
    values: dict[str, Any] = {}
    for name, default in full.items():
        if name in overrides:
            raw = overrides[name].value
            values[name] = coerce(name, default, raw.tolist() if hasattr(raw, "tolist") else raw)
        else:
            values[name] = list(default) if isinstance(default, list) else default
    check_mode(values)
    for name, value in values.items():
        if isinstance(value, list) and not value:
            continue  # rclpy cannot declare an untyped empty array; nothing to show
        node.declare_parameter(name, value)
    return values


def check_mode(values: Mapping[str, Any]) -> None:
    """Reject an unknown time ``mode``."""
    if values["mode"] not in MODES:
        raise ParameterFileError(
            f"parameter 'mode': expected one of {MODES}, got {values['mode']!r}"
        )


def values_from_mapping(
    schema: Mapping[str, object], mapping: Mapping[str, object], node: str = "node"
) -> dict[str, Any]:
    """Same checks as :func:`read_parameters` on a plain (dotted) mapping, without ROS."""
    full = {**SHARED, **schema}
    unknown = sorted(set(mapping) - set(full) - _BUILTIN)
    if unknown:
        raise ParameterFileError(f"unknown parameter '{unknown[0]}' for node '{node}'")
    values = {
        name: coerce(name, default, mapping[name])
        if name in mapping
        else (list(default) if isinstance(default, list) else default)
        for name, default in full.items()
    }
    check_mode(values)
    return values


def build(prefix: str, factory: Callable[..., T], **kwargs: Any) -> T:
    """Call a validating constructor; re-raise its error naming the parameter."""
    try:
        return factory(**kwargs)
    except ConfigError as err:
        field, _, detail = str(err).partition(": ")
        raise ParameterFileError(f"parameter '{prefix}{field}': {detail}") from err


def section(values: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    """Sub-mapping of ``values`` under ``prefix.`` with the prefix removed."""
    p = prefix + "."
    return {k[len(p) :]: v for k, v in values.items() if k.startswith(p)}
