"""Reference trajectories at the table: position, velocity, acceleration.

All in SI at the table side (m, m/s, m/s^2); the axis divides by the lead
``R`` to get the motor angle. ``sample(t)`` takes an array of times (s).
"""

from __future__ import annotations

import itertools
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


@dataclass(frozen=True, kw_only=True)
class TrialReference:
    """Trials of an out-and-back move, one trajectory per stretch of trials (paper 001).

    Iterative learning control (001 Sect. III) repeats a trial: a trajectory
    of ``N`` samples that starts and ends at rest at the same position. Trial
    ``j`` (1-based) covers ``[(j - 1) T, j T)`` with ``T = trial_s``; it runs
    trajectory ``m``, the last one whose ``first_trials[m] <= j``, so that the
    reference can change at a given trial (001 Fig. 9a: Ref. 1 for trials
    1-5, Ref. 2 from trial 6).

    Trajectory ``m`` rests at ``offset_m`` until ``start_times_s[m]``, then
    moves out and back in ``move_times_s[m]``:
    ``x = offset + A sin^4(pi u)``, ``u = (tau - t_0) / T_m`` in ``[0, 1]``,
    and rests again until the end of the trial. ``sin^4`` starts and ends
    with zero velocity, acceleration and jerk, and reverses the velocity at
    ``u = 1/2`` (at ``offset + A``), away from the trial's ends; the stretches
    around it more than 100 um from a reversal are what the weighting of 001
    eq. (27) keeps when ``|A|`` is well above 100 um.

    Parameters
    ----------
    trial_s : float
        ``T``, length of a trial, s, > 0.
    amplitudes_m : sequence of float
        ``A`` of each trajectory, m, non-zero (either sign).
    move_times_s : sequence of float
        ``T_m`` of each trajectory, s, > 0.
    start_times_s : sequence of float
        ``t_0`` of each trajectory, s, >= 0, with ``t_0 + T_m < T`` (a rest
        at both ends of every trial).
    first_trials : sequence of int
        The trial each trajectory starts at: 1 first, strictly increasing.
    offset_m : float
        Position at rest, m.
    """

    trial_s: float
    amplitudes_m: tuple[float, ...]
    move_times_s: tuple[float, ...]
    start_times_s: tuple[float, ...]
    first_trials: tuple[int, ...]
    offset_m: float = 0.0

    def __post_init__(self) -> None:
        require_positive("trial_s", self.trial_s)
        require_finite("offset_m", self.offset_m)
        fields = {
            "amplitudes_m": self.amplitudes_m,
            "move_times_s": self.move_times_s,
            "start_times_s": self.start_times_s,
            "first_trials": self.first_trials,
        }
        count = len(self.amplitudes_m)
        for name, values in fields.items():
            object.__setattr__(self, name, tuple(values))
            if len(values) != count or count == 0:
                raise ConfigError(
                    f"{name}: expected one value per trajectory ({max(count, 1)}), got {list(values)!r}"
                )
        for a in self.amplitudes_m:
            if require_finite("amplitudes_m", a) == 0.0:
                raise ConfigError("amplitudes_m: expected non-zero amplitudes, got 0.0")
        for t_move, t_0 in zip(self.move_times_s, self.start_times_s, strict=True):
            require_positive("move_times_s", t_move)
            require_nonnegative("start_times_s", t_0)
            if not t_0 + t_move < self.trial_s:
                raise ConfigError(
                    f"move_times_s: a trajectory must start and end at rest within the trial: "
                    f"start {t_0!r} s + move {t_move!r} s is not below trial_s = {self.trial_s!r} s"
                )
        firsts = self.first_trials
        if (
            any(isinstance(f, bool) or not isinstance(f, int) for f in firsts)
            or firsts[0] != 1
            or any(b <= a for a, b in itertools.pairwise(firsts))
        ):
            raise ConfigError(
                f"first_trials: expected whole numbers starting at 1, strictly increasing, got {list(firsts)!r}"
            )

    @property
    def period_s(self) -> float | None:
        """None: the reference repeats per trial only while the trajectory stays the same."""
        return None

    def trajectory_of(self, trial: int) -> int:
        """Index of the trajectory trial ``trial`` (1-based) runs."""
        if trial < 1:
            raise ConfigError(f"trial: expected a trial number >= 1, got {trial!r}")
        return max(m for m, first in enumerate(self.first_trials) if first <= trial)

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        trial = np.floor(t / self.trial_s).astype(np.int64) + 1
        tau = t - (trial - 1) * self.trial_s
        index = np.zeros(t.shape, dtype=np.int64)
        for m, first in enumerate(self.first_trials):
            index[trial >= first] = m
        amp = np.asarray(self.amplitudes_m)[index]
        move = np.asarray(self.move_times_s)[index]
        u = (tau - np.asarray(self.start_times_s)[index]) / move
        moving = (u > 0.0) & (u < 1.0)
        # Exactly 0 at rest (sin(pi) is not): a velocity of 0 means rest.
        s = np.where(moving, np.sin(np.pi * u), 0.0)
        c = np.cos(np.pi * u)
        w = np.pi / move
        return (
            self.offset_m + amp * s**4,
            4.0 * amp * w * s**3 * c,
            4.0 * amp * w * w * s**2 * (3.0 * c * c - s * s),
        )


