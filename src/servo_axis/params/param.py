"""Parameter schemas: each key's default, unit, range and meaning, and strict checking.

rclpy silently ignores undeclared keys of a parameter file (ROS_NOTES); a
typo must stop the node instead. A schema maps each (dotted) parameter name
to a :class:`Param`; the type of its default is the type of the parameter.
:func:`check_values` rejects unknown keys, wrong types, NaN/inf and values
outside the stated range with a :class:`ParameterFileError` naming the full
key; the frozen dataclasses of :mod:`servo_axis.core` that the values feed
then check what depends on several keys at once.

Nothing here imports rclpy: the nodes (:mod:`servo_axis.nodes.base`), the
headless simulation and the reports check a scenario the same way.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

from servo_axis.core.errors import ConfigError, ParameterFileError, did_you_mean

T = TypeVar("T")

#: Keys rclpy itself declares on every node.
BUILTIN = frozenset({"use_sim_time", "start_type_description_service"})


@dataclass(frozen=True)
class Param:
    """One parameter: default, SI unit, allowed range and a one-line meaning.

    Parameters
    ----------
    default : bool, int, float, str or list
        The default; its type is the parameter's type (an int default makes
        an integer parameter, a float one a number; lists are lists of
        numbers or strings, their element type taken from the first element).
    unit : str
        SI unit (``"m"``, ``"N m/A"``, ``"rad"``, ``"s"``), ``""`` for none.
    meaning : str
        What the value is, in one line.
    minimum, maximum : float or None
        Inclusive bounds of a number (of every element of a list of numbers).
    above, below : float or None
        Exclusive bounds (``above=0.0`` is "> 0").
    choices : tuple of str or None
        The allowed strings.
    """

    default: object
    unit: str = ""
    meaning: str = ""
    minimum: float | None = None
    maximum: float | None = None
    above: float | None = None
    below: float | None = None
    choices: tuple[str, ...] | None = None

    def range_text(self) -> str:
        """The allowed values as text (for the parameter reference)."""
        if self.choices is not None:
            return " \\| ".join(repr(c) for c in self.choices)
        if isinstance(self.default, bool) or isinstance(self.default, str):
            return ""
        low = f"> {self.above:g}" if self.above is not None else None
        low = f">= {self.minimum:g}" if self.minimum is not None else low
        high = f"< {self.below:g}" if self.below is not None else None
        high = f"<= {self.maximum:g}" if self.maximum is not None else high
        return ", ".join(p for p in (low, high) if p) or "finite"

    def check(self, name: str, value: object) -> object:
        """``value`` coerced to the parameter's type and checked against its range.

        Raises
        ------
        ParameterFileError
            Naming ``name``: wrong type, NaN/inf, out of range, not a choice.
        """
        value = coerce(name, self.default, value)
        if self.choices is not None and value not in self.choices:
            raise ParameterFileError(
                f"parameter '{name}': expected one of {self.choices}, got {value!r}"
            )
        numbers = value if isinstance(value, list) else [value]
        for number in numbers:
            if isinstance(number, bool) or not isinstance(number, int | float):
                continue
            self._check_number(name, float(number), value)
        return value

    def _check_number(self, name: str, x: float, value: object) -> None:
        if not math.isfinite(x):
            raise ParameterFileError(f"parameter '{name}': expected a finite number, got {value!r}")
        bounds = (
            (self.minimum, ">=", lambda b: x >= b),
            (self.above, ">", lambda b: x > b),
            (self.maximum, "<=", lambda b: x <= b),
            (self.below, "<", lambda b: x < b),
        )
        ok: Callable[[float], bool]
        for bound, text, ok in bounds:
            if bound is not None and not ok(bound):
                raise ParameterFileError(
                    f"parameter '{name}': expected a value {text} {bound:g}, got {value!r}"
                )


#: A schema: dotted parameter name -> :class:`Param`.
Schema = Mapping[str, Param]


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
            if (
                isinstance(elem, int)
                and not isinstance(elem, bool)
                and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
            ):
                return [int(v) for v in value]
    raise ParameterFileError(f"parameter '{name}': expected {type_name(default)}, got {value!r}")


def type_name(default: object) -> str:
    """``a number``, ``a list of strings``, ... for the type of ``default``."""
    if isinstance(default, list):
        elem = default[0] if default else 0.0
        if isinstance(elem, str):
            return "a list of strings"
        if isinstance(elem, int) and not isinstance(elem, bool):
            return "a list of integers"
        return "a list of numbers"
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}[type(default)]


def defaults(schema: Schema) -> dict[str, Any]:
    """Every key of ``schema`` with its default value (lists copied)."""
    return {
        name: list(p.default) if isinstance(p.default, list) else p.default
        for name, p in schema.items()
    }


def check_values(schema: Schema, given: Mapping[str, object], node: str = "node") -> dict[str, Any]:
    """The checked values of ``schema``: ``given`` where set, the defaults elsewhere.

    Raises
    ------
    ParameterFileError
        For a key of ``given`` that is not in the schema (naming the node),
        or a value of the wrong type, not finite or out of its range.
    """
    unknown = sorted(set(given) - set(schema) - BUILTIN)
    if unknown:
        raise ParameterFileError(
            f"unknown parameter '{unknown[0]}' for node '{node}'"
            + unknown_key_hint(unknown[0], schema)
            + (f" (and {len(unknown) - 1} more: {unknown[1:]})" if len(unknown) > 1 else "")
        )
    values = defaults(schema)
    for name, param in schema.items():
        if name in given:
            values[name] = param.check(name, given[name])
    return values


def unknown_key_hint(name: str, keys: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for a key not among ``keys``; for a group's name, its keys."""
    keys = list(keys)
    group = [k for k in keys if k.startswith(f"{name}.")]
    if group:
        return f" ('{name}' is a group of keys: {', '.join(group)})"
    hint = did_you_mean(name, keys)
    return f" ({hint})" if hint else ""


def build(
    prefix: str,
    factory: Callable[..., T],
    *,
    keys: Mapping[str, str] | None = None,
    **kwargs: Any,
) -> T:
    """Call a validating constructor; re-raise its error naming the full parameter.

    The constructor's :class:`ConfigError` names its own argument
    (``period_s: ...``); the parameter is ``prefix`` + that name, or
    ``keys[name]`` when the argument comes from a key of another name
    (``{"period_s": "control_period_s"}``).
    """
    try:
        return factory(**kwargs)
    except ParameterFileError:
        raise  # already names its parameter
    except ConfigError as err:
        field, _, detail = str(err).partition(": ")
        name = (keys or {}).get(field, prefix + field)
        raise ParameterFileError(f"parameter '{name}': {detail}") from err


def dataclass_defaults(cls: type) -> dict[str, Any]:
    """Field defaults of a core parameter dataclass (an axis preset is stated there once)."""
    return {
        f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING
    }


def section(values: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    """Sub-mapping of ``values`` under ``prefix.`` with the prefix removed."""
    p = prefix + "."
    return {k[len(p) :]: v for k, v in values.items() if k.startswith(p)}
