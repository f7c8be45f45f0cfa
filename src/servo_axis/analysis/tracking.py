"""The tracking error of a run: its statistics as in ``summary.json`` and its unit.

:class:`TrackingError` types what
:func:`~servo_axis.analysis.metrics.error_statistics` computes: the RMS and
largest magnitude of ``R (r - y)`` (m; ``r - y`` in rad for a rotary table,
:func:`error_unit`) over every sample and over the reference instants, per
complete cycle of a periodic reference and from the second cycle on.

The attributes are named ``rms_m``, ``max_m`` whatever the unit; in
``summary.json`` a rotary run's are ``rms_rad``, ``max_rad``
(:func:`unit_keys`), so that every key names the unit of its value.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from servo_axis.analysis.serial import Serial
from servo_axis.params.factories import plant_model
from servo_axis.params.resolve import node_values
from servo_axis.params.values import PlantValues


@dataclass(frozen=True)
class ErrorStats(Serial):
    """RMS and largest magnitude of an error, m (NaN over no samples)."""

    rms_m: float
    max_m: float


@dataclass(frozen=True)
class SampleStats(Serial):
    """Error statistics over every sample and over the reference instants."""

    all_samples: ErrorStats
    reference_instants: ErrorStats


@dataclass(frozen=True)
class CycleStats(Serial):
    """Tracking error of one complete cycle of the reference.

    Attributes
    ----------
    cycle : int
        Cycle number, from 1.
    rms_m, max_m : float
        Over every sample of the cycle, m.
    reference_instants : ErrorStats
        Over the reference instants of the cycle.
    """

    cycle: int
    rms_m: float
    max_m: float
    reference_instants: ErrorStats


@dataclass(frozen=True)
class TrackingError(Serial):
    """Statistics of the tracking error ``R (r - y)`` of a run.

    Attributes
    ----------
    all_samples, reference_instants : ErrorStats
        Whole run, every sample and the reference instants.
    cycles : tuple of CycleStats
        Per complete cycle of a periodic reference (else empty).
    after_first_cycle : SampleStats or None
        From cycle 2 on; None when the reference is not periodic.
    """

    all_samples: ErrorStats
    reference_instants: ErrorStats
    cycles: tuple[CycleStats, ...] = ()
    after_first_cycle: SampleStats | None = field(default=None, metadata={"omit_none": True})


def axis_values(scenario: dict[str, Any]) -> PlantValues:
    """Checked shared values of an axis (period, lead, mode, names), as its plant has them."""
    values: PlantValues = node_values(scenario, "plant")
    return values


def error_unit(plant_values: PlantValues) -> str:
    """``rad`` for a plant model whose table turns (its registry entry's ``rotary``), else ``m``.

    A rotary table's position is its angle, so the tracking error is
    ``r - y`` in rad (no lead); every other model's table moves along a
    line, ``x = R theta``: the error ``R (r - y)`` is in m.
    """
    return "rad" if plant_model(plant_values.model, "plant.model").rotary else "m"


def position_scale(plant_values: PlantValues) -> float:
    """Table position per rad of controlled output: ``R`` (m/rad), 1 for a rotary table."""
    return 1.0 if error_unit(plant_values) == "rad" else float(plant_values.lead_m_per_rad)


def unit_keys(block: Any, unit: str, *, reading: bool = False) -> Any:
    """A ``tracking_error`` mapping with its ``_m`` keys named for ``unit``.

    Writing (``reading`` false): for ``unit`` ``rad`` every key ending in
    ``_m`` (``rms_m``, ``max_m``) of the block and its nested mappings and
    lists ends in ``_rad``; reading: the inverse, so that the dataclasses
    read either (a summary written before the keys were named for rad has
    ``_m`` keys and ``error_unit: rad``). ``m`` leaves the block as it is.
    """
    if unit == "m":
        return block
    old, new = (f"_{unit}", "_m") if reading else ("_m", f"_{unit}")
    if isinstance(block, dict):
        return {
            (k[: -len(old)] + new if k.endswith(old) else k): unit_keys(v, unit, reading=reading)
            for k, v in block.items()
        }
    if isinstance(block, list):
        return [unit_keys(v, unit, reading=reading) for v in block]
    return block
