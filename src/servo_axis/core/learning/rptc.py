"""Repetitive perfect tracking control: the periodic signal generator (paper 000).

Paper 000 (Fujimoto & Takemura), Sect. III-IV, Figs. 6, 10: a memory of
``Nd = Td / Tr`` reference samples accumulates the filtered tracking error
cycle by cycle, ``c_{j+1} = c_j + Q~n e_j`` (the learning term of eq. (9)
with the n-times filter of eq. (19), :mod:`.filters`), and a state-variable
generator gives position and central-difference velocity of the
correction, which is added to the next cycle's target trajectory
(``side = "target"``, ``period = "cycle"`` of :mod:`.base`).

One learning cycle is ``Nd`` reference samples (period ``Tr``). The error of
a cycle is periodic, so the non-causal filter is applied circularly over
the cycle: the samples before the start of the cycle are those at its end,
which the memory holds (the delay compensation of Fig. 6). With circular
filtering ``Q`` and ``Q~n`` are circulant and commute, which makes eq. (27)
hold exactly in the lifted model with ``Delta = 0``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_positive
from servo_axis.core.learning.filters import circular_filter, n_times_taps

FloatArray = NDArray[np.float64]


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


class PeriodicSignalGenerator:
    """The PSG of 000 Fig. 6 / Fig. 10: memory, learning filter, state-variable generator.

    Parameters
    ----------
    params : LearningParams
        ``Nd``, ``Nq``, ``n`` and ``Tr``.
    """

    name = "rptc"
    period = "cycle"
    side = "target"

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

    def learn(self, error: ArrayLike, *, period: int | None = None) -> FloatArray:
        """Learn one cycle's tracking error: ``c_{j+1} = c_j + Q~n e_j`` (eq. (9), (19)).

        Parameters
        ----------
        error : array, shape (Nd,)
            Tracking error ``r - y`` at the ``Nd`` reference samples of the
            cycle, in the unit of the correction (rad or m).
        period : int, optional
            The cycle's number; the correction carries over cycle to cycle,
            so it is not used.

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

    # -- LearningLaw ---------------------------------------------------------
    @property
    def samples_per_period(self) -> int:
        """``Nd``."""
        return self.params.samples_per_cycle

    @property
    def periods_learned(self) -> int:
        """Cycles learned so far."""
        return self.cycles_learned

    def next_correction(self, *, period: int | None = None) -> tuple[FloatArray, FloatArray]:
        """Position and velocity of the next cycle's correction (:meth:`states`), whatever ``period``."""
        return self.states()

    def identity(self) -> dict[str, Any]:
        """``Nd``, ``Nq``, ``n`` and ``Tr``: a memory of other values is not reused."""
        p = self.params
        return {
            "samples_per_cycle": p.samples_per_cycle,
            "nq": p.nq,
            "n": p.n,
            "period_s": p.period_s,
        }

    def state(self) -> dict[str, Any]:
        """The correction (exact float text) and the cycles learned."""
        return {"correction": self._correction.tolist(), "cycles_learned": self.cycles_learned}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong length or value)."""
        cycles = state.get("cycles_learned")
        if isinstance(cycles, bool) or not isinstance(cycles, int) or cycles < 0:
            raise SignalError(f"cycles_learned: expected an integer >= 0, got {cycles!r}")
        correction = state.get("correction")
        if not isinstance(correction, list):
            raise SignalError("correction: expected a list of numbers")
        self.load(correction, cycles)
