"""A feedforward term whose module imports a dependency that is not installed."""

from __future__ import annotations

import servo_axis_no_such_dependency  # type: ignore[import-not-found]  # noqa: F401

TERM = None