@dataclass(frozen=True, kw_only=True)
class SegmentsReference:
    """Half-cosine moves one after the other, each from rest to rest (paper 004 Fig. 11).

    Move ``i`` covers ``d_i`` in ``T_i``: ``x = x_i + d_i (1 - cos(pi tau / T_i)) / 2``,
    ``tau`` the time into it, so its velocity is zero at both ends and its
    deceleration into the stop is ``|d_i| (pi / T_i)^2 / 2`` (the
    25 (1 - cos 2 pi t) mm of 004 Sect. V is moves of +-50 mm in 0.5 s, at
    ``100 pi^2`` mm/s^2). Two moves of opposite sign meet at a reversal, two of
    the same sign at a stop without one (a non-reversal motion); the motion
    starts after ``delay_s`` at rest and stays at the end.

    Parameters
    ----------
    distances_m : tuple of float
        ``d_i``, m, each finite and non-zero (at least one).
    durations_s : tuple of float
        ``T_i``, s, each > 0, one per move.
    delay_s : float
        Rest before the first move, s, >= 0.
    offset_m : float
        Start position, m.
    """

    distances_m: tuple[float, ...]
    durations_s: tuple[float, ...]
    delay_s: float = 0.0
    offset_m: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "distances_m", tuple(float(d) for d in self.distances_m))
        object.__setattr__(self, "durations_s", tuple(float(t) for t in self.durations_s))
        if not self.distances_m or len(self.distances_m) != len(self.durations_s):
            raise ConfigError(
                "durations_s: expected one duration per distance (at least one move), got "
                f"{len(self.durations_s)} for {len(self.distances_m)}"
            )
        for i, (d, t) in enumerate(zip(self.distances_m, self.durations_s, strict=True)):
            if require_finite(f"distances_m[{i}]", d) == 0.0:
                raise ConfigError(f"distances_m[{i}]: expected a non-zero distance, got 0.0")
            require_positive(f"durations_s[{i}]", t)
        require_nonnegative("delay_s", self.delay_s)
        require_finite("offset_m", self.offset_m)

    @property
    def period_s(self) -> None:
        """None: not periodic."""
        return None

    def sample(self, t_s: ArrayLike) -> Arrays:
        t = np.asarray(t_s, dtype=float)
        pos = np.full(t.shape, self.offset_m)
        vel = np.zeros(t.shape)
        acc = np.zeros(t.shape)
        start = self.delay_s
        for d, big_t in zip(self.distances_m, self.durations_s, strict=True):
            tau = t - start
            w = math.pi / big_t
            inside = (tau >= 0.0) & (tau < big_t)
            phase = w * np.clip(tau, 0.0, big_t)
            pos += np.where(tau >= 0.0, 0.5 * d * (1.0 - np.cos(phase)), 0.0)
            vel += np.where(inside, 0.5 * d * w * np.sin(phase), 0.0)
            acc += np.where(inside, 0.5 * d * w * w * np.cos(phase), 0.0)
            start += big_t
        return pos, vel, acc


