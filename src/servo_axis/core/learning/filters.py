"""Learning filters and the convergence condition of repetitive PTC (paper 000).

* the zero-phase learning filter ``Q = ((z + 2 + z^-1) / 4)^Nq`` (eq. (2)),
  realised as ``Q_r = z^-Nq Q`` (eq. (3)) by ``Nq`` samples of delay
  compensation in the memory;
* the n-times learning filter ``Q~n = sum_{m=1..n} C(n,m) (-1)^(m+1) Q^m =
  I - (I - Q)^n`` (eq. (19)), an FIR filter of half-length ``n Nq``
  (eq. (28)), which needs ``n Nq + 2 < Nd`` (eq. (29));
* zero-phase filtering of one period of a periodic signal;
* the convergence measure of eq. (15)/(21) and the modelling error and
  sensitivity it is computed from (Fig. 14).

The ILC laws of paper 001 use the same ``Q`` (its eq. (24)/(25)).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_positive

FloatArray = NDArray[np.float64]


def q_filter_taps(nq: int) -> FloatArray:
    """Taps of ``Q = ((z + 2 + z^-1)/4)^Nq`` (eq. (2)), indices ``-Nq .. Nq``.

    The taps are the binomial coefficients ``C(2Nq, k) / 4^Nq``: symmetric
    (zero phase) with unit sum (DC gain 1).
    """
    if not isinstance(nq, int) or nq < 0:
        raise ConfigError(f"nq: expected an integer >= 0, got {nq!r}")
    return np.array([math.comb(2 * nq, k) for k in range(2 * nq + 1)], dtype=float) / 4.0**nq


def n_times_taps(nq: int, n: int) -> FloatArray:
    """Taps of the n-times learning filter ``Q~n = I - (I - Q)^n`` (eq. (19)).

    Indices ``-n Nq .. n Nq`` (eq. (28)).
    """
    if not isinstance(n, int) or n < 1:
        raise ConfigError(f"n: expected an integer >= 1, got {n!r}")
    q = q_filter_taps(nq)
    one_minus_q = -q
    one_minus_q[nq] += 1.0
    power = np.array([1.0])
    for _ in range(n):
        power = np.convolve(power, one_minus_q)
    taps = -power
    taps[n * nq] += 1.0
    return taps


def q_gain(freq_hz: ArrayLike, *, nq: int, period_s: float) -> FloatArray:
    """Gain of ``Q`` at ``freq_hz``: ``cos(pi f T)^(2 Nq)`` (real: zero phase)."""
    f = np.asarray(freq_hz, dtype=float)
    t = require_positive("period_s", period_s)
    return np.cos(np.pi * f * t) ** (2 * nq)


def n_times_gain(freq_hz: ArrayLike, *, nq: int, n: int, period_s: float) -> FloatArray:
    """Gain of ``Q~n``: ``1 - (1 - |Q|)^n`` (000 Fig. 11 and 12)."""
    return 1.0 - (1.0 - q_gain(freq_hz, nq=nq, period_s=period_s)) ** n


def convergence_measure(q: ArrayLike, s: ArrayLike, delta: ArrayLike) -> float:
    """``sup_w |1 - Q - Q S Delta|`` over a frequency grid (eq. (15), (21)).

    Parameters
    ----------
    q : array
        Learning filter frequency response (``Q`` or ``Q~n``), real or complex.
    s : array
        Sensitivity ``S = 1 / (1 + P C)`` on the same grid.
    delta : array
        Multiplicative modelling error ``Delta = (P - P_n) / P_n``.

    Returns
    -------
    float
        Below 1 is the sufficient condition for monotonic convergence.
    """
    qa, sa, da = (np.asarray(v, dtype=complex) for v in (q, s, delta))
    return float(np.max(np.abs(1.0 - qa - qa * sa * da)))


def circular_filter(signal: ArrayLike, taps: ArrayLike) -> FloatArray:
    """Zero-phase FIR filtering of one period of a periodic signal.

    ``y[i] = sum_k taps[k] x[(i + k - h) mod N]`` with ``h = (len(taps)-1)/2``.
    """
    x = np.asarray(signal, dtype=float)
    b = np.asarray(taps, dtype=float)
    h = (len(b) - 1) // 2
    if len(b) % 2 != 1:
        raise ConfigError("taps: expected an odd number of taps (a zero-phase filter)")
    if len(b) > len(x):
        raise ConfigError(f"taps: {len(b)} taps are longer than the period of {len(x)} samples")
    y = np.zeros_like(x)
    for k, c in enumerate(b):
        if c != 0.0:
            y += c * np.roll(x, h - k)
    return y


def modelling_error_and_sensitivity(
    freq_hz: ArrayLike,
    *,
    plant: NDArray[np.complex128],
    nominal: NDArray[np.complex128],
    controller: NDArray[np.complex128],
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """``Delta = (P - P_n) / P_n`` and ``S_n = 1 / (1 + P_n C)`` (000 Fig. 14, eq. (11)).

    The responses are given on the grid ``freq_hz`` (used only for the shape check).
    """
    f = np.asarray(freq_hz, dtype=float)
    for name, v in (("plant", plant), ("nominal", nominal), ("controller", controller)):
        if np.shape(v) != f.shape:
            raise SignalError(f"{name}: expected the shape of freq_hz {f.shape}, got {np.shape(v)}")
    delta: NDArray[np.complex128] = (plant - nominal) / nominal
    sens: NDArray[np.complex128] = 1.0 / (1.0 + nominal * controller)
    return delta, sens
