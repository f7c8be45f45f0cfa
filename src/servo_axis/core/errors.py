"""Errors raised by servo_axis.

All are ``ValueError`` subclasses so that callers that only know the standard
library still catch them; each message names the argument and what was
expected.
"""

from __future__ import annotations

from collections.abc import Iterable
from difflib import get_close_matches
from math import isfinite as _isfinite  # at the top: the checks run per online estimate


class ServoAxisError(ValueError):
    """Base class of every error servo_axis raises on bad input."""


class ConfigError(ServoAxisError):
    """A configuration value (dataclass field, ROS parameter) is invalid."""


class ParameterFileError(ConfigError):
    """A parameter file has an unknown key, a wrong type or an out-of-range value."""


class BrokenPluginError(ParameterFileError):
    """A scenario selects an installed extension (plugin) that cannot be loaded."""


class SignalError(ServoAxisError):
    """A signal (array, message field) has the wrong length, NaN/inf or a bad stamp."""


class TableError(ServoAxisError):
    """A data table (friction table, learning memory) is malformed or mismatched."""


def require_finite(name: str, value: float) -> float:
    """Return ``value`` as float, or raise :class:`ConfigError` naming ``name``."""
    v = float(value)
    if not _isfinite(v):
        raise ConfigError(f"{name}: expected a finite number, got {value!r}")
    return v


def require_positive(name: str, value: float) -> float:
    """Return ``value`` as float if finite and > 0, else raise :class:`ConfigError`."""
    v = require_finite(name, value)
    if v <= 0.0:
        raise ConfigError(f"{name}: expected a value > 0, got {value!r}")
    return v


def require_nonnegative(name: str, value: float) -> float:
    """Return ``value`` as float if finite and >= 0, else raise :class:`ConfigError`."""
    v = require_finite(name, value)
    if v < 0.0:
        raise ConfigError(f"{name}: expected a value >= 0, got {value!r}")
    return v


def closest(name: object, choices: Iterable[str], n: int = 1) -> list[str]:
    """The ``n`` choices most like ``name`` (a typo's candidates), best first; [] if none is close.

    The ratio of :func:`difflib.get_close_matches` (0.6), compared without
    case, so that ``Ptc_Nominal`` finds ``ptc_nominal``.
    """
    if not isinstance(name, str):
        return []
    by_lower = {c.lower(): c for c in choices}
    return [by_lower[m] for m in get_close_matches(name.lower(), list(by_lower), n=n)]


def did_you_mean(name: object, choices: Iterable[str], n: int = 1) -> str:
    """``"did you mean 'x'?"`` (or ``'x' or 'y'``) for the closest choices; ``""`` if none is close."""
    found = closest(name, choices, n)
    if not found:
        return ""
    return "did you mean " + " or ".join(f"'{c}'" for c in found) + "?"
