"""Conditional recursive least squares with projection (paper 003, eqs. (5), (6), (16)).

The regression is ``u[k] = phi[k]^T theta`` with ``n`` parameters (for the
tilting axis ``theta = [J, D, U]``, ``phi = [y'', y', sin y]``, eq. (4)).

Per-parameter forgetting (Table I gives a factor per parameter)
---------------------------------------------------------------
Eq. (5) has one forgetting factor ``lambda``. With a factor ``lambda_i`` per
parameter the covariance is realised as *vector (directional) forgetting*:
before the update, each parameter's row and column of ``P`` is inflated by
``1 / sqrt(lambda_i)``, then the ordinary ``lambda = 1`` update is applied::

    Pbar = Lambda^{-1/2} P[k-1] Lambda^{-1/2},     Lambda = diag(lambda_i)
    L[k] = Pbar phi / (1 + phi^T Pbar phi)
    P[k] = (I - L[k] phi^T) Pbar

i.e. the variance of parameter ``i`` is inflated by ``1 / lambda_i`` per
update (its information is discounted by ``lambda_i``,
an exponential memory of ``1 / (1 - lambda_i)`` updates for that parameter)
and keeps ``P`` symmetric positive definite. With all ``lambda_i = lambda``,
``Pbar = P / lambda`` and the three lines are exactly eq. (5):
``L = P phi / (lambda + phi^T P phi)`` and ``P[k] = (I - L phi^T) P / lambda``.
(Inflating *after* the update instead, ``Lambda^{-1/2} (I - L phi^T) P
Lambda^{-1/2}`` with ``L = P phi / (1 + phi^T P phi)``, is the same recursion
shifted by half a step: it equals eq. (5) only when started from
``P[0] / lambda``; inflating first matches eq. (5) from the same ``P[0]``.)

Conditional update (eq. (16))
-----------------------------
``update(phi, u, enabled)`` updates only the enabled parameters ``e``: the
disabled ones ``d`` keep their value, their contribution is moved to the
left side, ``u - phi_d^T theta_d = phi_e^T theta_e``, and the update above
runs on the sub-vector ``theta_e`` with the block ``P_ee`` (forgetting only
the enabled parameters). The disabled block ``P_dd`` is kept. The cross block
is propagated with the same linear map as the enabled errors,
``P_ed <- (I - L phi_e^T) Lambda_e^{-1/2} P_ed``: then
``P[k] = T Pbar T^T + diag(L L^T, 0)`` with ``T = diag(I - L phi_e^T, I)``
invertible, so ``P`` stays positive definite. (Keeping ``P_ed`` unchanged
while ``P_ee`` shrinks can make ``P`` indefinite and ``1 + phi^T P phi``
vanish; with every parameter enabled the two coincide.) If none is enabled,
nothing changes (no forgetting either: eq. (5)'s "otherwise P[k] = P[k-1]").

Projection (eq. (6))
--------------------
Per component, an increment that would put the parameter at or beyond its
upper bound while being >= 0 (or at or below its lower bound while <= 0) is
set to 0, exactly as eq. (6). Started inside ``[lower, upper]`` (checked),
eq. (6) alone keeps the estimate inside; the result is also clipped to the
bounds as a guard against rounding. The covariance update is not projected.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_positive

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _float_tuple(name: str, value: ArrayLike) -> tuple[float, ...]:
    a = np.atleast_1d(np.asarray(value, dtype=float))
    if a.ndim != 1 or a.size == 0:
        raise ConfigError(f"{name}: expected a non-empty 1-D array of numbers, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{name}: expected finite numbers, got {value!r}")
    return tuple(float(v) for v in a)


@dataclass(frozen=True, kw_only=True)
class RlsParams:
    """Parameters of :class:`ConditionalRls` for ``n`` parameters.

    Parameters
    ----------
    initial : array, shape (n,)
        ``theta[0]``, in the parameters' units (e.g. kg m^2, N m s/rad, N m).
    lower, upper : array, shape (n,)
        ``theta_min``, ``theta_max`` of eq. (6); ``lower < upper`` and
        ``lower <= initial <= upper`` per component.
    forgetting : array, shape (n,)
        ``lambda_i`` in (0, 1] per parameter (Table I: 0.999, 0.999, 0.995).
    initial_covariance : float
        ``p0 > 0``: ``P[0] = p0 I``.
    names : tuple of str, length n
        Parameter names, e.g. ``("J", "D", "U")``; used in messages and state.

    Notes
    -----
    Array fields are stored as tuples of float.
    """

    initial: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    forgetting: tuple[float, ...]
    initial_covariance: float
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        initial = _float_tuple("initial", self.initial)
        n = len(initial)
        fields = {"initial": initial}
        for key in ("lower", "upper", "forgetting"):
            v = _float_tuple(key, getattr(self, key))
            if len(v) != n:
                raise ConfigError(f"{key}: expected {n} values (as initial), got {len(v)}")
            fields[key] = v
        names = tuple(self.names) if not isinstance(self.names, str) else (self.names,)
        if len(names) != n or not all(isinstance(s, str) and s for s in names):
            raise ConfigError(f"names: expected {n} non-empty strings, got {self.names!r}")
        if len(set(names)) != n:
            raise ConfigError(f"names: expected distinct names, got {self.names!r}")
        lo, hi, lam = fields["lower"], fields["upper"], fields["forgetting"]
        for i, name in enumerate(names):
            if not lo[i] < hi[i]:
                raise ConfigError(
                    f"lower, upper: expected lower < upper for {name}, got {lo[i]!r} >= {hi[i]!r}"
                )
            if not lo[i] <= initial[i] <= hi[i]:
                raise ConfigError(
                    f"initial: expected lower <= initial <= upper for {name}, got {initial[i]!r} "
                    f"outside [{lo[i]!r}, {hi[i]!r}]"
                )
            if not 0.0 < lam[i] <= 1.0:
                raise ConfigError(
                    f"forgetting: expected a value in (0, 1] for {name}, got {lam[i]!r}"
                )
        p0 = require_positive("initial_covariance", self.initial_covariance)
        for key, v in fields.items():
            object.__setattr__(self, key, v)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "initial_covariance", p0)

    @property
    def n(self) -> int:
        """Number of parameters."""
        return len(self.initial)


def _vector(name: str, value: ArrayLike, n: int) -> FloatArray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SignalError(f"{name}: expected {n} numbers, got {value!r}") from exc
    if a.shape != (n,):
        raise SignalError(f"{name}: expected shape ({n},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SignalError(f"{name}: expected finite values, got {a.tolist()!r}")
    return a


class ConditionalRls:
    """Conditional RLS of eq. (5) with projection eq. (6) and per-parameter forgetting.

    Parameters
    ----------
    params : RlsParams
        Initial estimate, bounds, forgetting factors, ``p0`` and names.
    """

    def __init__(self, params: RlsParams) -> None:
        self.params = params
        self._lower = np.array(params.lower)
        self._upper = np.array(params.upper)
        self._inv_sqrt_lambda = 1.0 / np.sqrt(np.array(params.forgetting))
        from servo_axis.core.identification.online.dlpid_kernels import conditional_rls_update

        self._kernel = conditional_rls_update
        self.reset()
        # Load the compiled step now (from numba's disk cache), not at the first update.
        n = params.n
        self._kernel(
            self._theta.copy(),
            self._p.copy(),
            self._inv_sqrt_lambda,
            self._lower,
            self._upper,
            self.updates.copy(),
            np.zeros(n),
            0.0,
            np.ones(n, dtype=bool),
        )

    def reset(self) -> None:
        """Back to ``theta[0]``, ``P[0] = p0 I`` and no update."""
        n = self.params.n
        self._theta = np.array(self.params.initial)
        self._p = self.params.initial_covariance * np.eye(n)
        self.updates = np.zeros(n, dtype=np.int64)

    @property
    def n(self) -> int:
        """Number of parameters."""
        return self.params.n

    @property
    def theta(self) -> FloatArray:
        """Current estimate ``theta[k]`` (copy)."""
        return self._theta.copy()

    @property
    def covariance(self) -> FloatArray:
        """Current ``P[k]`` (copy)."""
        return self._p.copy()

    def predict(self, phi: ArrayLike) -> float:
        """``phi^T theta[k]`` (e.g. ``u_RLS`` of eq. (8))."""
        return float(_vector("phi", phi, self.n) @ self._theta)

    def update(self, phi: ArrayLike, u: float, enabled: ArrayLike | None = None) -> BoolArray:
        """One step of eq. (5)-(6) on the enabled parameters.

        Parameters
        ----------
        phi : array, shape (n,)
            Regressor ``phi[k]``.
        u : float
            Left side ``u[k]`` (``u_lower`` of eq. (4)).
        enabled : array of bool, shape (n,), optional
            Which parameters may be updated (eq. (16)); all if omitted.

        Returns
        -------
        ndarray of bool, shape (n,)
            The parameters whose estimate and covariance were updated (the
            enabled ones; all False if none is). A projected component
            counts as updated (its increment was zeroed by eq. (6), its
            covariance updated).
        """
        n = self.n
        phi_a = _vector("phi", phi, n)
        try:
            u_f = float(u)
        except (TypeError, ValueError):
            u_f = math.nan
        if not math.isfinite(u_f):
            raise SignalError(f"u: expected a finite number, got {u!r}")
        if enabled is None:
            mask = np.ones(n, dtype=bool)
        else:
            m = np.asarray(enabled)
            if m.shape != (n,) or m.dtype != np.bool_:
                raise SignalError(f"enabled: expected {n} booleans, got {enabled!r}")
            mask = m.copy()
        if not mask.any():
            return mask
        self._step(phi_a, u_f, mask)
        return mask

    def update_checked(self, phi: FloatArray, u: float, enabled: BoolArray) -> BoolArray:
        """:meth:`update` for a caller that built its arguments itself (no checks).

        ``phi``: float64 array of shape (n,), finite; ``u``: a finite float;
        ``enabled``: bool array of shape (n,), not kept. The per-sample
        path of :class:`~servo_axis.core.identification.online.dlpid.Dlpid`.
        """
        if enabled.any():
            self._step(phi, u, enabled)
        return enabled

    def predict_checked(self, phi: FloatArray) -> float:
        """:meth:`predict` of a finite float64 ``phi`` of shape (n,) (no checks)."""
        return float(phi @ self._theta)

    def _step(self, phi: FloatArray, u: float, mask: BoolArray) -> None:
        """Eqs. (5), (6), (16) on checked values (finite ``phi``, ``u``; a mask with one True).

        The vector-forgetting update, the increment and the projection of
        the module docstring, compiled
        (:func:`~servo_axis.core.identification.online.dlpid_kernels.conditional_rls_update`):
        ``theta``, ``P`` and the update counts change in place.
        """
        self._kernel(
            self._theta,
            self._p,
            self._inv_sqrt_lambda,
            self._lower,
            self._upper,
            self.updates,
            phi,
            u,
            mask,
        )

    def state(self) -> dict[str, Any]:
        """Estimate, covariance and update counts (exact float text), keyed by name order."""
        return {
            "names": list(self.params.names),
            "theta": self._theta.tolist(),
            "covariance": self._p.tolist(),
            "updates": [int(v) for v in self.updates],
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong name, length or value)."""
        n = self.n
        names = state.get("names")
        if names != list(self.params.names):
            raise SignalError(f"names: expected {list(self.params.names)!r}, got {names!r}")
        theta = _vector("theta", _as_list("theta", state.get("theta")), n)
        if np.any(theta < self._lower) or np.any(theta > self._upper):
            raise SignalError(f"theta: expected values inside the bounds, got {theta.tolist()!r}")
        cov_raw = _as_list("covariance", state.get("covariance"))
        try:
            cov = np.asarray(cov_raw, dtype=float)
        except (TypeError, ValueError) as exc:
            raise SignalError("covariance: expected an n x n list of numbers") from exc
        if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
            raise SignalError(f"covariance: expected a finite {n} x {n} matrix")
        if not np.array_equal(cov, cov.T) or np.linalg.eigvalsh(cov)[0] <= 0.0:
            raise SignalError("covariance: expected a symmetric positive definite matrix")
        updates = _as_list("updates", state.get("updates"))
        if len(updates) != n or not all(
            isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in updates
        ):
            raise SignalError(f"updates: expected {n} integers >= 0, got {updates!r}")
        self._theta = theta.copy()
        self._p = cov
        self.updates = np.array(updates, dtype=np.int64)


def _as_list(name: str, value: Any) -> Sequence[Any]:
    if not isinstance(value, list):
        raise SignalError(f"{name}: expected a list, got {type(value).__name__}")
    return value
