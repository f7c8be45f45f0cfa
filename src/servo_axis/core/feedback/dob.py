"""Inverse-model disturbance observer on the motor angle (paper 004 Sect. II, Fig. 5)."""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive
from servo_axis.core.feedback.discrete import tustin


class DisturbanceObserver:
    """Inverse-model disturbance observer on the motor angle with a first-order LPF.

    ``d_hat = Q(s) [ (J s + D) / K_T * w - u_prev ]`` with
    ``Q(s) = w_q / (s + w_q)``, where ``w[k] = (theta[k] - theta[k-1]) / T``
    (the angle is differenced once because ``P_n^-1`` is improper by two and
    ``Q`` is first order) and ``u_prev = u[k-1]`` is the total current of
    the previous sample. Each part is Tustin-discretised. ``d_hat`` is the
    input disturbance in current units with ``y = P_n (u + d)``; the caller
    applies ``u = u_ref - d_hat``.

    Parameters
    ----------
    inertia_kgm2, damping_Nms_per_rad, torque_constant_Nm_per_A : float
        Nominal model.
    cutoff_hz : float
        LPF cut-off ``w_q / 2 pi``, Hz, > 0 (80 Hz in paper 004).
    period_s : float
        Control period, s, > 0.
    """

    def __init__(
        self,
        *,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
        cutoff_hz: float,
        period_s: float,
    ) -> None:
        j = require_positive("inertia_kgm2", inertia_kgm2)
        d = require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad)
        kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        wq = 2.0 * math.pi * require_positive("cutoff_hz", cutoff_hz)
        self.period_s = require_positive("period_s", period_s)
        if cutoff_hz >= 0.5 / period_s:
            raise ConfigError(f"cutoff_hz: expected below the Nyquist frequency, got {cutoff_hz!r}")
        self._inverse = tustin(np.array([wq * j / kt, wq * d / kt]), np.array([1.0, wq]), period_s)
        self._lpf = tustin(np.array([wq]), np.array([1.0, wq]), period_s)
        self._last_angle: float | None = None

    def reset(self) -> None:
        """Zero the observer state."""
        self._inverse.reset()
        self._lpf.reset()
        self._last_angle = None

    def update(self, angle_rad: float, previous_current_A: float) -> float:
        """Disturbance estimate (A) after this sample's angle (rad)."""
        last = angle_rad if self._last_angle is None else self._last_angle
        self._last_angle = angle_rad
        velocity = (angle_rad - last) / self.period_s
        return self._inverse.update(velocity) - self._lpf.update(previous_current_A)
