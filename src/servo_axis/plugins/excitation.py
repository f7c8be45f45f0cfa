"""Feedforward term ``excitation``: a known test torque for a frequency-response measurement.

A periodic multisine, chirp or PRBS torque
(:class:`servo_axis.core.identification.offline.excitation.Excitation`) added to the
feedforward current, so that it enters the plant input on top of whatever
loop stabilises the axis. It runs on any plant the run has: the suite's,
an outside simulator, a real axis (``run --external plant``). The signal is
a function of the control sample alone, so ``python -m servo_axis identify``
rebuilds it from the run's scenario (docs/how-to/identify-your-axis.md).
"""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.errors import ParameterFileError
from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock
from servo_axis.core.identification.offline.excitation import PHASES, SIGNALS, Excitation
from servo_axis.params.param import Param, build
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.plugins.values import ExcitationValues

SCHEMA: dict[str, Param] = {
    "excitation.enabled": Param(
        False,
        meaning="add a periodic test torque at the plant input for a frequency-response "
        "measurement (docs/how-to/identify-your-axis.md)",
    ),
    "excitation.signal": Param(
        "multisine",
        choices=SIGNALS,
        meaning="multisine on every line of the band (low crest factor), periodic linear "
        "chirp, or PRBS (maximum-length sequence)",
    ),
    "excitation.amplitude_Nm": Param(
        0.5, unit="N m", above=0.0, meaning="peak of the test torque at the motor"
    ),
    "excitation.min_frequency_hz": Param(
        1.0, unit="Hz", above=0.0, meaning="lowest frequency of the band"
    ),
    "excitation.max_frequency_hz": Param(
        200.0,
        unit="Hz",
        above=0.0,
        meaning="highest frequency of the band, below the Nyquist frequency 1 / (2 T_u)",
    ),
    "excitation.period_s": Param(
        1.0,
        unit="s",
        above=0.0,
        meaning="one period of the signal, a whole number of control periods; the lines are "
        "1 / period_s apart",
    ),
    "excitation.periods": Param(
        4, minimum=1, meaning="periods averaged (>= 2 gives an uncertainty per line)"
    ),
    "excitation.settle_periods": Param(
        1, minimum=0, meaning="periods before the averaged ones, not used (the loop's transient)"
    ),
    "excitation.start_s": Param(
        0.0,
        unit="s",
        minimum=0.0,
        meaning="when the excitation starts, a whole number of control periods",
    ),
    "excitation.phases": Param(
        "schroeder", choices=PHASES, meaning="multisine phases: Schroeder's or random"
    ),
    "excitation.seed": Param(0, minimum=0, meaning="seed of the random phases"),
}


def _samples(values: ExcitationValues, key: str, seconds: float) -> int:
    """``seconds`` (of ``key``) as a whole number of control periods."""
    t = values.control_period_s
    n = seconds / t
    if abs(n - round(n)) > 1e-6 * max(1.0, n):
        raise ParameterFileError(
            f"parameter '{key}': expected a whole number of control periods "
            f"({t!r} s), got {seconds!r}"
        )
    return int(np.rint(n))


def excitation_of(values: ExcitationValues) -> Excitation | None:
    """The excitation of checked feedforward values, or None when it is off."""
    e = values.excitation
    if not e.enabled:
        return None
    keys = {
        "period_samples": "excitation.period_s",
        "start_step": "excitation.start_s",
        "control_period_s": "control_period_s",
    }
    return build(
        "excitation.",
        Excitation,
        keys=keys,
        signal=e.signal,
        amplitude_Nm=e.amplitude_Nm,
        min_frequency_hz=e.min_frequency_hz,
        max_frequency_hz=e.max_frequency_hz,
        period_samples=_samples(values, "excitation.period_s", e.period_s),
        periods=e.periods,
        settle_periods=e.settle_periods,
        start_step=_samples(values, "excitation.start_s", e.start_s),
        control_period_s=values.control_period_s,
        phases=e.phases,
        seed=e.seed,
    )


class ExcitationTerm:
    """The excitation torque as a feedforward current (nominal ``K_T``)."""

    def __init__(self, excitation: Excitation, *, torque_constant_Nm_per_A: float) -> None:
        #: The signal (``python -m servo_axis identify`` reads it from the term).
        self.excitation = excitation
        self._period = excitation.one_period() / torque_constant_Nm_per_A
        self._start = excitation.start_step
        self._stop = excitation.stop_step
        self._n = excitation.period_samples

    def currents(self, block: ReferenceBlock) -> np.ndarray:
        k = np.asarray(block.step, dtype=np.int64)
        on = (k >= self._start) & (k < self._stop)
        return np.where(on, self._period[np.mod(k - self._start, self._n)], 0.0)


def _torque_constant(values: ExcitationValues) -> float:
    kt = values.nominal.torque_constant_Nm_per_A
    if not (math.isfinite(kt) and kt > 0):
        raise ParameterFileError(
            f"parameter 'nominal.torque_constant_Nm_per_A': expected > 0, got {kt!r}"
        )
    return kt


def _build(values: ExcitationValues) -> FeedforwardTerm | None:
    excitation = excitation_of(values)
    if excitation is None:
        return None
    return ExcitationTerm(excitation, torque_constant_Nm_per_A=_torque_constant(values))


def _check(values: ExcitationValues) -> None:
    """The signal's settings (a frozen record; its samples are not computed) and ``K_T``."""
    if excitation_of(values) is not None:
        _torque_constant(values)


#: The entry point ``servo_axis.feedforward_terms: excitation``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    check=_check,
    values=ExcitationValues,
    order=50.0,
    description="periodic test torque (multisine, chirp, PRBS) for a frequency-response "
    "measurement (docs/how-to/identify-your-axis.md)",
)
