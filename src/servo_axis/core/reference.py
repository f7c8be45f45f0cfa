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
    """``x = offset + A sin(2 pi f t + phase)``.

    Parameters
    ----------
    amplitude_m : float
        ``A``, m, >= 0 (the 10 mm of paper 000 Fig. 18 is 0.01).
    frequency_hz : float
        ``f``, Hz, > 0.
    offset_m, phase_rad : float
        Offset (m) and phase at t = 0 (rad).
    """

    amplitude_m: float
    frequency_hz: float
    offset_m: float = 0.0
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative("amplitude_m", self.amplitude_m)
        require_positive("frequency_hz", self.frequency_hz)
        require_finite("offset_m", self.offset_m)
        require_finite("phase_rad", self.phase_rad)

    @property
    def period_s(self) -> float:
        """``1 / f``, s."""
        return 1.0 / self.frequency_hz

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        w = 2.0 * math.pi * self.frequency_hz
        arg = w * t + self.phase_rad
        a = self.amplitude_m
        return self.offset_m + a * np.sin(arg), a * w * np.cos(arg), -a * w * w * np.sin(arg)


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
