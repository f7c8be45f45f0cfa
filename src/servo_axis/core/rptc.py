"""Repetitive perfect tracking control: learning filters and the periodic signal generator.

Paper 000 (Fujimoto & Takemura), Sect. III-IV, Figs. 5, 6, 10:

* the zero-phase learning filter ``Q = ((z + 2 + z^-1) / 4)^Nq`` (eq. (2)),
  realised as ``Q_r = z^-Nq Q`` (eq. (3)) by ``Nq`` samples of delay
  compensation in the memory;
* the n-times learning filter ``Q~n = sum_{m=1..n} C(n,m) (-1)^(m+1) Q^m =
  I - (I - Q)^n`` (eq. (19)), an FIR filter of half-length ``n Nq``
  (eq. (28)), which needs ``n Nq + 2 < Nd`` (eq. (29));
* the periodic signal generator (PSG): a memory of ``Nd = Td / Tr`` samples
  that accumulates the filtered tracking error cycle by cycle, ``c_{j+1} =
  c_j + Q e_j`` (the learning term of eq. (9)), and a state-variable
  generator giving position and central-difference velocity of the
  correction, which is added to the next cycle's target trajectory.

One learning cycle is ``Nd`` reference samples (period ``Tr``). The error of
a cycle is periodic, so the non-causal filter is applied circularly over
the cycle: the samples before the start of the cycle are those at its end,
which the memory holds (the delay compensation of Fig. 6). With circular
filtering ``Q`` and ``Q~n`` are circulant and commute, which makes eq. (27)
hold exactly in the lifted model with ``Delta = 0``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ConfigError, SignalError, TableError, require_positive

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


@dataclass(frozen=True, kw_only=True)
class LearningParams:
    """Parameters of the periodic signal generator.

    Parameters
    ----------
    samples_per_cycle : int
        ``Nd = Td / Tr``, >= 4.
    nq : int
        ``Nq`` of eq. (2), >= 0.
    n : int
        ``n`` of the n-times filter (1 is the conventional ``Q``), >= 1.
    period_s : float
        ``Tr``, s, > 0.
    """

    samples_per_cycle: int
    nq: int
    n: int = 1
    period_s: float = 2e-3

    def __post_init__(self) -> None:
        if not isinstance(self.samples_per_cycle, int) or self.samples_per_cycle < 4:
            raise ConfigError(
                f"samples_per_cycle: expected an integer >= 4, got {self.samples_per_cycle!r}"
            )
        if not isinstance(self.nq, int) or self.nq < 0:
            raise ConfigError(f"nq: expected an integer >= 0, got {self.nq!r}")
        if not isinstance(self.n, int) or self.n < 1:
            raise ConfigError(f"n: expected an integer >= 1, got {self.n!r}")
        require_positive("period_s", self.period_s)
        if not self.n * self.nq + 2 < self.samples_per_cycle:
            raise ConfigError(
                f"n, nq: eq. (29) needs n Nq + 2 < Nd, got n = {self.n}, Nq = {self.nq}, "
                f"Nd = {self.samples_per_cycle}"
            )

    @property
    def delay_samples(self) -> int:
        """Delay compensation of the realised filter, ``n Nq`` (eq. (3), (28))."""
        return self.n * self.nq


class PeriodicSignalGenerator:
    """The PSG of 000 Fig. 6 / Fig. 10: memory, learning filter, state-variable generator.

    Parameters
    ----------
    params : LearningParams
        ``Nd``, ``Nq``, ``n`` and ``Tr``.
    """

    def __init__(self, params: LearningParams) -> None:
        self.params = params
        self.taps = n_times_taps(params.nq, params.n)
        self._correction = np.zeros(params.samples_per_cycle)
        self.cycles_learned = 0

    @property
    def correction(self) -> FloatArray:
        """Accumulated correction of the target position per sample of the cycle (read-only copy)."""
        return self._correction.copy()

    def load(self, correction: ArrayLike, cycles_learned: int) -> None:
        """Restore a memory (e.g. from a file), checking its length and values."""
        c = np.asarray(correction, dtype=float)
        if c.shape != self._correction.shape:
            raise SignalError(
                f"correction: expected {self._correction.size} samples (Nd), got shape {c.shape}"
            )
        if not np.all(np.isfinite(c)):
            raise SignalError("correction: expected finite values")
        self._correction = c.copy()
        self.cycles_learned = int(cycles_learned)

    def learn(self, error: ArrayLike) -> FloatArray:
        """Learn one cycle's tracking error: ``c_{j+1} = c_j + Q~n e_j`` (eq. (9), (19)).

        Parameters
        ----------
        error : array, shape (Nd,)
            Tracking error ``r - y`` at the ``Nd`` reference samples of the
            cycle, in the unit of the correction (rad or m).

        Returns
        -------
        ndarray
            The new correction.
        """
        e = np.asarray(error, dtype=float)
        if e.shape != self._correction.shape:
            raise SignalError(
                f"error: expected {self._correction.size} samples (Nd), got shape {e.shape}"
            )
        if not np.all(np.isfinite(e)):
            raise SignalError("error: expected finite values")
        self._correction = self._correction + circular_filter(e, self.taps)
        self.cycles_learned += 1
        return self.correction

    def states(self) -> tuple[FloatArray, FloatArray]:
        """State-variable generator: position and central-difference velocity of the correction.

        The velocity ``(c[i+1] - c[i-1]) / (2 Tr)`` has no sample delay
        (000 Sect. III-A); the correction is periodic, so the ends wrap.
        """
        c = self._correction
        vel = (np.roll(c, -1) - np.roll(c, 1)) / (2.0 * self.params.period_s)
        return c.copy(), vel


MEMORY_FORMAT = "servo_axis rptc memory v1"


def save_memory(path: str | Path, psg: PeriodicSignalGenerator, *, scenario: str) -> None:
    """Persist the PSG memory atomically (write a temporary file, then rename).

    The file is JSON: format tag, scenario name, the learning parameters, the
    number of cycles learned, the correction (exact float text) and a SHA-256
    of the correction, so that a truncated or edited file is detected.
    """
    p = psg.params
    correction = psg.correction.tolist()
    body = {
        "format": MEMORY_FORMAT,
        "scenario": scenario,
        "samples_per_cycle": p.samples_per_cycle,
        "nq": p.nq,
        "n": p.n,
        "period_s": p.period_s,
        "cycles_learned": psg.cycles_learned,
        "correction": correction,
        "sha256": _digest(correction),
    }
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(json.dumps(body))
    os.replace(tmp, target)


def load_memory(
    path: str | Path, *, params: LearningParams, scenario: str
) -> tuple[FloatArray, int]:
    """Read a memory written by :func:`save_memory` and check it belongs to this run.

    Returns
    -------
    correction, cycles_learned

    Raises
    ------
    TableError
        Naming the file and what is wrong: not JSON or truncated, another
        format, a checksum mismatch, another scenario or other learning
        parameters (``Nd``, ``Nq``, ``n``, ``Tr``).
    OSError
        If the file cannot be read.
    """
    target = Path(path)
    try:
        body = json.loads(target.read_text())
    except ValueError as err:
        raise TableError(
            f"{target}: not a readable memory file (corrupt or truncated): {err}"
        ) from None
    if not isinstance(body, dict) or body.get("format") != MEMORY_FORMAT:
        raise TableError(f"{target}: expected format {MEMORY_FORMAT!r}")
    correction = body.get("correction")
    if not isinstance(correction, list) or body.get("sha256") != _digest(correction):
        raise TableError(
            f"{target}: the correction does not match its checksum (corrupt or edited)"
        )
    expected = {
        "scenario": scenario,
        "samples_per_cycle": params.samples_per_cycle,
        "nq": params.nq,
        "n": params.n,
        "period_s": params.period_s,
    }
    for key, value in expected.items():
        if body.get(key) != value:
            raise TableError(f"{target}: {key} is {body.get(key)!r}, this run has {value!r}")
    values = np.array(correction, dtype=float)
    if values.shape != (params.samples_per_cycle,) or not np.all(np.isfinite(values)):
        raise TableError(f"{target}: expected {params.samples_per_cycle} finite correction values")
    cycles = body.get("cycles_learned")
    if not isinstance(cycles, int) or cycles < 0:
        raise TableError(f"{target}: cycles_learned must be an integer >= 0, got {cycles!r}")
    return values, cycles


def _digest(values: list[float]) -> str:
    return hashlib.sha256(json.dumps(values).encode()).hexdigest()


def ball_screw_response(
    freq_hz: ArrayLike,
    *,
    torque_constant_Nm_per_A: float,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    modes: tuple[tuple[float, float, float], ...] = (),
    dead_time_s: float = 0.0,
) -> NDArray[np.complex128]:
    """Frequency response of eq. (30) of 000, current (A) to motor angle (rad).

    ``P(jw) = [K_T/(J s^2 + D s) + sum_i K_i/(s^2 + 2 zeta_i w_i s + w_i^2)] e^{-T_d s}``
    with ``K_i = a_i K_T / J`` and ``modes`` as ``(f_i Hz, zeta_i, a_i)``;
    without modes and dead time it is the nominal ``P_n`` of eq. (1).
    """
    s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
    kt, j, d = torque_constant_Nm_per_A, inertia_kgm2, damping_Nms_per_rad
    p = kt / (j * s**2 + d * s)
    for f_i, zeta, a in modes:
        w = 2 * np.pi * f_i
        p = p + (a * kt / j) / (s**2 + 2 * zeta * w * s + w**2)
    result: NDArray[np.complex128] = p * np.exp(-s * dead_time_s)
    return result


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
