"""The sigmoid law of paper 004 eq. (9) with sign and distance from the measured stage.

Paper 004 Sect. IV writes the compensation as

    F_c = sgn(v) sqrt((gamma / d_r^)^2 / (1 + (gamma / d_r^)^2)) F_0,    d_r^ = sigma / z,

(eqs. (8)-(9)) with ``v`` "the velocity of the stage" and ``z`` the
displacement from the reversal point: both are measured. The feedforward
term :class:`~servo_axis.core.feedforward.sigmoid.SigmoidTerm` takes them
from the reference instead (it knows the next reversal and brakes ``F_c``
before it). :class:`StageSigmoid` is the paper's wording: a per-sample
function of the table position read on the linear scale, so it lives in the
feedback loop (:class:`~servo_axis.core.feedback.loop.FeedbackLoop`), where
the measurement is, and knows only the past:

* the direction ``sgn(v)`` is the direction of the last change of the scale
  reading (a reading equal to the last keeps it: the scale's count is the
  resolution of ``v``); before the first change it is 0 (no current);
* a reversal is the first reading behind the furthest point of the current
  motion (the extremum): the direction flips there and the reversal point is
  that extremum; ``z = |x_t - x_rev|``, ``inf`` before the first reversal
  (``|F_c| = F_0``);
* the current is ``F_c / K_T`` (A), ``F_c`` of eq. (9)
  (:func:`~servo_axis.core.feedforward.sigmoid.sigmoid_torque`, the same
  floats written out for one sample).

So ``F_c`` keeps ``+-F_0`` up to the measured reversal, drops to 0 there and
rises again in the new direction within about ``x_s / 2``: the law cannot
act before the stage reverses. Deterministic: a function of the sequence of
readings alone.
"""

from __future__ import annotations

import math

from servo_axis.core.errors import SignalError, require_positive
from servo_axis.core.feedforward.sigmoid import SigmoidParams


class StageSigmoid:
    """Eq. (9) of 004 from the measured table position, one sample at a time.

    Parameters
    ----------
    params : SigmoidParams
        ``sigma`` (m^2/rad), ``gamma`` (m/rad), ``F_0`` (N m) of eqs. (8)-(9).
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.

    Raises
    ------
    ConfigError
        ``torque_constant_Nm_per_A`` not finite and > 0.
    """

    def __init__(self, params: SigmoidParams, *, torque_constant_Nm_per_A: float) -> None:
        self.params = params
        self._kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        self._ratio = params.gamma_m_per_rad / params.sigma_m2_per_rad  # r = ratio z, 1/m
        self._direction = 0
        self._extremum: float | None = None
        self._reversal_m: float | None = None

    @property
    def direction(self) -> int:
        """``sgn(v)`` as last measured: +1, -1, or 0 before the stage first moved."""
        return self._direction

    @property
    def reversal_m(self) -> float | None:
        """The table position of the last measured reversal (m), None before the first."""
        return self._reversal_m

    def torque_Nm(self, table_m: float) -> float:
        """``F_c`` of eq. (9) (N m, motor torque) after the reading ``table_m`` (m).

        Raises
        ------
        SignalError
            ``table_m`` not finite.
        """
        if not math.isfinite(table_m):
            raise SignalError(f"table_m: expected a finite scale reading, got {table_m!r}")
        extremum = self._extremum
        d = self._direction
        if extremum is None:
            self._extremum = table_m
        elif d == 0:
            if table_m != extremum:
                self._direction = 1 if table_m > extremum else -1
                self._extremum = table_m
        elif (table_m - extremum) * d > 0.0:
            self._extremum = table_m
        elif table_m != extremum:
            # Behind the furthest point of this motion: the stage reversed there.
            self._reversal_m = extremum
            self._direction = -d
            self._extremum = table_m
        if self._direction == 0:
            return 0.0
        if self._reversal_m is None:
            return self._direction * self.params.coulomb_Nm
        r = self._ratio * abs(table_m - self._reversal_m)
        return self._direction * self.params.coulomb_Nm * (r / math.hypot(1.0, r)) + 0.0

    def current_A(self, table_m: float) -> float:
        """``F_c / K_T`` (A) after the reading ``table_m`` (m); call once per sample, in order."""
        return self.torque_Nm(table_m) / self._kt
