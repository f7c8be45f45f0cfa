"""Frequency responses of the shipped plant models' linear parts, as the control loop samples them.

The loop holds the torque over a control period (zero-order hold) and reads
the sensors at the sample instants, so the measured response is that of
the sampled system, not ``P(j w)``. For a continuous model ``x' = A x + B
u(t - T_d)``, ``y = C x`` with ``T_d = m T + tau`` (``0 <= tau < T``) the
exact sampled model is (Franklin, Powell & Workman, *Digital Control of
Dynamic Systems*, Sect. 4.3.4)::

    x[k+1] = Phi x[k] + G0 u[k - m] + G1 u[k - m - 1]
    Phi = e^{A T},  G0 = Gamma(T - tau),  G1 = e^{A (T - tau)} Gamma(tau),
    Gamma(t) = int_0^t e^{A s} ds B

and its response ``C (z I - Phi)^-1 (G0 z^-m + G1 z^{-m-1})`` at ``z =
e^{j w T}``. The integrals come from one matrix exponential of the
augmented matrix ``[[A, B], [0, 0]]``.

Models (input: the motor torque ``K_T i``, N m; ``K_T`` cancels):

* :func:`rigid_modes`: paper 000 eq. (30) per unit torque,
  ``1 / (J s^2 + D s) + sum_i (a_i / J) / (s^2 + 2 zeta_i w_i s + w_i^2)``
  (``K_i = a_i K_T / J``), output the motor angle, with the dead time;
* :func:`two_inertia`: paper 004's elastic screw linearised with a linear
  spring ``k_h`` and the first-order current loop; outputs the motor angle
  and the table position.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from servo_axis.core.errors import ConfigError

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


def _gamma(a: FloatArray, b: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
    """``(e^{A t}, int_0^t e^{A s} ds B)``."""
    n, p = a.shape[0], b.shape[1]
    big = np.zeros((n + p, n + p))
    big[:n, :n] = a * t
    big[:n, n:] = b * t
    e = expm(big)
    return e[:n, :n], e[:n, n:]


def sampled_response(
    a: ArrayLike,
    b: ArrayLike,
    c: ArrayLike,
    *,
    frequency_hz: ArrayLike,
    control_period_s: float,
    dead_time_s: float = 0.0,
) -> ComplexArray:
    """Response of the zero-order-hold sampled ``(A, B, C)`` with a dead time.

    Parameters
    ----------
    a, b, c : array_like
        ``A`` (n x n), ``B`` (n x 1), ``C`` (q x n) of the continuous model.
    frequency_hz : array_like
        Frequencies, Hz, ``0 < f``.
    control_period_s : float
        ``T``, s, > 0.
    dead_time_s : float
        ``T_d``, s, >= 0.

    Returns
    -------
    ndarray of complex, shape (q, len(frequency_hz))
    """
    am = np.asarray(a, dtype=float)
    bm = np.asarray(b, dtype=float).reshape(am.shape[0], 1)
    cm = np.atleast_2d(np.asarray(c, dtype=float))
    t = float(control_period_s)
    if not (math.isfinite(dead_time_s) and dead_time_s >= 0.0):
        raise ConfigError(f"dead_time_s: expected a finite value >= 0, got {dead_time_s!r}")
    whole = math.floor(dead_time_s / t + 1e-12)
    tau = dead_time_s - whole * t
    tau = 0.0 if tau < 1e-15 else tau
    phi, _ = _gamma(am, bm, t)
    e_rest, g0 = _gamma(am, bm, t - tau)
    _, g_tau = _gamma(am, bm, tau) if tau > 0.0 else (None, np.zeros_like(bm))
    g1 = e_rest @ g_tau
    f = np.asarray(frequency_hz, dtype=float)
    z = np.exp(2j * math.pi * f * t)
    n = am.shape[0]
    # Every frequency at once: a stack of (z I - Phi) x = G0 z^-m + G1 z^-(m+1).
    lhs = z[:, None, None] * np.eye(n) - phi
    rhs = (
        g0[None, :, :] * (z**-whole)[:, None, None]
        + g1[None, :, :] * (z ** (-whole - 1))[:, None, None]
    )
    x = np.linalg.solve(lhs, rhs)[:, :, 0]
    return np.asarray((cm @ x.T).astype(np.complex128))


def rigid_modes(
    *,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    modes: tuple[tuple[float, float, float], ...] = (),
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(A, B, C)`` of paper 000 eq. (30) per unit torque (motor angle out).

    Parameters
    ----------
    inertia_kgm2 : float
        ``J``, kg m^2, > 0.
    damping_Nms_per_rad : float
        ``D``, N m s/rad, >= 0.
    modes : tuple of (frequency_hz, zeta, a)
        The modes: ``(a / J) / (s^2 + 2 zeta w s + w^2)``, ``w = 2 pi f``.
    """
    j, d = inertia_kgm2, damping_Nms_per_rad
    n = 2 + 2 * len(modes)
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    c = np.zeros((1, n))
    a[0, 1] = 1.0
    a[1, 1] = -d / j
    b[1, 0] = 1.0 / j
    c[0, 0] = 1.0
    for i, (f, zeta, gain) in enumerate(modes):
        w = 2.0 * math.pi * f
        r = 2 + 2 * i
        a[r, r + 1] = 1.0
        a[r + 1, r] = -w * w
        a[r + 1, r + 1] = -2.0 * zeta * w
        b[r + 1, 0] = gain / j
        c[0, r] = 1.0
    return a, b, c


