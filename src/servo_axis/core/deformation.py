"""The deformation ratio of paper 004 Sect. III-C, eqs. (5)-(7).

The ratio of table motion to motor rotation,

    l_d = dx_t / dtheta_m ~ (x_t[k] - x_t[k-p]) / (theta_m[k] - theta_m[k-p]),   (5), (6)

equals the lead ``R`` of the screw for a rigid drive; its excess

    d_r = l_d - R                                                               (7)

(m/rad) shows the elastic deformation of the screw, nut and bearings, which
changes quickly near a reversal of a fast motion (004 Figs. 11-13).

``x_t`` is the linear scale (m), ``theta_m`` the motor encoder (rad). Near a
stop the increments are a few quantisation steps and the ratio is
meaningless (004: ``d_r`` "cannot be accurately calculated" there): where
``|theta_m[k] - theta_m[k-p]| < min_rotation_rad`` (or is 0), and for the
first ``p`` samples, ``d_r`` is reported as 0.0 and flagged invalid. With
quantisation steps ``q_x`` and ``q_theta``, a rigid drive gives
``|d_r| <= (q_x + R q_theta) / |theta_m[k] - theta_m[k-p]|``, which sets
``min_rotation_rad`` for a wanted resolution of ``d_r``.

:func:`deformation_ratio` works on whole records (reports);
:class:`DeformationRatio` streams one sample at a time and gives the same
floats bit for bit (the same operations in the same order).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_nonnegative, require_positive

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _check_settings(
    window_samples: int, lead_m_per_rad: float, min_rotation_rad: float
) -> tuple[int, float, float]:
    if (
        isinstance(window_samples, bool)
        or not isinstance(window_samples, int | np.integer)
        or window_samples < 1
    ):
        raise ConfigError(f"window_samples: expected an integer >= 1, got {window_samples!r}")
    lead = require_positive("lead_m_per_rad", lead_m_per_rad)
    min_rot = require_nonnegative("min_rotation_rad", min_rotation_rad)
    return int(window_samples), lead, min_rot


@dataclass(frozen=True)
class DeformationTrace:
    """Eqs. (6)-(7) at every sample of a record.

    Attributes
    ----------
    d_r_m_per_rad : ndarray of float
        ``d_r = dx / dtheta - R``, m/rad; 0.0 where not valid.
    scale_increment_m : ndarray of float
        ``dx = x_t[k] - x_t[k-p]``, m; 0.0 for ``k < p``.
    encoder_increment_rad : ndarray of float
        ``dtheta = theta_m[k] - theta_m[k-p]``, rad; 0.0 for ``k < p``.
    valid : ndarray of bool
        ``k >= p``, ``|dtheta| >= min_rotation_rad``, ``dtheta != 0`` and a
        finite ratio.
    """

    d_r_m_per_rad: FloatArray
    scale_increment_m: FloatArray
    encoder_increment_rad: FloatArray
    valid: BoolArray


@dataclass(frozen=True)
class DeformationSample:
    """Eqs. (6)-(7) at one sample (fields as in :class:`DeformationTrace`, scalars)."""

    d_r_m_per_rad: float
    scale_increment_m: float
    encoder_increment_rad: float
    valid: bool


def _reading_array(name: str, values: ArrayLike) -> FloatArray:
    a = np.asarray(values, dtype=float)
    if a.ndim != 1:
        raise SignalError(f"{name}: expected a 1-D array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.isfinite(a))[0])
        raise SignalError(f"{name}: expected finite readings, got {a[bad]!r} at sample {bad}")
    return a


def deformation_ratio(
    encoder_rad: ArrayLike,
    scale_m: ArrayLike,
    *,
    window_samples: int,
    lead_m_per_rad: float,
    min_rotation_rad: float,
) -> DeformationTrace:
    """The deformation ratio ``d_r`` of eqs. (6)-(7) over a record.

    Parameters
    ----------
    encoder_rad : array_like, shape (n,)
        Motor angle ``theta_m`` per sample, rad, finite.
    scale_m : array_like, shape (n,)
        Table position ``x_t`` per sample, m, finite.
    window_samples : int
        ``p`` of eq. (6), >= 1: the increments span ``p`` sampling periods.
    lead_m_per_rad : float
        ``R``, m/rad, > 0.
    min_rotation_rad : float
        Smallest ``|dtheta|`` (rad, >= 0) for which the ratio is computed.

    Returns
    -------
    DeformationTrace
        Per sample: ``d_r`` (m/rad), ``dx`` (m), ``dtheta`` (rad), ``valid``;
        never NaN or inf in ``d_r``.

    Raises
    ------
    ConfigError
        Naming ``window_samples``, ``lead_m_per_rad`` or ``min_rotation_rad``.
    SignalError
        Naming ``encoder_rad`` or ``scale_m`` for a non-finite reading, a
        non-1-D array, or lengths that differ.
    """
    p, lead, min_rot = _check_settings(window_samples, lead_m_per_rad, min_rotation_rad)
    theta = _reading_array("encoder_rad", encoder_rad)
    x = _reading_array("scale_m", scale_m)
    if theta.shape != x.shape:
        raise SignalError(
            f"encoder_rad, scale_m: expected the same length, got {theta.size} and {x.size}"
        )
    n = theta.size
    dx = np.zeros(n)
    dtheta = np.zeros(n)
    if n > p:
        dx[p:] = x[p:] - x[:-p]
        dtheta[p:] = theta[p:] - theta[:-p]
    valid = np.zeros(n, dtype=bool)
    valid[p:] = (np.abs(dtheta[p:]) >= min_rot) & (dtheta[p:] != 0.0)
    d_r = np.zeros(n)
    with np.errstate(over="ignore", invalid="ignore"):
        # Same operations as DeformationRatio.update: (dx / dtheta) - R.
        d_r[valid] = dx[valid] / dtheta[valid] - lead
    # An overflowing increment or ratio is as meaningless as a stop.
    finite = np.isfinite(d_r)
    valid &= finite
    d_r[~finite] = 0.0
    return DeformationTrace(
        d_r_m_per_rad=d_r, scale_increment_m=dx, encoder_increment_rad=dtheta, valid=valid
    )


class DeformationRatio:
    """Streaming ``d_r`` of eqs. (6)-(7): the same floats as :func:`deformation_ratio`.

    Parameters
    ----------
    window_samples : int
        ``p``, >= 1.
    lead_m_per_rad : float
        ``R``, m/rad, > 0.
    min_rotation_rad : float
        Smallest ``|dtheta|`` (rad, >= 0) for which the ratio is computed.

    Raises
    ------
    ConfigError
        Naming the argument out of range.
    """

    def __init__(
        self, *, window_samples: int, lead_m_per_rad: float, min_rotation_rad: float
    ) -> None:
        self.window_samples, self.lead_m_per_rad, self.min_rotation_rad = _check_settings(
            window_samples, lead_m_per_rad, min_rotation_rad
        )
        self._history: deque[tuple[float, float]] = deque(maxlen=self.window_samples + 1)

    def reset(self) -> None:
        """Forget every reading (the next ``p`` samples are invalid again)."""
        self._history.clear()

    def update(self, encoder_rad: float, scale_m: float) -> DeformationSample:
        """Take ``theta_m[k]`` (rad) and ``x_t[k]`` (m); return ``d_r`` at ``k``.

        Raises
        ------
        SignalError
            Naming ``encoder_rad`` or ``scale_m`` for a non-finite reading
            (the reading is not taken).
        """
        theta = float(encoder_rad)
        x = float(scale_m)
        for name, value in (("encoder_rad", theta), ("scale_m", x)):
            if not math.isfinite(value):
                raise SignalError(f"{name}: expected a finite reading, got {value!r}")
        self._history.append((theta, x))
        if len(self._history) <= self.window_samples:
            return DeformationSample(0.0, 0.0, 0.0, False)
        theta_old, x_old = self._history[0]
        dx = x - x_old
        dtheta = theta - theta_old
        if dtheta == 0.0 or abs(dtheta) < self.min_rotation_rad:
            return DeformationSample(0.0, dx, dtheta, False)
        d_r = dx / dtheta - self.lead_m_per_rad
        if not math.isfinite(d_r):
            return DeformationSample(0.0, dx, dtheta, False)
        return DeformationSample(d_r, dx, dtheta, True)
