"""Periodic excitation signals for a frequency-response measurement.

Three signals, each periodic in ``N`` control samples so that a whole
number of periods can be averaged without leakage (Pintelon & Schoukens,
*System Identification: A Frequency Domain Approach*, 2nd ed., Ch. 2 and 5):

* ``multisine``: ``sum_m cos(2 pi m k / N + phi_m)`` over every DFT line ``m``
  in the band, with Schroeder phases ``phi_m = -pi m' (m' + 1) / M`` (``m'``
  the line's rank, ``M`` the number of lines: a low crest factor) or
  phases drawn uniformly from a seeded generator;
* ``chirp``: a linear sweep from the lowest to the highest line of the band
  over one period, its end frequencies on DFT lines (``m0 + m1`` even) so
  that the phase returns to a multiple of ``2 pi`` and the signal repeats;
* ``prbs``: a maximum-length binary sequence (:func:`scipy.signal.max_len_seq`)
  of ``+-1`` held ``hold`` samples per bit, its clock ``1 / (hold T)`` about
  2.5 times the band's top (the ``sinc^2`` spectrum is down 3 dB at 0.44 of
  the clock), cut to ``N`` samples.

Each is scaled to the peak ``amplitude_Nm`` (a torque at the motor). The
signal is 0 before ``start_step`` and after ``settle_periods + periods``
periods; the ``periods`` after the settling ones are the measured window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive

#: The excitation signals.
SIGNALS = ("multisine", "chirp", "prbs")
#: The phases of a multisine.
PHASES = ("schroeder", "random")


@dataclass(frozen=True, kw_only=True)
class Excitation:
    """A periodic excitation torque, added at the plant input.

    Parameters
    ----------
    signal : str
        ``multisine``, ``chirp`` or ``prbs``.
    amplitude_Nm : float
        Peak torque at the motor, N m, > 0.
    min_frequency_hz, max_frequency_hz : float
        The band, Hz: ``0 < min < max < 1 / (2 T)``; it must hold at least
        one DFT line ``m / (N T)``.
    period_samples : int
        ``N``, samples of one period (>= 8): the lines are ``1 / (N T)`` apart.
    periods : int
        Periods averaged, >= 1 (>= 2 gives an uncertainty per line).
    settle_periods : int
        Periods before the averaged ones (transients of the loop), >= 0.
    start_step : int
        First control sample of the excitation, >= 0.
    control_period_s : float
        ``T``, s, > 0.
    phases : str
        Multisine phases: ``schroeder`` or ``random``.
    seed : int
        Seed of the random phases, >= 0.
    """

    signal: str = "multisine"
    amplitude_Nm: float
    min_frequency_hz: float
    max_frequency_hz: float
    period_samples: int
    periods: int = 4
    settle_periods: int = 1
    start_step: int = 0
    control_period_s: float
    phases: str = "schroeder"
    seed: int = 0

    def __post_init__(self) -> None:
        if self.signal not in SIGNALS:
            raise ConfigError(f"signal: expected one of {list(SIGNALS)}, got {self.signal!r}")
        if self.phases not in PHASES:
            raise ConfigError(f"phases: expected one of {list(PHASES)}, got {self.phases!r}")
        require_positive("amplitude_Nm", self.amplitude_Nm)
        require_positive("control_period_s", self.control_period_s)
        require_positive("min_frequency_hz", self.min_frequency_hz)
        nyquist = 0.5 / self.control_period_s
        if not self.min_frequency_hz < self.max_frequency_hz < nyquist:
            raise ConfigError(
                "max_frequency_hz: expected min_frequency_hz < max_frequency_hz < "
                f"{nyquist:g} Hz (the Nyquist frequency), got {self.min_frequency_hz!r} .. "
                f"{self.max_frequency_hz!r}"
            )
        for name, low in (("period_samples", 8), ("periods", 1), ("settle_periods", 0)):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < low:
                raise ConfigError(f"{name}: expected an integer >= {low}, got {value!r}")
        if not isinstance(self.start_step, int) or self.start_step < 0:
            raise ConfigError(f"start_step: expected an integer >= 0, got {self.start_step!r}")
        require_nonnegative("seed", self.seed)
        if self.lines.size == 0:
            raise ConfigError(
                f"period_samples: expected a period whose lines 1/(N T) = "
                f"{self.resolution_hz:g} Hz apart fall into {self.min_frequency_hz:g} .. "
                f"{self.max_frequency_hz:g} Hz, got N = {self.period_samples}"
            )

    @property
    def resolution_hz(self) -> float:
        """Line spacing ``1 / (N T)``, Hz."""
        return 1.0 / (self.period_samples * self.control_period_s)

    @property
    def lines(self) -> NDArray[np.int64]:
        """DFT lines ``m`` (``f = m / (N T)``) of the band, ascending."""
        df = self.resolution_hz
        first = max(1, math.ceil(self.min_frequency_hz / df - 1e-9))
        last = min(math.floor(self.max_frequency_hz / df + 1e-9), (self.period_samples - 1) // 2)
        return np.arange(first, last + 1, dtype=np.int64)

    @property
    def frequency_hz(self) -> NDArray[np.float64]:
        """The band's line frequencies, Hz."""
        return np.asarray(self.lines * self.resolution_hz, dtype=np.float64)

    @property
    def window(self) -> tuple[int, int]:
        """``(first, stop)``: the control samples of the averaged periods."""
        first = self.start_step + self.settle_periods * self.period_samples
        return first, first + self.periods * self.period_samples

    @property
    def stop_step(self) -> int:
        """The first sample after the excitation."""
        return self.window[1]

    def one_period(self) -> NDArray[np.float64]:
        """One period of the signal (``N`` samples), peak ``amplitude_Nm``, N m."""
        n = self.period_samples
        k = np.arange(n)
        lines = self.lines
        if self.signal == "multisine":
            rank = np.arange(lines.size)
            if self.phases == "schroeder":
                phi = -math.pi * rank * (rank + 1) / lines.size
            else:
                phi = np.random.default_rng(self.seed).uniform(0.0, 2.0 * math.pi, lines.size)
            x = np.cos(2.0 * math.pi * np.outer(k, lines) / n + phi).sum(axis=1)
        elif self.signal == "chirp":
            m0, m1 = int(lines[0]), int(lines[-1])
            if (m0 + m1) % 2:
                m1 = m1 - 1 if m1 - 1 > m0 else m1 + 1
            x = np.cos(2.0 * math.pi * (m0 * k / n + 0.5 * (m1 - m0) * (k / n) ** 2))
        else:
            clock_hz = 2.5 * self.max_frequency_hz
            hold = max(1, int(1.0 / (clock_hz * self.control_period_s)))
            bits = -(-n // hold)
            order = max(2, math.ceil(math.log2(bits + 1)))
            # Imported here: scipy.signal costs the runner and the feedforward node ~1 s
            # at start-up, and only a prbs needs it.
            from scipy.signal import max_len_seq

            seq = max_len_seq(order)[0][:bits].astype(float) * 2.0 - 1.0
            x = np.repeat(seq, hold)[:n]
            x = x - x.mean()
        return np.asarray(self.amplitude_Nm * x / np.max(np.abs(x)), dtype=np.float64)

    def torque_Nm(self, steps: ArrayLike) -> NDArray[np.float64]:
        """The excitation at control samples ``steps``, N m (0 outside the excitation)."""
        k = np.asarray(steps, dtype=np.int64) - self.start_step
        period = self.one_period()
        on = (k >= 0) & (k < self.stop_step - self.start_step)
        return np.where(on, period[np.mod(k, self.period_samples)], 0.0)
