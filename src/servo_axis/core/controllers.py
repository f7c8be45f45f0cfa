"""Feedback controllers: pole-placement PID (Tustin) and the disturbance observer.

Both act on the nominal plant of paper 000 eq. (1),
``P_n(s) = K_T / (J s^2 + D s)`` from current (A) to motor angle (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError, require_nonnegative, require_positive


class DiscreteFilter:
    """A rational discrete filter ``b(z^-1) / a(z^-1)`` in transposed direct form II.

    Parameters
    ----------
    b, a : sequence of float
        Numerator and denominator coefficients in powers of ``z^-1``;
        ``a[0]`` must be non-zero (the filter is normalised by it).
    """

    def __init__(self, b: np.ndarray, a: np.ndarray) -> None:
        b = np.atleast_1d(np.asarray(b, dtype=float))
        a = np.atleast_1d(np.asarray(a, dtype=float))
        if a[0] == 0.0:
            raise ConfigError("a: expected a non-zero leading denominator coefficient")
        n = max(len(a), len(b))
        self.b = [float(v) for v in np.pad(b, (0, n - len(b))) / a[0]]
        self.a = [float(v) for v in np.pad(a, (0, n - len(a))) / a[0]]
        self._z = [0.0] * (n - 1)

    def reset(self) -> None:
        """Zero the internal state."""
        self._z = [0.0] * len(self._z)

    def update(self, x: float) -> float:
        """Filter one sample."""
        b, a, z = self.b, self.a, self._z
        y = b[0] * x + (z[0] if z else 0.0)
        for i in range(len(z)):
            nxt = z[i + 1] if i + 1 < len(z) else 0.0
            z[i] = b[i + 1] * x - a[i + 1] * y + nxt
        return y


def tustin(num: np.ndarray, den: np.ndarray, period_s: float) -> DiscreteFilter:
    """Bilinear (Tustin) discretisation of ``num(s) / den(s)`` as a filter.

    Substitutes ``s = (2 / T) (1 - z^-1) / (1 + z^-1)`` and multiplies through
    by ``(1 + z^-1)^n``, ``n`` the order of the denominator.
    """
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    n = len(den) - 1
    if len(num) - 1 > n:
        raise ConfigError("num: expected a proper transfer function (deg num <= deg den)")
    num = np.concatenate((np.zeros(n + 1 - len(num)), num))
    k = 2.0 / period_s
    minus = np.array([1.0, -1.0])  # 1 - z^-1, coefficients in powers of z^-1
    plus = np.array([1.0, 1.0])  # 1 + z^-1

    def substitute(poly: np.ndarray) -> np.ndarray:
        out = np.zeros(n + 1)
        for i, c in enumerate(poly):  # c multiplies s^(n - i)
            power = n - i
            term = np.array([c * k**power])
            for _ in range(power):
                term = np.convolve(term, minus)
            for _ in range(n - power):
                term = np.convolve(term, plus)
            out += term
        return out

    return DiscreteFilter(substitute(num), substitute(den))


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
