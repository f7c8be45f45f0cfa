"""Multirate perfect tracking control (PTC) for the nominal ball-screw model.

Paper 000 Sect. III-A and Fig. 5, after Fujimoto's PTC [16]: the plant
``P_n = K_T / (J s^2 + D s)`` (eq. (1)) has state ``x = [theta, omega]``
(rad, rad/s). With ``(A_d, B_d)`` its zero-order-hold discretisation at the
control period ``T_u`` and the reference period ``T_r = 2 T_u`` (two inputs
per reference sample, as many as states), the state advances over ``T_r`` as
``x[i+1] = A x[i] + B [u[2i], u[2i+1]]^T`` with ``A = A_d^2`` and
``B = [A_d B_d, B_d]``. The feedforward

    ``[u[2i], u[2i+1]]^T = B^-1 (x_d[i+1] - A x_d[i])``

makes the nominal state equal the target ``x_d`` at every reference instant
(docs/design.md section 1). The nominal output between them is the feedback reference.

The nominal model can be replaced from a given reference instant on
(:meth:`MultiratePtc.replace_model`): the adaptive PTC of paper 003 eq. (11)
recomputes ``A`` and ``B`` from identified ``J``, ``D``; each instant uses
the model in force at it, so the result does not depend on how the
instants are grouped into calls.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import (
    ConfigError,
    SignalError,
    require_nonnegative,
    require_positive,
)


@dataclass(frozen=True)
class PtcOutput:
    """Feedforward and nominal trajectory at the control samples ``0 .. 2M-1``.

    Attributes
    ----------
    current_A : ndarray, shape (2M,)
        Feedforward current ``u[k]``, A.
    position_rad, velocity_rad_s : ndarray, shape (2M,)
        Nominal motor angle (rad) and velocity (rad/s) at sample ``k``.
    """

    current_A: NDArray[np.float64]
    position_rad: NDArray[np.float64]
    velocity_rad_s: NDArray[np.float64]


class _Model(NamedTuple):
    """``(A_d, B_d)`` at ``T_u`` and ``A = A_d^2``, ``B^-1`` over ``T_r``, from one instant on.

    A named tuple, not a frozen dataclass: one is made per online estimate (003 eq. (11)).
    """

    from_instant: int
    ad: NDArray[np.float64]
    bd: NDArray[np.float64]
    a_matrix: NDArray[np.float64]
    b_matrix: NDArray[np.float64]
    b_inv: NDArray[np.float64]


def _discretise(
    from_instant: int,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    kt: float,
    tu: float,
    products: Callable[..., tuple[Any, Any, Any, Any]] | None = None,
) -> _Model:
    """The model of ``J``, ``D``, ``K_T`` at ``T_u`` from ``from_instant`` (ZOH through ``expm``).

    ``products``: :func:`~servo_axis.core.feedforward.ptc_kernels.ptc_model`,
    which takes ``A_d``, ``B_d`` and the products from the exponential in one
    compiled call (the same numbers, ``A_d`` and ``B_d`` as contiguous
    copies), or None for numpy.
    """
    j = require_positive("inertia_kgm2", inertia_kgm2)
    d = require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad)
    kt = require_positive("torque_constant_Nm_per_A", kt)
    m = np.zeros((3, 3))
    m[0, 1] = 1.0
    m[1, 1] = -d / j
    m[1, 2] = kt / j
    e = _expm_upper(m * tu)
    if products is not None:
        ad, bd, a_matrix, b_matrix = products(e)
        return _Model(from_instant, ad, bd, a_matrix, b_matrix, _inv2(b_matrix))
    ad, bd = e[:2, :2], e[:2, 2]
    b_matrix = np.empty((2, 2))
    b_matrix[:, 0] = ad @ bd
    b_matrix[:, 1] = bd
    return _Model(from_instant, ad, bd, ad @ ad, b_matrix, _inv2(b_matrix))


def _inv2(b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.linalg.inv(b)`` of a float64 2 x 2 ``b``: the same call of numpy's own routine.

    ``np.linalg.inv`` checks and converts its argument, then calls its gufunc
    ``_umath_linalg.inv`` (LAPACK ``gesv`` on the identity) under an error
    state that raises ``LinAlgError`` for a singular matrix. For a float64
    2 x 2 array the checks pass and the conversions do nothing, so this calls
    the gufunc under that error state directly (a third of the time; one
    call per online estimate). Without those numpy internals it is
    ``np.linalg.inv``.
    """
    if _linalg is None:  # pragma: no cover - another numpy
        return cast("NDArray[np.float64]", np.linalg.inv(b))
    gufunc, raise_singular = _linalg
    with np.errstate(
        call=raise_singular, invalid="call", over="ignore", divide="ignore", under="ignore"
    ):
        return cast("NDArray[np.float64]", gufunc(b, signature="d->d"))


