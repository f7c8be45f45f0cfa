"""Reference trajectories at the table: position, velocity, acceleration.

All in SI at the table side (m, m/s, m/s^2); the axis divides by the lead
``R`` to get the motor angle. ``sample(t)`` takes an array of times (s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ConfigError, require_finite, require_nonnegative, require_positive

Arrays = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


class Reference(Protocol):
    """What the feedforward generator needs from a reference."""

    @property
    def period_s(self) -> float | None:
        """Period of the trajectory (s), or None if it is not periodic."""
        ...

    def sample(self, t_s: ArrayLike) -> Arrays:
        """Position (m), velocity (m/s) and acceleration (m/s^2) at times ``t_s`` (s)."""
        ...


@dataclass(frozen=True, kw_only=True)
class SineReference:
    """``x = offset + A sin(2 pi f s(t) + phase)``, ``s(t) = t`` unless ramped.

    With ``ramp_s = T > 0`` the phase speeds up smoothly from rest: the time
    warp ``s`` has ``s'(t) = 10 u^3 - 15 u^4 + 6 u^5`` (``u = t / T``), so
    ``s(t) = T (2.5 u^4 - 3 u^5 + u^6)`` for ``t < T`` and
    ``s(t) = t - T / 2`` after it: the speed of the phase goes from 0 to
    ``2 pi f`` with continuous acceleration and jerk, and the signal is
    periodic from ``T`` on. Two axes with the same ramp trace a circle that
    starts at rest, which a constant-speed circle cannot (000 Fig. 18
    starts at full speed and needs a very large input at t = 0).

    Parameters
    ----------
    amplitude_m : float
        ``A``, m, >= 0 (the 10 mm of paper 000 Fig. 18 is 0.01).
    frequency_hz : float
        ``f``, Hz, > 0.
    offset_m, phase_rad : float
        Offset (m) and phase at t = 0 (rad).
    ramp_s : float
        ``T``, s, >= 0 (0: no ramp).
    """

    amplitude_m: float
    frequency_hz: float
    offset_m: float = 0.0
    phase_rad: float = 0.0
    ramp_s: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative("amplitude_m", self.amplitude_m)
        require_positive("frequency_hz", self.frequency_hz)
        require_finite("offset_m", self.offset_m)
        require_finite("phase_rad", self.phase_rad)
        require_nonnegative("ramp_s", self.ramp_s)

    def _warp(self, t: np.ndarray) -> Arrays:
        """``s, s', s''`` of the ramp at ``t``."""
        if self.ramp_s == 0.0:
            return t, np.ones_like(t), np.zeros_like(t)
        big_t = self.ramp_s
        u = np.clip(t / big_t, 0.0, 1.0)
        ramping = t < big_t
        s = np.where(ramping, big_t * (2.5 * u**4 - 3 * u**5 + u**6), t - big_t / 2)
        ds = np.where(ramping, 10 * u**3 - 15 * u**4 + 6 * u**5, 1.0)
        dds = np.where(ramping, (30 * u**2 - 60 * u**3 + 30 * u**4) / big_t, 0.0)
        return s, ds, dds

    @property
    def period_s(self) -> float:
        """``1 / f``, s."""
        return 1.0 / self.frequency_hz

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        w = 2.0 * math.pi * self.frequency_hz
        s, ds, dds = self._warp(t)
        arg = w * s + self.phase_rad
        a = self.amplitude_m
        return (
            self.offset_m + a * np.sin(arg),
            a * w * ds * np.cos(arg),
            a * w * (dds * np.cos(arg) - w * ds * ds * np.sin(arg)),
        )


@dataclass(frozen=True, kw_only=True)
class OneMinusCosReference:
    """``x = A (1 - cos 2 pi f t)``: starts at rest (paper 004: 25 (1 - cos 2 pi t) mm).

    Parameters
    ----------
    amplitude_m : float
        ``A``, m, >= 0.
    frequency_hz : float
        ``f``, Hz, > 0.
    """

    amplitude_m: float
    frequency_hz: float

    def __post_init__(self) -> None:
        require_nonnegative("amplitude_m", self.amplitude_m)
        require_positive("frequency_hz", self.frequency_hz)

    @property
    def period_s(self) -> float:
        """``1 / f``, s."""
        return 1.0 / self.frequency_hz

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        w = 2.0 * math.pi * self.frequency_hz
        a = self.amplitude_m
        return a * (1.0 - np.cos(w * t)), a * w * np.sin(w * t), a * w * w * np.cos(w * t)


@dataclass(frozen=True, kw_only=True)
class PointToPointReference:
    """Minimum-jerk moves of ``distance_m`` in ``move_time_s``, with dwells.

    ``x = start + d (10 s^3 - 15 s^4 + 6 s^5)``, ``s = t / T``: zero velocity
    and acceleration at both ends. With ``back_and_forth`` the axis moves back
    after the dwell and the trajectory repeats every ``2 (T + dwell)``.

    Parameters
    ----------
    distance_m : float
        Move length ``d``, m (either sign, non-zero).
    move_time_s : float
        ``T``, s, > 0.
    dwell_s : float
        Standstill after each move, s, >= 0.
    start_m : float
        Start position, m.
    back_and_forth : bool
        Move back and repeat (True) or stay at the end (False).
    """

    distance_m: float
    move_time_s: float
    dwell_s: float = 0.0
    start_m: float = 0.0
    back_and_forth: bool = True

    def __post_init__(self) -> None:
        if require_finite("distance_m", self.distance_m) == 0.0:
            raise ConfigError("distance_m: expected a non-zero distance, got 0.0")
        require_positive("move_time_s", self.move_time_s)
        require_nonnegative("dwell_s", self.dwell_s)
        require_finite("start_m", self.start_m)

    @property
    def period_s(self) -> float | None:
        """``2 (T + dwell)`` when back and forth, else None."""
        return 2.0 * (self.move_time_s + self.dwell_s) if self.back_and_forth else None

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        T, d = self.move_time_s, self.distance_m
        leg = T + self.dwell_s
        if self.back_and_forth:
            tc = np.mod(t, 2.0 * leg)
            back = tc >= leg
            tau = np.where(back, tc - leg, tc)
        else:
            back = np.zeros(t.shape, dtype=bool)
            tau = t
        s = np.clip(tau / T, 0.0, 1.0)
        moving = (tau >= 0.0) & (tau < T)
        shape = 10 * s**3 - 15 * s**4 + 6 * s**5
        dshape = np.where(moving, (30 * s**2 - 60 * s**3 + 30 * s**4) / T, 0.0)
        ddshape = np.where(moving, (60 * s - 180 * s**2 + 120 * s**3) / T**2, 0.0)
        sign = np.where(back, -1.0, 1.0)
        pos = self.start_m + np.where(back, d * (1.0 - shape), d * shape)
        return pos, sign * d * dshape, sign * d * ddshape


#: Reference kinds by name, for parameter files.
KINDS: dict[str, Any] = {
    "sine": SineReference,
    "one_minus_cos": OneMinusCosReference,
    "point_to_point": PointToPointReference,
}


def make_reference(kind: str, **params: Any) -> Reference:
    """Build a reference by name (``sine``, ``one_minus_cos``, ``point_to_point``).

    Raises
    ------
    ConfigError
        Naming ``kind`` for an unknown kind, or the offending field.
    """
    if kind not in KINDS:
        raise ConfigError(f"kind: expected one of {sorted(KINDS)}, got {kind!r}")
    ref: Reference = KINDS[kind](**params)
    return ref
