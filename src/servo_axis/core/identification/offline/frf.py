"""The plant's frequency response measured in closed loop, the excitation as instrument.

With a known excitation ``d`` added to the plant input ``u`` of a loop
``u = d + C (r - y)`` and noise ``v`` on the measured output ``y = P u + v``,
the direct estimate ``S_uy / S_uu`` is biased towards ``-1 / C`` wherever
the noise dominates, because the loop feeds ``v`` back into ``u`` (``u``
and ``v`` are correlated). The excitation is independent of the noise, so
the ratio of the cross spectra with it (the indirect or instrumental
variable estimate, Ljung 1999 Sect. 13.5; Pintelon & Schoukens 2012 Sect.
2.6 and 5.3)::

    P = S_dy / S_du = (P S) / S,   S = 1 / (1 + P C)

is consistent: ``S_du`` is the sensitivity and ``S_dy`` the process
sensitivity, each seen by ``d``, and the loop's controller drops out. The
spectra are Welch averages (:func:`scipy.signal.csd`, :func:`scipy.signal.welch`)
over whole periods of the excitation, one period per segment, rectangular
window, no overlap: for a periodic ``d`` that is the average of the
periods' DFTs, without leakage at the excited lines, and ``S_dy / S_du``
equals ``mean_p Y_p / mean_p U_p``. The uncertainty per line is the spread of
the periods: with ``E_p = Y_p - P U_p``, ``var(P) = sum_p |E_p|^2 /
((n_p - 1) n_p |mean U|^2)`` (first order in the noise). The coherence is
``|S_dy|^2 / (S_dd S_yy)``: the share of the output's power that the
excitation explains (1 for a noise-free linear plant); the one reported is
the smaller of it and the same of ``u`` (inside a stiff loop the excitation's
share of ``u`` is what runs out first, at the low lines).

A slow drift that is not periodic (the loop following a move, a creeping
operating point) leaks into the low lines, where a stiff loop leaves little
of the excitation in ``u`` and ``y``. Before the spectra, a polynomial in
time (degree ``trend_degree``) is fitted to each of ``u`` and ``y`` in the
complement of the periodic signals, ``(I - Pi) s = (I - Pi) V c`` with
``Pi`` the average over the periods tiled, and subtracted: the periodic
part (the response to the excitation) is left as it is, the drift goes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import csd, welch

from servo_axis.core.errors import SignalError

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class FrequencyResponse:
    """A measured frequency response at the excited lines.

    Attributes
    ----------
    frequency_hz : ndarray
        Line frequencies, Hz.
    response : ndarray of complex
        ``P`` at each line (output unit per N m).
    coherence : ndarray
        The smaller of the excitation's coherence with the output,
        ``|S_dy|^2 / (S_dd S_yy)``, and with the plant input,
        ``|S_du|^2 / (S_dd S_uu)``, at each line, 0..1: the estimate needs both.
    std : ndarray
        Standard deviation of ``P`` (complex, the root of ``E|dP|^2``); NaN
        with one period.
    sensitivity : ndarray of complex
        ``S_du / S_dd``: the loop's sensitivity ``1 / (1 + P C)`` at each line.
    periods : int
        Periods averaged.
    """

    frequency_hz: FloatArray
    response: ComplexArray
    coherence: FloatArray
    std: FloatArray
    sensitivity: ComplexArray
    periods: int


def _periods(name: str, x: ArrayLike, period: int, count: int) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1 or a.size != period * count:
        raise SignalError(
            f"{name}: expected {period * count} samples ({count} periods of {period}), "
            f"got shape {a.shape}"
        )
    if not np.all(np.isfinite(a)):
        raise SignalError(f"{name}: expected finite samples, got NaN or inf")
    return a


def remove_trend(x: FloatArray, period: int, count: int, degree: int) -> FloatArray:
    """``x`` less the polynomial of ``degree`` fitted orthogonally to period-``period`` signals."""
    if degree < 1 or count < 2:
        return x
    t = np.linspace(-1.0, 1.0, x.size)
    v = np.vander(t, degree + 1, increasing=True)[:, 1:]

    def aperiodic(a: NDArray[np.float64]) -> NDArray[np.float64]:
        shaped = a.reshape(count, period, *a.shape[1:])
        return np.asarray((shaped - shaped.mean(axis=0, keepdims=True)).reshape(a.shape))

    coef, *_ = np.linalg.lstsq(aperiodic(v), aperiodic(x), rcond=None)
    return np.asarray(x - v @ coef, dtype=np.float64)


def closed_loop_frf(
    *,
    excitation: ArrayLike,
    plant_input: ArrayLike,
    output: ArrayLike,
    period_samples: int,
    lines: ArrayLike,
    control_period_s: float,
    trend_degree: int = 3,
) -> FrequencyResponse:
    """The plant's response from ``plant_input`` to ``output``, the excitation as instrument.

    Parameters
    ----------
    excitation : array_like
        ``d``: the known excitation over whole periods (any unit).
    plant_input : array_like
        ``u``: the plant input, N m (the ``command`` torque).
    output : array_like
        ``y``: a sensor (rad, m).
    period_samples : int
        ``N``: samples per period; the three signals hold a whole number
        of periods, the same samples.
    lines : array_like of int
        The excited DFT lines ``m`` (``f = m / (N T)``).
    control_period_s : float
        ``T``, s.
    trend_degree : int
        Degree of the drift removed from ``u`` and ``y`` (0: none).

    Returns
    -------
    FrequencyResponse
    """
    n = int(period_samples)
    d_all = np.asarray(excitation, dtype=np.float64)
    count = d_all.size // n if n > 0 else 0
    if count < 1 or d_all.size != count * n:
        raise SignalError(
            f"excitation: expected a whole number (>= 1) of periods of {n} samples, "
            f"got {d_all.size} samples"
        )
    d = _periods("excitation", d_all, n, count)
    u = _periods("plant_input", plant_input, n, count)
    y = _periods("output", output, n, count)
    u = remove_trend(u, n, count, trend_degree)
    y = remove_trend(y, n, count, trend_degree)
    m = np.asarray(lines, dtype=np.int64)
    fs = 1.0 / control_period_s
    kw = {"fs": fs, "window": "boxcar", "nperseg": n, "noverlap": 0, "detrend": False}
    _, s_du = csd(d, u, **kw)
    _, s_dy = csd(d, y, **kw)
    _, s_dd = welch(d, **kw)
    _, s_yy = welch(y, **kw)
    s_du, s_dy, s_dd, s_yy = s_du[m], s_dy[m], s_dd[m], s_yy[m]
    if np.any(np.abs(s_du) == 0.0):
        raise SignalError("excitation: a line of the band has no excitation power")
    response = s_dy / s_du
    _, s_uu = welch(u, **kw)
    tiny = np.finfo(float).tiny
    coherence = np.minimum(
        np.abs(s_dy) ** 2 / np.maximum(s_dd * s_yy, tiny),
        np.abs(s_du) ** 2 / np.maximum(s_dd * s_uu[m], tiny),
    )
    # scipy's csd is conj(D) Y; the sensitivity d -> u is S_du / S_dd.
    sensitivity = s_du / s_dd
    if count >= 2:
        big_u = np.fft.rfft(u.reshape(count, n), axis=1)[:, m]
        big_y = np.fft.rfft(y.reshape(count, n), axis=1)[:, m]
        err = big_y - response * big_u
        var = (np.abs(err) ** 2).sum(axis=0) / ((count - 1) * count * np.abs(big_u.mean(0)) ** 2)
        std = np.sqrt(var)
    else:
        std = np.full(m.size, np.nan)
    return FrequencyResponse(
        frequency_hz=m * fs / n,
        response=np.asarray(response, dtype=np.complex128),
        coherence=np.clip(coherence, 0.0, 1.0),
        std=np.asarray(std, dtype=np.float64),
        sensitivity=np.asarray(sensitivity, dtype=np.complex128),
        periods=count,
    )
