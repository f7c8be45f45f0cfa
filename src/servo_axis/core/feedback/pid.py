"""Pole-placement PID with filtered derivative, discretised by Tustin (paper 000 Sect. V).

It acts on the nominal plant of paper 000 eq. (1),
``P_n(s) = K_T / (J s^2 + D s)`` from current (A) to motor angle (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive
from servo_axis.core.feedback.discrete import tustin


@dataclass(frozen=True, kw_only=True)
class PidGains:
    """Gains of ``C(s) = Kp + Ki / s + Kd s / (tau s + 1)`` (rad -> A).

    Attributes
    ----------
    kp_A_per_rad, ki_A_per_rad_s, kd_A_s_per_rad : float
        Proportional, integral and derivative gains.
    derivative_tau_s : float
        Time constant of the derivative filter, s, > 0.
    """

    kp_A_per_rad: float
    ki_A_per_rad_s: float
    kd_A_s_per_rad: float
    derivative_tau_s: float

    def __post_init__(self) -> None:
        require_nonnegative("kp_A_per_rad", self.kp_A_per_rad)
        require_nonnegative("ki_A_per_rad_s", self.ki_A_per_rad_s)
        require_positive("derivative_tau_s", self.derivative_tau_s)

    def transfer_function(self) -> tuple[np.ndarray, np.ndarray]:
        """Numerator and denominator of ``C(s)`` in descending powers of s."""
        kp, ki, kd, tau = (
            self.kp_A_per_rad,
            self.ki_A_per_rad_s,
            self.kd_A_s_per_rad,
            self.derivative_tau_s,
        )
        return np.array([kp * tau + kd, kp + ki * tau, ki]), np.array([tau, 1.0, 0.0])


def design_pid_pole_placement(
    *,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    torque_constant_Nm_per_A: float,
    bandwidth_hz: float,
) -> PidGains:
    """PID with filtered derivative by pole placement on ``P_n`` (paper 000, Sect. V).

    Pole pattern: all four closed-loop poles at ``s = -w``, ``w = 2 pi
    bandwidth_hz``. The characteristic polynomial of ``1 + P_n C = 0``,
    ``J tau s^4 + (J + D tau) s^3 + (D + K_T Kp tau + K_T Kd) s^2
    + K_T (Kp + Ki tau) s + K_T Ki``, is matched to ``J tau (s + w)^4``, which
    fixes the derivative filter ``tau = J / (4 w J - D)`` as well.

    Parameters
    ----------
    inertia_kgm2 : float
        Nominal ``J``, kg m^2, > 0.
    damping_Nms_per_rad : float
        Nominal ``D``, N m s/rad, >= 0.
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    bandwidth_hz : float
        Position-loop bandwidth (the pole radius), Hz, > 0, with
        ``4 w J > D``.

    Returns
    -------
    PidGains
    """
    j = require_positive("inertia_kgm2", inertia_kgm2)
    d = require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad)
    kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
    w = 2.0 * math.pi * require_positive("bandwidth_hz", bandwidth_hz)
    if 4.0 * w * j <= d:
        raise ConfigError(
            f"bandwidth_hz: expected 4 (2 pi f) J > D for a positive derivative filter, got {bandwidth_hz!r}"
        )
    tau = j / (4.0 * w * j - d)
    ki = w**4 * j * tau / kt
    kp = 4.0 * w**3 * j * tau / kt - ki * tau
    kd = (6.0 * w**2 * j * tau - d) / kt - kp * tau
    return PidGains(kp_A_per_rad=kp, ki_A_per_rad_s=ki, kd_A_s_per_rad=kd, derivative_tau_s=tau)


class DiscretePid:
    """The PID ``C(s)`` discretised by Tustin at the control period.

    Parameters
    ----------
    gains : PidGains
        Continuous-time gains.
    period_s : float
        Control period ``T_u``, s, > 0.
    """

    def __init__(self, *, gains: PidGains, period_s: float) -> None:
        self.gains = gains
        self.period_s = require_positive("period_s", period_s)
        num, den = gains.transfer_function()
        self.filter = tustin(num, den, period_s)

    def reset(self) -> None:
        """Zero the controller state."""
        self.filter.reset()

    def update(self, error_rad: float) -> float:
        """Current (A) for this sample's angle error (rad)."""
        return self.filter.update(error_rad)
