"""The fit of a GMS model to a slow reversal (paper 004 Fig. 4(b)): :func:`fit_gms`.

The ``gms-fit`` command (``servo_axis.identify.gms_fit``) reads a run and calls it;
here only the numbers. Nothing here reads a file, a clock or a logger.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from servo_axis.core.errors import ConfigError, SignalError, require_positive
from servo_axis.core.friction.gms_model import simulate_gms
from servo_axis.core.friction.gms_params import MAX_ELEMENTS, FloatArray, GmsParams

#: A fit simulates at most this many samples per evaluation (longer paths are subsampled)...
MAX_FIT_SAMPLES = 5000
#: ... and at most this many element-samples, but never fewer than 1000 samples: the cost
#: of one evaluation and the number of them both grow with the elements (20 elements on
#: 1000 samples take about 5 s, 4 elements on 5000 samples below 1 s).
FIT_ELEMENT_SAMPLES = 20000

_MIN_SAMPLES = 8


@dataclass(frozen=True)
class GmsFit:
    """A GMS model fitted to a slow reversal (:func:`fit_gms`).

    Attributes
    ----------
    params : GmsParams
        The fitted model, elements in order of increasing break-away
        displacement ``alpha_i F_c / k_i``.
    rms_residual_Nm : float
        RMS of measured minus model torque over the samples from the first
        reversal on, at the full rate, N m.
    model_torque_Nm : ndarray
        The fitted model's torque along the whole given path (from the
        virgin state at its first sample), N m.
    """

    params: GmsParams
    rms_residual_Nm: float
    model_torque_Nm: FloatArray


def _signal(name: str, value: ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SignalError(f"{name}: expected a 1-D array of numbers") from None
    if arr.ndim != 1:
        raise SignalError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SignalError(f"{name}: expected finite values, got NaN or inf")
    return arr


def _directions(velocity: FloatArray) -> NDArray[np.int64]:
    """The direction of motion per sample, a zero velocity taking the last non-zero sign."""
    sign = np.sign(velocity).astype(np.int64)
    moving = np.flatnonzero(sign)
    if moving.size == 0:
        return sign
    # Forward-fill the zeros with the previous sign (the leading ones with the first).
    last = np.maximum.accumulate(np.where(sign != 0, np.arange(sign.size), -1))
    last[last < 0] = moving[0]
    return sign[last]


def _initial_guess(
    position: FloatArray,
    torque: FloatArray,
    direction: NDArray[np.int64],
    reversals: NDArray[np.int64],
    elements: int,
) -> tuple[float, list[float], list[float]]:
    """``(F_c, k_i, alpha_i)`` to start from, read off the data.

    The sliding level is first taken roughly from the far half of each
    branch, the pre-sliding distance ``x_s`` as the median over the branches
    of the displacement where the signed torque first reaches 90 % of it;
    then ``F_c`` is the median ``|torque|`` beyond ``3 x_s`` and the
    elements share it equally with break-away points spread evenly over
    ``(0, x_s / 2]`` (a reversal sweeps twice the virgin curve's range).
    """
    n = position.size
    first = int(reversals[0])
    anchor = np.empty(n)
    bounds = [*reversals.tolist(), n]
    for start, stop in itertools.pairwise(bounds):
        anchor[start:stop] = position[start - 1]
    d = np.abs(position[first:] - anchor[first:])
    y = direction[first:] * torque[first:]
    far = d >= 0.5 * float(d.max())
    rough = float(np.median(y[far]))
    if not rough > 0.0:
        raise SignalError(
            "torque_Nm: the torque does not follow the direction of motion in sliding "
            f"(median signed level {rough!r} N m); expected the torque that overcomes friction"
        )
    reach: list[float] = []
    for start, stop in itertools.pairwise(bounds):
        hit = np.flatnonzero(y[start - first : stop - first] >= 0.9 * rough)
        if hit.size:
            reach.append(float(d[start - first + hit[0]]))
    x_s = float(np.median(reach)) if reach else 0.5 * float(d.max())
    if not x_s > 0.0:
        x_s = 0.5 * float(d.max())
    sliding = d > 3.0 * x_s
    fc = float(np.median(np.abs(torque[first:][sliding]))) if sliding.any() else rough
    weights = [1.0 / elements] * elements
    breakaway = [0.5 * x_s * (i + 1) / elements for i in range(elements)]
    stiffness = [a * fc / b for a, b in zip(weights, breakaway, strict=True)]
    return fc, stiffness, weights


def fit_gms(
    position_m: ArrayLike,
    torque_Nm: ArrayLike,
    *,
    elements: int,
    period_s: float,
    initial: GmsParams | None = None,
) -> GmsFit:
    """Fit ``k_i``, ``alpha_i`` and ``F_c`` of a GMS model to a slow reversal (paper 004 Fig. 4(b)).

    The model is simulated along the measured position path (velocity
    ``np.gradient(position, period)``) from the virgin state, and the
    squared torque residual is minimised with
    :func:`scipy.optimize.least_squares` over ``log k_i``, ``log F_c`` and
    the weights as a softmax of ``N - 1`` free logits. Only the samples
    from the first reversal on count: the model starts virgin, the axis in
    an unknown state, and the sliding before a reversal wipes out that
    difference (every element slips) provided the motion before the first
    reversal exceeds the pre-sliding distance. Paths longer than
    :data:`MAX_FIT_SAMPLES` (fewer with many elements,
    :data:`FIT_ELEMENT_SAMPLES`) are subsampled for the search, so that a
    fit takes at most a few seconds (stick increments add up exactly, so
    the quasi-static model is the same at the samples kept); the residual
    reported is at the full rate. Deterministic: one start read off the
    data (see :func:`_initial_guess`), no restarts.

    ``F_s`` (kept equal to ``F_c``), ``V_s``, ``delta``, ``C`` and
    ``sigma_2`` are not fitted: a slow reversal never leaves the
    quasi-static regime, where the torque depends only on the displacement
    path, so they are not identifiable from it. They keep their defaults,
    or those of ``initial`` (``F_s`` then at the same ratio to ``F_c``).

    Parameters
    ----------
    position_m : array, shape (n,)
        Table position at each sample, m (the reference of an
        identification run: its sign changes mark the reversals, so it
        should be free of noise).
    torque_Nm : array, shape (n,)
        Friction torque estimate at each sample, N m, with the sign of the
        motion in sliding.
    elements : int
        Number of elements N, 1..20.
    period_s : float
        Sample period, s, > 0.
    initial : GmsParams or None
        Start of the search (N elements) instead of the one read off the data.

    Returns
    -------
    GmsFit

    Raises
    ------
    SignalError
        Arrays of different lengths, non-finite, too short, without motion
        or without a reversal (the argument named).
    ConfigError
        ``elements``, ``period_s`` or ``initial`` out of range.
    """
    pos, tq, period = _fit_arguments(position_m, torque_Nm, elements, period_s, initial)
    path = _fit_path(pos, period, elements)
    space = _search_space(pos, tq, path, elements, initial)
    p_sub, v_sub, t_sub = pos[path.kept], path.velocity[path.kept], tq[path.kept][path.counted]
    period_sub = period * path.stride

    def residual(x: FloatArray) -> FloatArray:
        model = simulate_gms(space.params_of(x), p_sub, v_sub, period_s=period_sub)
        return np.asarray(model[path.counted] - t_sub, dtype=float)

    solution = least_squares(
        residual,
        space.x0,
        bounds=(space.lower, space.upper),
        method="trf",
        x_scale="jac",
        max_nfev=200 * 2 * elements,
    )
    best = _in_breakaway_order(space.params_of(np.asarray(solution.x, dtype=float)))
    model = simulate_gms(best, pos, path.velocity, period_s=period)
    first = path.first
    rms = float(np.sqrt(np.mean((tq[first:] - model[first:]) ** 2)))
    return GmsFit(params=best, rms_residual_Nm=rms, model_torque_Nm=model)


def _fit_arguments(
    position_m: ArrayLike,
    torque_Nm: ArrayLike,
    elements: int,
    period_s: float,
    initial: GmsParams | None,
) -> tuple[FloatArray, FloatArray, float]:
    """The position (m), the torque (N m) and the period (s) of :func:`fit_gms`, checked."""
    pos = _signal("position_m", position_m)
    tq = _signal("torque_Nm", torque_Nm)
    if pos.size != tq.size:
        raise SignalError(
            f"position_m, torque_Nm: expected arrays of one length, got {pos.size} and {tq.size}"
        )
    if isinstance(elements, bool) or not isinstance(elements, int):
        raise ConfigError(f"elements: expected an integer, got {elements!r}")
    if not 1 <= elements <= MAX_ELEMENTS:
        raise ConfigError(f"elements: expected 1..{MAX_ELEMENTS}, got {elements!r}")
    period = require_positive("period_s", period_s)
    if initial is not None and initial.elements != elements:
        raise ConfigError(
            f"initial: expected {elements} elements (as elements), got {initial.elements}"
        )
    return pos, tq, period


@dataclass(frozen=True)
class _FitPath:
    """The measured path as the fit sees it.

    Attributes
    ----------
    velocity : ndarray
        ``np.gradient(position, period)``, m/s, every sample.
    direction : ndarray of int
        The direction of motion per sample (:func:`_directions`).
    reversals : ndarray of int
        The samples where the direction changes.
    first : int
        The first reversal: the samples from it on are the ones that count.
    stride : int
        The search simulates every ``stride``-th sample.
    kept : ndarray of int
        The samples the search simulates.
    counted : ndarray of bool
        Which of ``kept`` count (from the first reversal on).
    """

    velocity: FloatArray
    direction: NDArray[np.int64]
    reversals: NDArray[np.int64]
    first: int
    stride: int
    kept: NDArray[np.int64]
    counted: NDArray[np.bool_]


def _fit_path(pos: FloatArray, period: float, elements: int) -> _FitPath:
    """The path's reversals and the samples the search simulates; refuses a path too short."""
    n_free = 2 * elements
    if pos.size < _MIN_SAMPLES:
        raise SignalError(f"position_m: expected at least {_MIN_SAMPLES} samples, got {pos.size}")
    vel = np.gradient(pos, period)
    direction = _directions(vel)
    if not np.any(vel != 0.0):
        raise SignalError("position_m: expected motion, the position never changes")
    reversals = np.flatnonzero(direction[1:] != direction[:-1]) + 1
    if reversals.size == 0:
        raise SignalError("position_m: no reversal in the data (the motion never changes sign)")
    first = int(reversals[0])
    budget = min(MAX_FIT_SAMPLES, max(1000, FIT_ELEMENT_SAMPLES // elements))
    stride = max(1, math.ceil(pos.size / budget))
    kept = np.arange(0, pos.size, stride)
    counted = kept >= first
    if int(counted.sum()) < 4 * n_free:
        raise SignalError(
            f"position_m: too short after the first reversal (sample {first}): expected at "
            f"least {4 * n_free * stride} samples there for {elements} elements, "
            f"got {pos.size - first}"
        )
    return _FitPath(vel, direction, reversals, first, stride, kept, counted)


@dataclass(frozen=True)
class _SearchSpace:
    """The fit's unknowns ``x = [log k_i, N - 1 weight logits, log F_c]``: start, bounds, model.

    ``fixed`` holds what is not fitted (``V_s``, ``delta``, ``C``,
    ``sigma_2``); ``F_s`` is kept at ``fs_ratio`` times ``F_c``.
    """

    elements: int
    fixed: GmsParams
    fs_ratio: float
    x0: FloatArray
    lower: FloatArray
    upper: FloatArray

    def params_of(self, x: FloatArray) -> GmsParams:
        """The model of the unknowns ``x`` (the weights a softmax of the logits and 0)."""
        elements = self.elements
        k = np.exp(x[:elements])
        logits = np.concatenate((x[elements : 2 * elements - 1], [0.0]))
        e = np.exp(logits - logits.max())
        w = e / e.sum()
        fc = float(np.exp(x[-1]))
        fixed = self.fixed
        return GmsParams(
            stiffness_Nm_per_m=tuple(k.tolist()),
            weights=tuple(w.tolist()),
            coulomb_Nm=fc,
            static_Nm=self.fs_ratio * fc,
            stribeck_velocity_m_s=fixed.stribeck_velocity_m_s,
            stribeck_exponent=fixed.stribeck_exponent,
            attraction_per_s=fixed.attraction_per_s,
            viscous_Nms_per_m=fixed.viscous_Nms_per_m,
        )


def _search_space(
    pos: FloatArray,
    tq: FloatArray,
    path: _FitPath,
    elements: int,
    initial: GmsParams | None,
) -> _SearchSpace:
    """The start (``initial``, or read off the data) and the bounds of the search."""
    if initial is None:
        fc0, k0, w0 = _initial_guess(pos, tq, path.direction, path.reversals, elements)
        fixed = GmsParams(stiffness_Nm_per_m=(1.0,), weights=(1.0,), coulomb_Nm=1.0)
    else:
        fc0, k0, w0 = (
            initial.coulomb_Nm,
            list(initial.stiffness_Nm_per_m),
            list(initial.weights),
        )
        fixed = initial
    fs_ratio = (fixed.static_Nm or fixed.coulomb_Nm) / fixed.coulomb_Nm
    log_w0 = np.log(np.asarray(w0))
    x0 = np.concatenate((np.log(k0), log_w0[:-1] - log_w0[-1], [math.log(fc0)]))
    # Bounds keep every trial model valid (finite stiffness, weights > 0 after rounding).
    spread = np.concatenate((np.full(elements, 25.0), np.full(elements - 1, 30.0), [5.0]))
    lower = x0 - spread
    upper = x0 + spread
    lower[elements : 2 * elements - 1] = -30.0
    upper[elements : 2 * elements - 1] = 30.0
    x0 = np.clip(x0, lower + 1e-9, upper - 1e-9)
    return _SearchSpace(elements, fixed, fs_ratio, x0, lower, upper)


def _in_breakaway_order(params: GmsParams) -> GmsParams:
    """``params`` with its elements in order of increasing break-away displacement."""
    order = sorted(range(params.elements), key=lambda i: params.breakaway_m[i])
    return GmsParams(
        stiffness_Nm_per_m=tuple(params.stiffness_Nm_per_m[i] for i in order),
        weights=tuple(params.weights[i] for i in order),
        coulomb_Nm=params.coulomb_Nm,
        static_Nm=params.static_Nm,
        stribeck_velocity_m_s=params.stribeck_velocity_m_s,
        stribeck_exponent=params.stribeck_exponent,
        attraction_per_s=params.attraction_per_s,
        viscous_Nms_per_m=params.viscous_Nms_per_m,
    )