def _linalg_routines() -> tuple[Any, Any] | None:
    """numpy's ``inv`` gufunc and its singular-matrix error handler, or None without them."""
    try:
        from numpy.linalg import _umath_linalg
        from numpy.linalg._linalg import (  # type: ignore[attr-defined]
            _raise_linalgerror_singular,
        )
    except ImportError:  # pragma: no cover - another numpy
        return None
    return _umath_linalg.inv, _raise_linalgerror_singular


_linalg = _linalg_routines()


def _expm_upper(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``scipy.linalg.expm(a)`` of an upper triangular, non-diagonal 3 x 3 ``a``: the same numbers.

    The adaptive PTC (003 eq. (11)) discretises a new model for every
    estimate; ``scipy.linalg.expm``'s general wrapper (batch loop, band
    test, ``np.triu``) costs several times its Pade core. For the one case
    used here, a single upper triangular matrix with a non-zero entry above
    the diagonal whose norm needs no scaling (``s = 0``), this runs the
    steps ``expm`` runs: the same Pade structure and ``U``/``V`` solve of
    scipy's own routines, then the part below the diagonal set to 0 (what
    ``np.triu`` does there). Any other case (scaling needed, or scipy
    without those routines) is ``scipy.linalg.expm`` itself.
    """
    pade = _pade_routines()
    if pade is None:
        return _scipy_expm(a)
    pick_pade_structure, pade_uv_calc = pade
    work = np.empty((5, 3, 3))
    work[0] = a
    order, scaling = pick_pade_structure(work)
    if order < 0 or scaling != 0 or pade_uv_calc(work, order) != 0:
        return _scipy_expm(a)
    e: NDArray[np.float64] = work[0].copy()
    e[1, 0] = e[2, 0] = e[2, 1] = 0.0
    return e


def _scipy_expm(a: NDArray[np.float64]) -> NDArray[np.float64]:
    import scipy.linalg

    return np.asarray(scipy.linalg.expm(a), dtype=float)


# Looked up on first use, not at import: scipy.linalg costs every node that
# imports the factories (the recorder too) ~0.3 s at start-up.
@functools.cache
def _pade_routines() -> tuple[Any, Any] | None:
    """scipy's Pade routines behind ``expm`` (scipy >= 1.9), or None without them."""
    try:
        from scipy.linalg._matfuncs_expm import pade_UV_calc, pick_pade_structure
    except ImportError:  # pragma: no cover - another scipy
        return None
    return pick_pade_structure, pade_UV_calc