#: Reference kinds by name, for parameter files.
KINDS: dict[str, Any] = {
    "sine": SineReference,
    "one_minus_cos": OneMinusCosReference,
    "point_to_point": PointToPointReference,
    "trials": TrialReference,
    "segments": SegmentsReference,
}


def make_reference(kind: str, **params: Any) -> Reference:
    """Build a reference by name (``sine``, ``one_minus_cos``, ``point_to_point``, ``trials``, ``segments``).

    Raises
    ------
    ConfigError
        Naming ``kind`` for an unknown kind, or the offending field.
    """
    if kind not in KINDS:
        raise ConfigError(f"kind: expected one of {sorted(KINDS)}, got {kind!r}")
    ref: Reference = KINDS[kind](**params)
    return ref


class GridSamples:
    """A reference's samples on a control grid ``k T``, computed a chunk at a time.

    ``reference.sample(k * T)`` for integer ``k`` is computed element by
    element (every reference here is a function of each time alone), so the
    sample at ``k`` is the same number whether it is computed alone, in a
    block of 10 or in a chunk of :data:`CHUNK`: the same times ``k * T``
    (an int64 times a float, as the callers form them) through the same
    operations. This keeps the samples of the chunks that the callers are in
    (the last two) and computes the next when asked, so that the short
    blocks of the adaptive feedforward (one per online estimate, 003) do not
    each evaluate the reference anew.

    Parameters
    ----------
    reference : Reference
        The trajectory.
    period_s : float
        ``T``, the grid's period, s, > 0.
    chunk : int
        Grid samples computed at a time, >= 1.
    """

    CHUNK = 2048

    def __init__(self, reference: Reference, period_s: float, chunk: int = CHUNK) -> None:
        self.reference = reference
        self._period = require_positive("period_s", period_s)
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
            raise ConfigError(f"chunk: expected an integer >= 1, got {chunk!r}")
        self._chunk = chunk
        self._start = 0
        self._values = np.zeros((3, 0))

    def _cover(self, first: int, last: int) -> None:
        """Make the kept samples cover steps ``first .. last`` (inclusive)."""
        start, values = self._start, self._values
        if start <= first and last < start + values.shape[1]:
            return
        c = self._chunk
        lo = (first // c) * c
        hi = (last // c + 1) * c
        if start <= lo < start + values.shape[1]:
            # Keep what is computed from lo on, add the chunks after it.
            have = start + values.shape[1]
            new = self._sample(have, hi)
            self._values = np.concatenate((values[:, lo - start :], new), axis=1)
        else:
            self._values = self._sample(lo, hi)
        self._start = lo

    def _sample(self, lo: int, hi: int) -> NDArray[np.float64]:
        t = np.arange(lo, hi) * self._period
        return np.vstack([np.broadcast_to(a, t.shape) for a in self.reference.sample(t)])

    def kept(self, first: int, last: int) -> tuple[int, NDArray[np.float64]]:
        """``(start, values)``: the kept samples, covering steps ``first .. last`` (``0 <= first``).

        ``values[:, k - start]`` is position, velocity and acceleration at
        step ``k``; the array is replaced, never changed, when other chunks
        are computed (a caller may key what it derives from it on its identity).
        """
        self._cover(first, last)
        return self._start, self._values

    def steps(self, k: NDArray[np.int64]) -> Arrays:
        """Position, velocity and acceleration at the grid steps ``k`` (fresh arrays)."""
        k = np.asarray(k, dtype=np.int64)
        if k.size == 0:
            return self.reference.sample(k * self._period)
        first, last = int(k.min()), int(k.max())
        if first < 0:
            return self.reference.sample(k * self._period)
        self._cover(first, last)
        rows = self._values[:, k - self._start]
        return rows[0], rows[1], rows[2]

    def range(self, k0: int, k1: int, stride: int = 1) -> Arrays:
        """The samples at ``k0, k0 + stride, ... < k1`` (fresh arrays), ``0 <= k0 < k1``."""
        if k0 < 0 or k1 <= k0:
            return self.reference.sample(np.arange(k0, k1, stride) * self._period)
        self._cover(k0, k1 - 1)
        rows = self._values[:, k0 - self._start : k1 - self._start : stride].copy()
        return rows[0], rows[1], rows[2]
