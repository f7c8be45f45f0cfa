"""Errors raised by servo_axis.

All are ``ValueError`` subclasses so that callers that only know the standard
library still catch them; each message names the argument and what was
expected.
"""

from __future__ import annotations

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