def two_inertia(
    *,
    motor_inertia_kgm2: float,
    motor_damping_Nms_per_rad: float,
    table_mass_kg: float,
    table_damping_Ns_per_m: float,
    stiffness_N_per_m: float,
    screw_damping_Ns_per_m: float,
    lead_m_per_rad: float,
    current_bandwidth_hz: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(A, B, C)`` of the elastic screw of paper 004 (motor angle and table position out).

    ``J_m th'' = T - B_m th' - R F``, ``M x'' = F - C_t x'``, ``F = k_h
    (R th - x) + c_s (R th' - x')``, ``T' = w_c (T_ref - T)`` (the current
    loop; ideal when ``current_bandwidth_hz`` is 0). States ``th, th', x,
    x'`` (and ``T``); SI units throughout.
    """
    jm, bm = motor_inertia_kgm2, motor_damping_Nms_per_rad
    m, ct = table_mass_kg, table_damping_Ns_per_m
    k, cs, r = stiffness_N_per_m, screw_damping_Ns_per_m, lead_m_per_rad
    lag = current_bandwidth_hz > 0.0
    n = 5 if lag else 4
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    a[0, 1] = 1.0
    a[1, 0] = -r * k * r / jm
    a[1, 1] = -(bm + r * cs * r) / jm
    a[1, 2] = r * k / jm
    a[1, 3] = r * cs / jm
    a[2, 3] = 1.0
    a[3, 0] = k * r / m
    a[3, 1] = cs * r / m
    a[3, 2] = -k / m
    a[3, 3] = -(cs + ct) / m
    if lag:
        wc = 2.0 * math.pi * current_bandwidth_hz
        a[1, 4] = 1.0 / jm
        a[4, 4] = -wc
        b[4, 0] = wc
    else:
        b[1, 0] = 1.0 / jm
    c = np.zeros((2, n))
    c[0, 0] = 1.0
    c[1, 2] = 1.0
    return a, b, c


def axial_mode_hz(
    *,
    motor_inertia_kgm2: float,
    table_mass_kg: float,
    stiffness_N_per_m: float,
    lead_m_per_rad: float,
) -> float:
    """The undamped two-inertia mode ``sqrt(k_h (1/M + R^2/J_m)) / 2 pi``, Hz."""
    return math.sqrt(
        stiffness_N_per_m * (1.0 / table_mass_kg + lead_m_per_rad**2 / motor_inertia_kgm2)
    ) / (2.0 * math.pi)
