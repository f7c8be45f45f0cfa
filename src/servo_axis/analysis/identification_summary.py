"""The online parameter identification of a run (paper 003, topic ``identifier/estimates``).

:func:`identification` summarises the validated estimates of a run's bag as
an :class:`OnlineIdentification` (``summary.json``'s ``identification`` block):
the final ``J, D, U, C`` against the plant's true values, their spread over
the last period and how often each parameter was updated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servo_axis.analysis.bag_streams import table_name
from servo_axis.analysis.serial import Serial
from servo_axis.analysis.signals import IDENTIFIER_SECTION, Signals
from servo_axis.params.resolve import Resolved
from servo_axis.params.values import PlantValues
from servo_axis.wire.cdr import EstimateData

#: The parameters an identifier estimates (003 eq. (2)): ``J, D, U, C``, as
#: named in the plant's parameters and in ``identifier/estimates``.
IDENTIFIED: tuple[str, ...] = ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm")


@dataclass(frozen=True)
class ParameterValues(Serial):
    """A value per identified parameter ``J, D, U, C`` of 003 eq. (2).

    Their values in SI units (kg m^2, N m s/rad, N m, N m), or ratios to the
    true values (no unit), by use.
    """

    inertia_kgm2: float
    damping_Nms_per_rad: float
    unbalance_Nm: float
    coulomb_Nm: float

    def values(self) -> tuple[float, float, float, float]:
        """``(J, D, U, C)``."""
        return (self.inertia_kgm2, self.damping_Nms_per_rad, self.unbalance_Nm, self.coulomb_Nm)


@dataclass(frozen=True)
class UpdateCounts(Serial):
    """How many estimates updated each parameter (eq. (16) for ``J, D, U``, eq. (8) for ``C``)."""

    inertia_kgm2: int
    damping_Nms_per_rad: int
    unbalance_Nm: int
    coulomb_Nm: int


@dataclass(frozen=True)
class OnlineIdentification(Serial):
    """The online parameter identification of a run (paper 003, topic ``identifier/estimates``).

    Attributes
    ----------
    estimates : int
        Estimates kept: validated, the first of each step.
    repeated : int
        Recorded estimates that repeat a kept one value for value (a
        restarted identifier's): not counted as junk.
    dropped : int
        Recorded estimates dropped as junk (failed the checks, or a second
        estimate of a step with other values).
    first_step, last_step : int or None
        The first and last estimate's ``step`` (None without estimates).
    final : ParameterValues
        ``J, D, U, C`` of the last estimate (by step); NaN without estimates.
    true : ParameterValues
        The plant's values (its parameters, defaults filled in); NaN for a
        parameter the plant model does not have.
    final_ratio : ParameterValues
        ``final / true`` (NaN where the true value is 0 or unknown).
    last_period_s : float or None
        The window of ``last_period_p2p``: the reference's period
        (``1 / reference.frequency_hz`` for a sine); None: not periodic, the
        whole run.
    last_period_p2p : ParameterValues
        Largest minus smallest estimate of each parameter over the estimates
        of the last ``last_period_s / T_u`` control steps up to the last
        estimate's (``step > last_step - round(last_period_s / T_u)``).
    final_kappa : float
        The PE index of eq. (7) of the last estimate.
    updates : UpdateCounts
        Per parameter, how many kept estimates updated it.
    """

    estimates: int
    repeated: int
    dropped: int
    first_step: int | None
    last_step: int | None
    final: ParameterValues
    true: ParameterValues
    final_ratio: ParameterValues
    last_period_s: float | None
    last_period_p2p: ParameterValues
    final_kappa: float
    updates: UpdateCounts


def _ratio(value: float, true: float) -> float:
    return value / true if true != 0.0 and math.isfinite(true) else math.nan


def summarise_estimates(
    estimates: list[EstimateData] | tuple[EstimateData, ...],
    *,
    true: ParameterValues,
    control_period_s: float,
    period_s: float | None,
    repeated: int = 0,
    dropped: int = 0,
) -> OnlineIdentification:
    """The :class:`OnlineIdentification` of validated estimates (any order; one per step).

    Parameters
    ----------
    estimates : sequence of EstimateData
        The kept estimates (:attr:`~servo_axis.analysis.signals.Signals.estimates`).
    true : ParameterValues
        The plant's true ``J, D, U, C``.
    control_period_s : float
        ``T_u``, s: an estimate's time is ``step * T_u``.
    period_s : float or None
        The reference's period, s: the window of the peak-to-peak values
        (None: every estimate).
    repeated, dropped : int
        Recorded estimates repeated and dropped (reported as they are).
    """
    ordered = sorted(estimates, key=lambda e: e.step)
    table = np.array(
        [(e.inertia_kgm2, e.damping_Nms_per_rad, e.unbalance_Nm, e.coulomb_Nm) for e in ordered],
        dtype=float,
    ).reshape(-1, 4)
    steps = np.array([e.step for e in ordered], dtype=int)
    nan4 = ParameterValues(math.nan, math.nan, math.nan, math.nan)
    if not ordered:
        final = p2p = nan4
        kappa = math.nan
    else:
        final = ParameterValues(*(float(v) for v in table[-1]))
        inside = np.ones(steps.size, dtype=bool)
        if period_s:
            inside = steps > steps[-1] - round(period_s / control_period_s)
        window = table[inside]
        p2p = ParameterValues(*(float(v) for v in window.max(axis=0) - window.min(axis=0)))
        kappa = ordered[-1].kappa
    counts = [sum(1 for e in ordered if e.updated[i]) for i in range(4)]
    return OnlineIdentification(
        estimates=len(ordered),
        repeated=repeated,
        dropped=dropped,
        first_step=ordered[0].step if ordered else None,
        last_step=ordered[-1].step if ordered else None,
        final=final,
        true=true,
        final_ratio=ParameterValues(
            *(_ratio(v, t) for v, t in zip(final.values(), true.values(), strict=True))
        ),
        last_period_s=period_s,
        last_period_p2p=p2p,
        final_kappa=kappa,
        updates=UpdateCounts(*counts),
    )


def true_parameters(plant_values: PlantValues) -> ParameterValues:
    """The plant's ``J, D, U, C`` (NaN for one its model does not have: each model has keys of
    its own)."""
    return ParameterValues(*(float(getattr(plant_values, name, math.nan)) for name in IDENTIFIED))


def identification(
    scenario: Resolved | dict[str, Any], sig: Signals, *, period_s: float | None
) -> OnlineIdentification | None:
    """The identification of a run with an identifier whose estimates the bag has, else None.

    Estimates are the validated ones of :attr:`Signals.estimates`; the
    repeats and the junk are those of the ``identifier/estimates`` topics.
    """
    topics = [t for t in sig.counts if table_name(t) == "identifier/estimates"]
    resolved = Resolved.of(scenario)
    if not resolved.has(IDENTIFIER_SECTION) or not topics:
        return None
    plant = resolved.plant
    return summarise_estimates(
        sig.estimates,
        true=true_parameters(plant),
        control_period_s=plant.control_period_s,
        period_s=period_s,
        repeated=sum(sig.repeated.get(t, 0) for t in topics),
        dropped=sum(sig.dropped.get(t, 0) for t in topics),
    )
