"""Persistent-excitation index over a moving window (paper 003, eq. (7)).

``M[k] = (1/W) sum phi[l] phi[l]^T`` over the last ``W`` regressors and
``kappa[k]`` its smallest eigenvalue; the regressor is persistently exciting
over the window when ``kappa > 0`` (003 Sect. III-B, ``W = 100``).

Eq. (7) writes the sum from ``l = k - W`` to ``k`` (``W + 1`` terms) over
``W``; here the window is the ``W`` latest samples ``k - W + 1 .. k`` so that
``M`` is their mean.

Cost: a ring buffer of the last ``W`` regressors and a running sum of their
outer products, ``O(n^2)`` per sample (plus ``eigvalsh`` of an ``n x n``
matrix, ``n = 3`` for the tilting axis). To stop rounding drift of the
running sum, it is recomputed from the buffer every ``W`` samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError

FloatArray = NDArray[np.float64]


class PeIndex:
    """Moving-window PE matrix ``M[k]`` and index ``kappa[k]`` of eq. (7).

    Parameters
    ----------
    n : int
        Regressor length, >= 1.
    window : int
        ``W``, samples, >= ``n`` (fewer than ``n`` outer products are always
        singular).

    Notes
    -----
    Until ``W`` samples are in, :attr:`kappa` is 0.0 (PE not yet verified)
    and :attr:`matrix` is the zero matrix; from the ``W``-th sample on they
    are those of the full window.
    """

    def __init__(self, n: int, window: int) -> None:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ConfigError(f"n: expected an integer >= 1, got {n!r}")
        if isinstance(window, bool) or not isinstance(window, int) or window < n:
            raise ConfigError(f"window: expected an integer >= n = {n}, got {window!r}")
        self.n = n
        self.window = window
        # The running sum's update, compiled (the same arithmetic as np.outer
        # and the elementwise -= / +=); numba loads only with a PE index.
        from servo_axis.core.identification.online.dlpid_kernels import outer_window_add

        self._add = outer_window_add
        self.reset()
        # Load the compiled step now (from numba's disk cache), not at the first
        # RLS step after the identifier's warm-up (a stall in a realtime node).
        outer_window_add(
            np.zeros((window, n)), np.zeros((n, n)), 0, np.zeros(n), False, window, True
        )

    def reset(self) -> None:
        """Empty the window."""
        self._buffer = np.zeros((self.window, self.n))
        self._sum = np.zeros((self.n, self.n))
        self._next = 0  # slot the next sample goes to
        self.count = 0  # samples seen (saturates nowhere: used for the recompute cadence)
        self._kappa = 0.0

    @property
    def full(self) -> bool:
        """True once ``W`` samples are in."""
        return self.count >= self.window

    @property
    def matrix(self) -> FloatArray:
        """``M[k]`` (zero until the window is full)."""
        if not self.full:
            return np.zeros((self.n, self.n))
        return self._sum / self.window

    @property
    def kappa(self) -> float:
        """``kappa[k]``, the smallest eigenvalue of ``M[k]`` (0.0 until the window is full)."""
        return self._kappa

    def update(self, phi: ArrayLike) -> float:
        """Add ``phi[k]`` (dropping the oldest once full) and return ``kappa[k]``."""
        try:
            v = np.asarray(phi, dtype=float)
        except (TypeError, ValueError) as exc:
            raise SignalError(f"phi: expected {self.n} numbers, got {phi!r}") from exc
        if v.shape != (self.n,):
            raise SignalError(f"phi: expected shape ({self.n},), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise SignalError(f"phi: expected finite values, got {v.tolist()!r}")
        return self.update_checked(v)

    def update_checked(self, v: FloatArray) -> float:
        """:meth:`update` of a finite float64 ``phi`` of shape (n,) (no checks; not kept)."""
        window = self.window
        count = self.count + 1
        recompute = count % window == 0
        # total -= outer(oldest), buffer[slot] = v, total += outer(v, v) and,
        # unless the sum is recomputed now, kappa: one compiled call.
        kappa = self._add(
            self._buffer,
            self._sum,
            self._next,
            v,
            self.full,
            window,
            count >= window and not recompute,
        )
        self._next = (self._next + 1) % window
        self.count = count
        if recompute:
            self._sum = self._buffer.T @ self._buffer
            self._kappa = float(_eigvalsh(self._sum / window)[0])
        elif count >= window:
            self._kappa = kappa
        return self._kappa

    def state(self) -> dict[str, Any]:
        """Buffer, running sum (kept so a resumed index is bit-identical), slot and count."""
        return {
            "buffer": self._buffer.tolist(),
            "sum": self._sum.tolist(),
            "next": self._next,
            "count": self.count,
            "kappa": self._kappa,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong shape or value)."""
        buffer = _matrix("buffer", state.get("buffer"), (self.window, self.n))
        total = _matrix("sum", state.get("sum"), (self.n, self.n))
        nxt, count = state.get("next"), state.get("count")
        for name, v, hi in (("next", nxt, self.window - 1), ("count", count, None)):
            if (
                isinstance(v, bool)
                or not isinstance(v, int)
                or v < 0
                or (hi is not None and v > hi)
            ):
                raise SignalError(f"{name}: expected an integer in range, got {v!r}")
        kappa = state.get("kappa")
        if isinstance(kappa, bool) or not isinstance(kappa, int | float):
            raise SignalError(f"kappa: expected a number, got {kappa!r}")
        assert isinstance(nxt, int) and isinstance(count, int)
        if nxt != count % self.window:
            raise SignalError(f"next: expected count % window = {count % self.window}, got {nxt}")
        self._buffer, self._sum = buffer, total
        self._next, self.count, self._kappa = nxt, count, float(kappa)


def _eigvalsh(a: FloatArray) -> FloatArray:
    """``np.linalg.eigvalsh(a)`` of a float64 square ``a``: the same call of numpy's own routine.

    ``np.linalg.eigvalsh`` checks and converts its argument, then calls its
    gufunc ``_umath_linalg.eigvalsh_lo`` (LAPACK ``syevd``) under an error
    state that raises ``LinAlgError`` when it does not converge; for a float64
    square array the checks pass and the conversions do nothing, so this
    calls the gufunc under that error state directly (once per RLS step).
    Without those numpy internals it is ``np.linalg.eigvalsh``.
    """
    if _linalg is None:  # pragma: no cover - another numpy
        return cast(FloatArray, np.linalg.eigvalsh(a))
    gufunc, raise_nonconvergence = _linalg
    with np.errstate(
        call=raise_nonconvergence, invalid="call", over="ignore", divide="ignore", under="ignore"
    ):
        result: FloatArray = gufunc(a, signature="d->d")
    return result


def _linalg_routines() -> tuple[Any, Any] | None:
    """numpy's ``eigvalsh`` gufunc and its error handler, or None without them."""
    try:
        from numpy.linalg import _umath_linalg
        from numpy.linalg._linalg import (  # type: ignore[attr-defined]
            _raise_linalgerror_eigenvalues_nonconvergence,
        )
    except ImportError:  # pragma: no cover - another numpy
        return None
    return _umath_linalg.eigvalsh_lo, _raise_linalgerror_eigenvalues_nonconvergence


_linalg = _linalg_routines()


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> FloatArray:
    if not isinstance(value, list):
        raise SignalError(f"{name}: expected a list of lists of numbers")
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"{name}: expected a list of lists of numbers") from exc
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise SignalError(f"{name}: expected a finite {shape[0]} x {shape[1]} matrix")
    return a
