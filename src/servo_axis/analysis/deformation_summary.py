"""The deformation ratio of a run at the stops of its reference (paper 004, ``deformation``).

A run whose bag has the ``deformation`` topic (the feedback's
``deformation.enabled``) gets a ``deformation`` block (:class:`Deformation`):
the deformation ratio ``d_r`` of paper 004 eq. (7) just before each stop of
the reference, where 004 Fig. 11 compares slow and fast, reversing and
non-reversing stops (:func:`reference_stops`, :func:`deformation_summary`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from servo_axis.analysis.bag_streams import table_name
from servo_axis.analysis.serial import Serial
from servo_axis.analysis.signals import Signals
from servo_axis.core.deformation import DeformationTrace
from servo_axis.params.factories import build_reference
from servo_axis.params.resolve import Resolved

#: The windows of :class:`DeformationWindow`, s relative to the stop: well
#: before it, where a fast stop's ``d_r`` still has its value of the
#: deceleration, and its last 15 ms, where 004 Fig. 11 shows it move (fast
#: stops) or stay (slow ones).
DEFORMATION_WINDOWS_S: tuple[tuple[float, float], ...] = ((-0.100, -0.050), (-0.015, 0.0))

#: Kinds of :class:`ReferenceStop`: the motion after it has the other sign,
#: the same sign, or there is none in the run.
STOP_KINDS: tuple[str, ...] = ("reversal", "non_reversal", "final")

#: A reference sample is at rest when ``|v| <= REST_TOLERANCE * max |v|``:
#: the segments' boundaries sample their velocity as a rounding of 0 (about
#: 1e-19 m/s), far below any moving sample (one sample from a slow stop of
#: ``deformation_cases``: 2.5e-6 m/s, 1.6e-5 of the peak speed).
REST_TOLERANCE = 1e-9


@dataclass(frozen=True)
class ReferenceStop(Serial):
    """An instant where the reference velocity reaches 0 after moving.

    Attributes
    ----------
    time_s : float
        When, s: the first sample at rest (or where the motion came to rest
        before it); or, between two samples, where the velocity is 0 by
        linear interpolation (a sign change) or by extrapolation with the
        acceleration (a speed minimum, see :func:`reference_stops`).
    kind : str
        ``reversal`` (the motion after has the other sign), ``non_reversal``
        (the same sign) or ``final`` (no motion after, in the run).
    deceleration_m_s2 : float
        ``|a|`` of the reference at the last sample before ``time_s``, m/s^2
        (rad/s^2 for a rotary table): for a half-cosine move of ``d`` in
        ``T``, ``|d| (pi / T)^2 cos(pi T_u / T) / 2``.
    """

    time_s: float
    kind: str
    deceleration_m_s2: float


def reference_stops(
    time_s: NDArray[np.float64],
    velocity: NDArray[np.float64],
    acceleration: NDArray[np.float64],
    *,
    rest_tolerance: float = REST_TOLERANCE,
) -> tuple[ReferenceStop, ...]:
    """Every stop of a sampled reference, in order (004 Fig. 11: where ``d_r`` is compared).

    A sample moves when ``|v| > rest_tolerance * max |v|``. A stop is

    * the first sample at rest after a moving one (a segments reference
      whose moves meet on the sample grid; the end of the motion), or
      before it, at ``t + |v / a|`` of the last moving sample when it
      decelerates and that is earlier (the motion ended off the grid);
    * a sign change between two moving samples (a sine; moves meeting off
      the grid with opposite signs), at the linear zero of ``v``;
    * a moving sample whose speed is a local minimum no larger than one
      sample of its acceleration, ``|v| <= T_u |a|``, with both neighbours
      moving the same way (moves meeting off the grid with the same sign),
      at ``t - v / a``. A smooth slow-down has ``a`` near 0 at its speed
      minimum and is no stop.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s, ascending and evenly spaced (``T_u``).
    velocity, acceleration : ndarray, shape (n,)
        The reference's velocity (m/s) and acceleration (m/s^2) at them.
    rest_tolerance : float
        The rest threshold relative to the peak speed.

    Returns
    -------
    tuple of ReferenceStop
        In time order; empty without motion.
    """
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(velocity, dtype=float)
    a = np.asarray(acceleration, dtype=float)
    n = t.size
    if n < 2 or not np.any(v):
        return ()
    dt = float(t[1] - t[0])
    moving = np.abs(v) > rest_tolerance * float(np.max(np.abs(v)))
    sign = np.sign(v) * moving
    # (time, index of the first sample after it, sign of the motion into it)
    found: list[tuple[float, int, float]] = []
    for k in range(1, n):
        if not moving[k]:
            if moving[k - 1]:
                # Came to rest between the samples when the last moving one,
                # decelerating, would reach 0 within the step.
                slowing = v[k - 1] * a[k - 1] < 0.0
                reach = abs(v[k - 1] / a[k - 1]) if slowing else math.inf
                found.append((min(float(t[k]), float(t[k - 1] + reach)), k, sign[k - 1]))
            continue
        if not moving[k - 1]:
            continue
        if sign[k] != sign[k - 1]:
            t0 = float(t[k - 1]) + dt * float(v[k - 1] / (v[k - 1] - v[k]))
            found.append((t0, k, sign[k - 1]))
        elif (
            k + 1 < n
            and moving[k + 1]
            and sign[k + 1] == sign[k]
            and abs(v[k]) <= abs(v[k - 1])
            and abs(v[k]) < abs(v[k + 1])
            and abs(v[k]) <= dt * abs(a[k])
        ):
            t0 = float(t[k] - v[k] / a[k])
            found.append((t0, k if t0 <= t[k] else k + 1, sign[k]))
    stops = []
    for t0, after, before in found:
        ahead = np.flatnonzero(moving[after:])
        kind = (
            "final"
            if ahead.size == 0
            else ("non_reversal" if sign[after + ahead[0]] == before else "reversal")
        )
        # The last sample strictly before the stop: its deceleration, not
        # the next move's acceleration at the boundary itself.
        last = int(np.searchsorted(t, t0 - 1e-6 * dt, side="right")) - 1
        decel = abs(float(a[last])) if last >= 0 else math.nan
        stops.append(ReferenceStop(time_s=t0, kind=kind, deceleration_m_s2=decel))
    return tuple(stops)


@dataclass(frozen=True)
class DeformationWindow(Serial):
    """``d_r`` over the valid samples of one window before a stop.

    Attributes
    ----------
    start_s, end_s : float
        The window, s relative to the stop, ends included.
    valid_samples : int
        Samples in it whose ``d_r`` is valid.
    mean_d_r_m_per_rad : float or None
        Their mean ``d_r``, m/rad; None (``null``) without a valid sample.
    """

    start_s: float
    end_s: float
    valid_samples: int
    mean_d_r_m_per_rad: float | None


@dataclass(frozen=True)
class DeformationStop(Serial):
    """A stop of the reference and ``d_r`` just before it (one panel of 004 Fig. 11).

    Attributes
    ----------
    time_s, kind, deceleration_m_s2
        As in :class:`ReferenceStop`.
    windows : tuple of DeformationWindow
        One per :data:`DEFORMATION_WINDOWS_S`, in that order.
    """

    time_s: float
    kind: str
    deceleration_m_s2: float
    windows: tuple[DeformationWindow, ...]


@dataclass(frozen=True)
class Deformation(Serial):
    """The deformation ratio of a run (paper 004 Sect. III-C, topic ``deformation``).

    Attributes
    ----------
    window_samples : int
        ``p`` of eq. (6), samples (the feedback's ``deformation.window_samples``).
    min_rotation_rad : float
        Smallest ``|theta_m[k] - theta_m[k-p]|`` with a valid ``d_r``, rad
        (``deformation.min_rotation_rad``).
    samples : int
        Recorded steps with a validated ``deformation`` message.
    valid_samples : int
        Those with a valid ``d_r``.
    dropped : int
        ``deformation`` messages dropped as junk.
    stops : tuple of DeformationStop
        Every stop of the reference (:func:`reference_stops`), in time order.
    """

    window_samples: int
    min_rotation_rad: float
    samples: int
    valid_samples: int
    dropped: int
    stops: tuple[DeformationStop, ...]


def window_mask(
    time_s: NDArray[np.float64], t_stop: float, start_s: float, end_s: float, period_s: float
) -> NDArray[np.bool_]:
    """Samples at ``t_stop + start_s <= t <= t_stop + end_s`` (a millionth of ``T_u`` of slack).

    The slack keeps a window's ends on the sample grid inside it despite the
    rounding of ``step * T_u``.
    """
    slack = 1e-6 * period_s
    t = np.asarray(time_s, dtype=float)
    mask: NDArray[np.bool_] = (t >= t_stop + start_s - slack) & (t <= t_stop + end_s + slack)
    return mask


def deformation_windows(
    time_s: NDArray[np.float64],
    trace: DeformationTrace,
    t_stop: float,
    *,
    period_s: float,
    windows_s: tuple[tuple[float, float], ...] = DEFORMATION_WINDOWS_S,
) -> tuple[DeformationWindow, ...]:
    """Mean ``d_r`` (m/rad) over the valid samples of each window before ``t_stop``.

    Parameters
    ----------
    time_s : ndarray
        Time of each sample of ``trace``, s.
    trace : DeformationTrace
        ``d_r`` and its validity per sample.
    t_stop : float
        The stop, s.
    period_s : float
        ``T_u``, s.
    windows_s : tuple of (float, float)
        The windows, s relative to ``t_stop``.
    """
    out = []
    for start, end in windows_s:
        inside = window_mask(time_s, t_stop, start, end, period_s) & trace.valid
        n = int(np.count_nonzero(inside))
        mean = float(np.mean(trace.d_r_m_per_rad[inside])) if n else None
        out.append(
            DeformationWindow(start_s=start, end_s=end, valid_samples=n, mean_d_r_m_per_rad=mean)
        )
    return tuple(out)


def deformation_summary(
    scenario: Resolved | dict[str, Any], scenario_path: Path, sig: Signals
) -> Deformation | None:
    """The :class:`Deformation` block of a run whose bag has the ``deformation`` topic, else None.

    The stops are those of the run's reference trajectory (the scenario's
    ``reference.*``, table side: what the feedforward generator is built
    from) sampled at the recorded steps: exact zeros of the velocity where
    moves meet, and the acceleration of the move into each stop.
    """
    trace = sig.deformation
    if trace is None:
        return None
    resolved = Resolved.of(scenario, scenario_path)
    period = resolved.plant.control_period_s
    fb = resolved.feedback
    t = cast(NDArray[np.float64], sig.step * period)
    _, vel, acc = build_reference(resolved.feedforward).sample(t)
    stops = tuple(
        DeformationStop(
            time_s=s.time_s,
            kind=s.kind,
            deceleration_m_s2=s.deceleration_m_s2,
            windows=deformation_windows(t, trace, s.time_s, period_s=period),
        )
        for s in reference_stops(t, vel, acc)
    )
    topics = [name for name in sig.counts if table_name(name) == "deformation"]
    return Deformation(
        window_samples=int(fb.deformation.window_samples),
        min_rotation_rad=float(fb.deformation.min_rotation_rad),
        samples=int(np.count_nonzero(~np.isnan(trace.scale_increment_m))),
        valid_samples=int(np.count_nonzero(trace.valid)),
        dropped=sum(sig.dropped.get(name, 0) for name in topics),
        stops=stops,
    )
