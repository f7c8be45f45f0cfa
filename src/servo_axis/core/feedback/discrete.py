"""Discrete filters: transposed direct form II and the Tustin (bilinear) discretisation.

Used by the PID and the disturbance observer (and any later filter of the
loop): one implementation of the per-sample update.
"""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.errors import ConfigError


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
        # In place (here and in set_state, settle): the feedback loop's fused
        # update (FeedbackLoop) holds the list itself.
        self._z[:] = [0.0] * len(self._z)

    @property
    def state(self) -> list[float]:
        """The internal state (a copy): ``order`` values, to persist and restore."""
        return list(self._z)

    def set_state(self, z: list[float]) -> None:
        """Restore a :attr:`state` (ConfigError on a wrong length)."""
        if len(z) != len(self._z):
            raise ConfigError(f"z: expected {len(self._z)} values, got {len(z)}")
        self._z[:] = [float(v) for v in z]

    def settle(self, x: float) -> None:
        """Set the state to the steady state for the input ``x`` held forever (DC gain b(1)/a(1))."""
        y = x * sum(self.b) / sum(self.a)
        n = len(self._z)
        self._z[:] = [
            math.fsum(self.b[j] * x - self.a[j] * y for j in range(i + 1, n + 1)) for i in range(n)
        ]

    @property
    def order(self) -> int:
        """The filter's order (the length of its state)."""
        return len(self._z)

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