class MultiratePtc:
    """Multirate PTC feedforward with ``T_r = 2 T_u``.

    Parameters
    ----------
    inertia_kgm2, damping_Nms_per_rad, torque_constant_Nm_per_A : float
        Nominal model of eq. (1), in force from instant 0.
    control_period_s : float
        ``T_u``, s, > 0.
    ratio : int
        ``T_r / T_u``; must be 2 (the plant order) for a square ``B``.
    compiled : bool
        Compute :meth:`feedforward` with the compiled
        :func:`~servo_axis.core.feedforward.ptc_kernels.ptc_segment` (the same
        numbers): for the adaptive feedforward, which computes a short block
        per online estimate. It loads numba when the PTC is built.
    """

    def __init__(
        self,
        *,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
        control_period_s: float,
        ratio: int = 2,
        compiled: bool = False,
    ) -> None:
        self._tu = require_positive("control_period_s", control_period_s)
        if ratio != 2:
            raise ConfigError(
                f"ratio: expected 2 (T_r = 2 T_u for the order-2 plant), got {ratio!r}"
            )
        self._segment: Callable[..., None] | None = None
        self._products: Callable[..., tuple[Any, Any, Any, Any]] | None = None
        if compiled:
            from servo_axis.core.feedforward.ptc_kernels import ptc_model, ptc_segment

            self._segment, self._products = ptc_segment, ptc_model
        self._models = [
            _discretise(
                0,
                inertia_kgm2,
                damping_Nms_per_rad,
                torque_constant_Nm_per_A,
                self._tu,
                self._products,
            )
        ]

    @property
    def ad(self) -> NDArray[np.float64]:
        """``A_d`` of the first model."""
        return self._models[0].ad

    @property
    def bd(self) -> NDArray[np.float64]:
        """``B_d`` of the first model."""
        return self._models[0].bd

    @property
    def a_matrix(self) -> NDArray[np.float64]:
        """``A = A_d^2`` of the first model."""
        return self._models[0].a_matrix

    @property
    def b_matrix(self) -> NDArray[np.float64]:
        """``B = [A_d B_d, B_d]`` of the first model."""
        return self._models[0].b_matrix

    def replace_model(
        self,
        *,
        from_instant: int,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
    ) -> None:
        """Use another nominal model from reference instant ``from_instant`` on (003 eq. (11)).

        Raises
        ------
        ConfigError
            If ``from_instant`` is not after the instant of the last model
            set (models are replaced forwards in time only), or a model
            value is invalid.
        """
        last = self._models[-1].from_instant
        if (
            isinstance(from_instant, bool)
            or not isinstance(from_instant, int)
            or from_instant <= last
        ):
            raise ConfigError(
                f"from_instant: expected an integer after {last} (the last model's), "
                f"got {from_instant!r}"
            )
        self._models.append(
            _discretise(
                from_instant,
                inertia_kgm2,
                damping_Nms_per_rad,
                torque_constant_Nm_per_A,
                self._tu,
                self._products,
            )
        )

    def forget_before(self, instant: int) -> None:
        """Drop the models no instant from ``instant`` on uses (keeps the one in force)."""
        while len(self._models) > 1 and self._models[1].from_instant <= instant:
            self._models.pop(0)

    def feedforward(self, x_d: NDArray[np.float64], first_instant: int = 0) -> PtcOutput:
        """Feedforward for the target states ``x_d`` at reference instants ``i0 .. i0 + M``.

        Parameters
        ----------
        x_d : ndarray, shape (M+1, 2)
            Target ``[theta (rad), omega (rad/s)]`` at ``i T_r``.
        first_instant : int
            ``i0``, the instant of ``x_d[0]`` (it selects the model in force).

        Returns
        -------
        PtcOutput
            For control samples ``2 i0 .. 2 (i0 + M) - 1``.
        """
        x = np.asarray(x_d, dtype=float)
        if x.ndim != 2 or x.shape[1] != 2 or x.shape[0] < 2:
            raise SignalError(f"x_d: expected shape (M+1, 2) with M >= 1, got {x.shape}")
        if not np.isfinite(x).all():
            raise SignalError("x_d: expected finite values")
        m = x.shape[0] - 1
        if self._segment is not None:
            return self._compiled_feedforward(x, first_instant, m)
        u = np.empty((m, 2))  # rows [u[2i], u[2i+1]]
        mid = np.empty((m, 2))  # nominal state at 2i+1
        for lo, hi, model in self._segments(first_instant, m):
            xs = x[lo : hi + 1]
            u[lo:hi] = (xs[1:] - xs[:-1] @ model.a_matrix.T) @ model.b_inv.T
            # u[2i] B_d as a column times a row: np.outer's products, without its call.
            mid[lo:hi] = xs[:-1] @ model.ad.T + u[lo:hi, 0:1] * model.bd
        current = u.reshape(2 * m)
        pos = np.empty(2 * m)
        vel = np.empty(2 * m)
        pos[0::2], vel[0::2] = x[:-1, 0], x[:-1, 1]
        pos[1::2], vel[1::2] = mid[:, 0], mid[:, 1]
        return PtcOutput(current_A=current, position_rad=pos, velocity_rad_s=vel)

    def _compiled_feedforward(
        self, x: NDArray[np.float64], first_instant: int, m: int
    ) -> PtcOutput:
        """:meth:`feedforward` of checked targets, a compiled call per model (the same numbers)."""
        segment = self._segment
        assert segment is not None
        x = np.ascontiguousarray(x)
        current = np.empty(2 * m)
        pos = np.empty(2 * m)
        vel = np.empty(2 * m)
        for lo, hi, model in self._segments(first_instant, m):
            # The models of a compiled PTC are ptc_model's: contiguous arrays.
            segment(x, lo, hi, model.a_matrix, model.b_inv, model.ad, model.bd, current, pos, vel)
        return PtcOutput(current_A=current, position_rad=pos, velocity_rad_s=vel)

    def _segments(self, first: int, m: int) -> list[tuple[int, int, _Model]]:
        """Row ranges ``[lo, hi)`` of ``0 .. m`` with the model in force at each."""
        out = []
        for n, model in enumerate(self._models):
            until = self._models[n + 1].from_instant if n + 1 < len(self._models) else None
            lo = max(model.from_instant - first, 0)
            hi = m if until is None else min(until - first, m)
            if lo < hi:
                out.append((lo, hi, model))
        return out
