"""The summary of a run (``summary.json``), typed.

:func:`summarise` computes a single-axis run's :class:`RunSummary` from its
bag and scenario and writes ``summary.json``; :func:`summarise_axes` does the
same for a multi-axis run (:class:`AxesSummary`: each axis and, for two axes,
the contour). ``to_json()`` writes the text layout the runs have always had
(``json.dumps(..., indent=2, allow_nan=True)``, same keys in the same order)
and ``from_json()`` / :func:`load_summary` read it back.

Every parameter (control period, lead, flags, names) is the checked value of
the scenario (:func:`servo_axis.params.resolve.node_values`), its default
where the scenario does not set it.

Units follow the plant model: the tracking error is the error of the table's
position, ``R (r - y)`` in m for a table that moves along a line (a ball
screw), ``r - y`` in rad for one that turns (a plant model whose registry
entry says ``rotary``: the tilting table of paper 003, whose position is its
angle); the keys keep
their ``_m`` names and a rotary run's summary says ``"error_unit": "rad"``.
The RMS over every sample of the run (``tracking_error.all_samples.rms_m``)
is the RMSD paper 003 compares (Figs. 7, 9).

A run whose bag has the ``deformation`` topic (the feedback's
``deformation.enabled``) gets a ``deformation`` block (:class:`Deformation`):
the deformation ratio ``d_r`` of paper 004 eq. (7) just before each stop of
the reference, where 004 Fig. 11 compares slow and fast, reversing and
non-reversing stops (:func:`reference_stops`, :func:`deformation_summary`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from servo_axis.analysis.health import RunHealth
from servo_axis.analysis.metrics import (
    ContourCycle,
    ContourResult,
    contour_error,
    error_statistics,
    to_plain,
)
from servo_axis.analysis.signals import (
    IDENTIFIER_SECTION,
    FaultRecord,
    Signals,
    learning_enabled,
    load_signals,
    table_name,
    tracking,
)
from servo_axis.core.deformation import DeformationTrace
from servo_axis.core.errors import ConfigError
from servo_axis.params.factories import build_reference, learning_law, plant_model
from servo_axis.params.resolve import feedforward_values, node_values
from servo_axis.params.scenario import load_scenario
from servo_axis.wire.cdr import EstimateData

SUMMARY_FILE = "summary.json"

#: The parameters an identifier estimates (003 eq. (2)): ``J, D, U, C``, as
#: named in the plant's parameters and in ``identifier/estimates``.
IDENTIFIED: tuple[str, ...] = ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm")


def _dumps(data: dict[str, Any]) -> str:
    return json.dumps(data, indent=2, allow_nan=True)


def _read(source: str | Path) -> dict[str, Any]:
    """The mapping of a summary given as JSON text or as a file path."""
    if isinstance(source, str) and source.lstrip().startswith("{"):
        text = source
    else:
        text = Path(source).read_text()
    data = json.loads(text)
    if not isinstance(data, dict):
        raise ConfigError(f"summary: expected a JSON object, got {type(data).__name__}")
    return data


@dataclass(frozen=True)
class ErrorStats:
    """RMS and largest magnitude of an error, m (NaN over no samples)."""

    rms_m: float
    max_m: float

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ErrorStats:
        """Inverse of :meth:`to_dict`."""
        return cls(rms_m=data["rms_m"], max_m=data["max_m"])


@dataclass(frozen=True)
class SampleStats:
    """Error statistics over every sample and over the reference instants."""

    all_samples: ErrorStats
    reference_instants: ErrorStats

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SampleStats:
        """Inverse of :meth:`to_dict`."""
        return cls(
            all_samples=ErrorStats.from_dict(data["all_samples"]),
            reference_instants=ErrorStats.from_dict(data["reference_instants"]),
        )


@dataclass(frozen=True)
class CycleStats:
    """Tracking error of one complete cycle of the reference.

    Attributes
    ----------
    cycle : int
        Cycle number, from 1.
    rms_m, max_m : float
        Over every sample of the cycle, m.
    reference_instants : ErrorStats
        Over the reference instants of the cycle.
    """

    cycle: int
    rms_m: float
    max_m: float
    reference_instants: ErrorStats

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CycleStats:
        """Inverse of :meth:`to_dict`."""
        return cls(
            cycle=data["cycle"],
            rms_m=data["rms_m"],
            max_m=data["max_m"],
            reference_instants=ErrorStats.from_dict(data["reference_instants"]),
        )


@dataclass(frozen=True)
class TrackingError:
    """Statistics of the tracking error ``R (r - y)`` of a run.

    Attributes
    ----------
    all_samples, reference_instants : ErrorStats
        Whole run, every sample and the reference instants.
    cycles : tuple of CycleStats
        Per complete cycle of a periodic reference (else empty).
    after_first_cycle : SampleStats or None
        From cycle 2 on; None when the reference is not periodic.
    """

    all_samples: ErrorStats
    reference_instants: ErrorStats
    cycles: tuple[CycleStats, ...] = ()
    after_first_cycle: SampleStats | None = field(default=None, metadata={"omit_none": True})

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrackingError:
        """Inverse of :meth:`to_dict`; reads the output of ``error_statistics``."""
        after = data.get("after_first_cycle")
        return cls(
            all_samples=ErrorStats.from_dict(data["all_samples"]),
            reference_instants=ErrorStats.from_dict(data["reference_instants"]),
            cycles=tuple(CycleStats.from_dict(c) for c in data["cycles"]),
            after_first_cycle=None if after is None else SampleStats.from_dict(after),
        )


@dataclass(frozen=True)
class ParameterValues:
    """A value per identified parameter ``J, D, U, C`` of 003 eq. (2).

    Their values in SI units (kg m^2, N m s/rad, N m, N m), or ratios to the
    true values (no unit), by use.
    """

    inertia_kgm2: float
    damping_Nms_per_rad: float
    unbalance_Nm: float
    coulomb_Nm: float

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ParameterValues:
        """Inverse of :meth:`to_dict`."""
        return cls(**{name: data[name] for name in IDENTIFIED})

    def values(self) -> tuple[float, float, float, float]:
        """``(J, D, U, C)``."""
        return (self.inertia_kgm2, self.damping_Nms_per_rad, self.unbalance_Nm, self.coulomb_Nm)


@dataclass(frozen=True)
class UpdateCounts:
    """How many estimates updated each parameter (eq. (16) for ``J, D, U``, eq. (8) for ``C``)."""

    inertia_kgm2: int
    damping_Nms_per_rad: int
    unbalance_Nm: int
    coulomb_Nm: int

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> UpdateCounts:
        """Inverse of :meth:`to_dict`."""
        return cls(**{name: data[name] for name in IDENTIFIED})


@dataclass(frozen=True)
class Identification:
    """The online parameter identification of a run (paper 003, topic ``identifier/estimates``).

    Attributes
    ----------
    estimates : int
        Estimates kept: validated, the first of each step.
    repeated : int
        Recorded estimates that repeat a kept one value for value (a
        restarted identifier's): not counted as junk.
    dropped : int
        Recorded estimates dropped as junk (failed the checks, or a second
        estimate of a step with other values).
    first_step, last_step : int or None
        The first and last estimate's ``step`` (None without estimates).
    final : ParameterValues
        ``J, D, U, C`` of the last estimate (by step); NaN without estimates.
    true : ParameterValues
        The plant's values (its parameters, defaults filled in); NaN for a
        parameter the plant model does not have.
    final_ratio : ParameterValues
        ``final / true`` (NaN where the true value is 0 or unknown).
    last_period_s : float or None
        The window of ``last_period_p2p``: the reference's period
        (``1 / reference.frequency_hz`` for a sine); None: not periodic, the
        whole run.
    last_period_p2p : ParameterValues
        Largest minus smallest estimate of each parameter over the estimates
        of the last ``last_period_s / T_u`` control steps up to the last
        estimate's (``step > last_step - round(last_period_s / T_u)``).
    final_kappa : float
        The PE index of eq. (7) of the last estimate.
    updates : UpdateCounts
        Per parameter, how many kept estimates updated it.
    """

    estimates: int
    repeated: int
    dropped: int
    first_step: int | None
    last_step: int | None
    final: ParameterValues
    true: ParameterValues
    final_ratio: ParameterValues
    last_period_s: float | None
    last_period_p2p: ParameterValues
    final_kappa: float
    updates: UpdateCounts

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Identification:
        """Inverse of :meth:`to_dict`."""
        return cls(
            estimates=data["estimates"],
            repeated=data["repeated"],
            dropped=data["dropped"],
            first_step=data["first_step"],
            last_step=data["last_step"],
            final=ParameterValues.from_dict(data["final"]),
            true=ParameterValues.from_dict(data["true"]),
            final_ratio=ParameterValues.from_dict(data["final_ratio"]),
            last_period_s=data["last_period_s"],
            last_period_p2p=ParameterValues.from_dict(data["last_period_p2p"]),
            final_kappa=data["final_kappa"],
            updates=UpdateCounts.from_dict(data["updates"]),
        )


def _ratio(value: float, true: float) -> float:
    return value / true if true != 0.0 and math.isfinite(true) else math.nan


def summarise_estimates(
    estimates: list[EstimateData] | tuple[EstimateData, ...],
    *,
    true: ParameterValues,
    control_period_s: float,
    period_s: float | None,
    repeated: int = 0,
    dropped: int = 0,
) -> Identification:
    """The :class:`Identification` of validated estimates (any order; one per step).

    Parameters
    ----------
    estimates : sequence of EstimateData
        The kept estimates (:attr:`~servo_axis.analysis.signals.Signals.estimates`).
    true : ParameterValues
        The plant's true ``J, D, U, C``.
    control_period_s : float
        ``T_u``, s: an estimate's time is ``step * T_u``.
    period_s : float or None
        The reference's period, s: the window of the peak-to-peak values
        (None: every estimate).
    repeated, dropped : int
        Recorded estimates repeated and dropped (reported as they are).
    """
    ordered = sorted(estimates, key=lambda e: e.step)
    table = np.array(
        [(e.inertia_kgm2, e.damping_Nms_per_rad, e.unbalance_Nm, e.coulomb_Nm) for e in ordered],
        dtype=float,
    ).reshape(-1, 4)
    steps = np.array([e.step for e in ordered], dtype=int)
    nan4 = ParameterValues(math.nan, math.nan, math.nan, math.nan)
    if not ordered:
        final = p2p = nan4
        kappa = math.nan
    else:
        final = ParameterValues(*(float(v) for v in table[-1]))
        inside = np.ones(steps.size, dtype=bool)
        if period_s:
            inside = steps > steps[-1] - round(period_s / control_period_s)
        window = table[inside]
        p2p = ParameterValues(*(float(v) for v in window.max(axis=0) - window.min(axis=0)))
        kappa = ordered[-1].kappa
    counts = [sum(1 for e in ordered if e.updated[i]) for i in range(4)]
    return Identification(
        estimates=len(ordered),
        repeated=repeated,
        dropped=dropped,
        first_step=ordered[0].step if ordered else None,
        last_step=ordered[-1].step if ordered else None,
        final=final,
        true=true,
        final_ratio=ParameterValues(
            *(_ratio(v, t) for v, t in zip(final.values(), true.values(), strict=True))
        ),
        last_period_s=period_s,
        last_period_p2p=p2p,
        final_kappa=kappa,
        updates=UpdateCounts(*counts),
    )


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
class ReferenceStop:
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
class DeformationWindow:
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

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> DeformationWindow:
        """Inverse of :meth:`to_dict`."""
        return cls(
            start_s=data["start_s"],
            end_s=data["end_s"],
            valid_samples=data["valid_samples"],
            mean_d_r_m_per_rad=data["mean_d_r_m_per_rad"],
        )


@dataclass(frozen=True)
class DeformationStop:
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

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> DeformationStop:
        """Inverse of :meth:`to_dict`."""
        return cls(
            time_s=data["time_s"],
            kind=data["kind"],
            deceleration_m_s2=data["deceleration_m_s2"],
            windows=tuple(DeformationWindow.from_dict(w) for w in data["windows"]),
        )


@dataclass(frozen=True)
class Deformation:
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

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Deformation:
        """Inverse of :meth:`to_dict`."""
        return cls(
            window_samples=data["window_samples"],
            min_rotation_rad=data["min_rotation_rad"],
            samples=data["samples"],
            valid_samples=data["valid_samples"],
            dropped=data["dropped"],
            stops=tuple(DeformationStop.from_dict(s) for s in data["stops"]),
        )


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
    scenario: dict[str, Any], scenario_path: Path, sig: Signals
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
    period = _axis_values(scenario)["control_period_s"]
    fb = node_values(scenario, "feedback")
    t = sig.step * period
    _, vel, acc = build_reference(feedforward_values(scenario, scenario_path)).sample(t)
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
        window_samples=int(fb["deformation.window_samples"]),
        min_rotation_rad=float(fb["deformation.min_rotation_rad"]),
        samples=int(np.count_nonzero(~np.isnan(trace.scale_increment_m))),
        valid_samples=int(np.count_nonzero(trace.valid)),
        dropped=sum(sig.dropped.get(name, 0) for name in topics),
        stops=stops,
    )


@dataclass(frozen=True)
class Realtime:
    """How the plant's clock kept time in a realtime run (its report, ``health.realtime``).

    A realtime run is never deterministic: which commands miss their
    deadline depends on the host. These figures say how far it was from
    the lockstep result (:mod:`servo_axis.core.deadlines`).

    Attributes
    ----------
    period_ns : int
        ``T_u``, ns.
    ticks : int
        Ticks of the clock (one step each).
    misses : int
        Ticks whose command had not arrived by the tick's deadline (the last
        current was held).
    commands_missing : int
        Steps whose command never arrived (counted in ``misses``).
    commands_late : int
        Commands that arrived more than a period after their state's tick
        (``misses = commands_late + commands_missing``).
    timer_rate : float
        Ticks per period of wall time from the start to the last tick (1.0:
        the clock kept time).
    tick_late_us, command_late_us : dict or None
        ``p50``, ``p99`` and ``max`` in us of the ticks' lateness (when the
        plant stepped after the deadline) and of the commands' (arrival after
        the tick of the state they answer: more than one period is a miss).
    floor : dict or None
        The floor of the host at this period (``rt_floor.py --json``'s result,
        ``run --floor FILE``); None (not written) if not given.
    scheduling : dict or None
        The plant process's scheduling: ``policy`` (``fifo`` or ``other``),
        ``priority`` and, where the system refused ``thread_priority``,
        ``refused`` (why); None from a plant that did not report it.
    """

    period_ns: int
    ticks: int
    misses: int
    commands_missing: int
    commands_late: int
    timer_rate: float
    tick_late_us: dict[str, float] | None
    command_late_us: dict[str, float] | None
    floor: dict[str, Any] | None = field(default=None, metadata={"omit_none": True})
    scheduling: dict[str, Any] | None = field(default=None, metadata={"omit_none": True})

    @property
    def miss_fraction(self) -> float:
        """``misses / ticks`` (0 without ticks)."""
        return self.misses / self.ticks if self.ticks else 0.0

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Realtime:
        return cls(
            period_ns=int(data["period_ns"]),
            ticks=int(data["ticks"]),
            misses=int(data["misses"]),
            commands_missing=int(data["commands_missing"]),
            commands_late=int(data.get("commands_late", 0)),
            timer_rate=float(data["timer_rate"]),
            tick_late_us=data.get("tick_late_us"),
            command_late_us=data.get("command_late_us"),
            floor=data.get("floor"),
            scheduling=data.get("scheduling"),
        )


@dataclass(frozen=True)
class RunSummary:
    """Summary of a single-axis run (``summary.json``).

    Attributes
    ----------
    scenario, description : str
        The scenario's name (the file stem if it has none) and description.
    scenario_file : str
        Path of the scenario file the run used.
    processes : str
        How the nodes ran (``processes``, ``composed``, ...).
    time_mode : str
        ``lockstep`` or ``realtime``.
    control_period_s : float
        ``T_u``, s.
    steps : int
        Recorded control steps (with both state and reference).
    sim_time_s, wall_time_s : float
        Simulated and wall time of the run, s.
    steps_per_s, realtime_factor : float
        Throughput (NaN when the wall time is not > 0).
    message_counts : dict
        Messages per recorded topic.
    faults : tuple of FaultRecord
        Trips of the feedback loop.
    ptc, friction_table : bool
        Whether the feedforward used PTC and the friction table.
    reference_period_s : float or None
        The learning cycle or the reference's period; None if not periodic.
    tracking_error : TrackingError
        Statistics of the tracking error.
    health : RunHealth or None
        Deaths, restarts, fallbacks, strangers and the exit code (the runner's
        view; None for a summary made from a bag alone).
    period_name : str or None
        ``trial`` when the periods of ``tracking_error.cycles`` are trials (a
        ``trials`` reference, paper 001); None (not written) for cycles.
    ilc_convergence : dict or None
        For a trial law (paper 001): ``nq`` and ``max |Q (1 - S L P)|`` of
        eq. (7) on the nominal model (``nominal``; the law refuses to start
        at 1 or above) and on the rigid-body part of the scenario's plant
        (``plant``); None (not written) otherwise.
    error_unit : str or None
        ``rad`` for a plant whose table turns (its model's ``rotary``): every
        ``*_m`` error is then in rad of table angle; None (not written): m.
    identification : Identification or None
        With an identifier whose estimates the bag holds (paper 003); None
        (not written) otherwise.
    deformation : Deformation or None
        With the ``deformation`` topic in the bag (paper 004); None (not
        written) otherwise.
    realtime : Realtime or None
        A realtime run's deadline misses and lateness (the plant's report);
        None (not written) in lockstep or without the report.
    """

    scenario: str
    description: str
    scenario_file: str
    processes: str
    time_mode: str
    control_period_s: float
    steps: int
    sim_time_s: float
    wall_time_s: float
    steps_per_s: float
    realtime_factor: float
    message_counts: dict[str, int]
    faults: tuple[FaultRecord, ...]
    ptc: bool
    friction_table: bool
    reference_period_s: float | None
    tracking_error: TrackingError
    health: RunHealth | None = field(default=None, metadata={"omit_none": True})
    period_name: str | None = field(default=None, metadata={"omit_none": True})
    ilc_convergence: dict[str, float] | None = field(default=None, metadata={"omit_none": True})
    error_unit: str | None = field(default=None, metadata={"omit_none": True})
    identification: Identification | None = field(default=None, metadata={"omit_none": True})
    deformation: Deformation | None = field(default=None, metadata={"omit_none": True})
    realtime: Realtime | None = field(default=None, metadata={"omit_none": True})

    @property
    def unit(self) -> str:
        """The unit of the tracking error: ``m``, or ``rad`` for a rotary table."""
        return self.error_unit or "m"

    @property
    def rmsd(self) -> float:
        """RMS of the tracking error over every sample of the run (003's RMSD), in :attr:`unit`."""
        return self.tracking_error.all_samples.rms_m

    def to_dict(self) -> dict[str, Any]:
        """The mapping of ``summary.json``, keys in file order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    def to_json(self) -> str:
        """The text of ``summary.json``."""
        return _dumps(self.to_dict())

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSummary:
        """Inverse of :meth:`to_dict`."""
        return cls(
            scenario=data["scenario"],
            description=data["description"],
            scenario_file=data["scenario_file"],
            processes=data["processes"],
            time_mode=data["time_mode"],
            control_period_s=data["control_period_s"],
            steps=data["steps"],
            sim_time_s=data["sim_time_s"],
            wall_time_s=data["wall_time_s"],
            steps_per_s=data["steps_per_s"],
            realtime_factor=data["realtime_factor"],
            message_counts=dict(data["message_counts"]),
            faults=tuple(FaultRecord.from_dict(f) for f in data["faults"]),
            ptc=data["ptc"],
            friction_table=data["friction_table"],
            reference_period_s=data["reference_period_s"],
            tracking_error=TrackingError.from_dict(data["tracking_error"]),
            health=RunHealth.from_dict(data["health"]) if "health" in data else None,
            period_name=data.get("period_name"),
            ilc_convergence=data.get("ilc_convergence"),
            error_unit=data.get("error_unit"),
            identification=(
                Identification.from_dict(data["identification"])
                if "identification" in data
                else None
            ),
            deformation=(
                Deformation.from_dict(data["deformation"]) if "deformation" in data else None
            ),
            realtime=Realtime.from_dict(data["realtime"]) if "realtime" in data else None,
        )

    @classmethod
    def from_json(cls, source: str | Path) -> RunSummary:
        """Read a summary from JSON text or from a ``summary.json`` path."""
        return cls.from_dict(_read(source))


@dataclass(frozen=True)
class ContourSummary:
    """Contour error of a two-axis run as in ``summary.json`` (no series).

    Attributes
    ----------
    axes : tuple of str
        The two axes, in the order of the coordinates.
    centre_m, radius_m, target_radial_deviation_m, circular_deviation_m, max_radial_m, cycles
        As in :class:`~servo_axis.analysis.metrics.ContourResult`.
    """

    axes: tuple[str, ...]
    centre_m: tuple[float, ...]
    radius_m: float
    target_radial_deviation_m: float
    circular_deviation_m: float
    max_radial_m: float
    cycles: tuple[ContourCycle, ...]

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ContourSummary:
        """Inverse of :meth:`to_dict`."""
        return cls(
            axes=tuple(data["axes"]),
            centre_m=tuple(data["centre_m"]),
            radius_m=data["radius_m"],
            target_radial_deviation_m=data["target_radial_deviation_m"],
            circular_deviation_m=data["circular_deviation_m"],
            max_radial_m=data["max_radial_m"],
            cycles=tuple(ContourCycle.from_dict(c) for c in data["cycles"]),
        )

    @classmethod
    def from_result(
        cls, axes: list[str] | tuple[str, ...], result: ContourResult
    ) -> ContourSummary:
        """The summary of a computed contour of ``axes``."""
        return cls.from_dict({"axes": list(axes), **result.to_summary()})


@dataclass(frozen=True)
class AxesSummary:
    """Summary of a multi-axis run (``summary.json`` of the run directory).

    Attributes
    ----------
    scenario, description : str
        The scenario's name and description.
    wall_time_s : float
        Wall time of the run, s.
    axes : dict
        Axis name -> :class:`RunSummary` of that axis.
    contour : ContourSummary or None
        For two axes, their contour error.
    health : RunHealth or None
        The whole run's health (each axis's summary has its own as well).
    """

    scenario: str
    description: str
    wall_time_s: float
    axes: dict[str, RunSummary]
    contour: ContourSummary | None = field(default=None, metadata={"omit_none": True})
    health: RunHealth | None = field(default=None, metadata={"omit_none": True})

    def to_dict(self) -> dict[str, Any]:
        """The mapping of ``summary.json``, keys in file order."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    def to_json(self) -> str:
        """The text of ``summary.json``."""
        return _dumps(self.to_dict())

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AxesSummary:
        """Inverse of :meth:`to_dict`."""
        contour = data.get("contour")
        return cls(
            scenario=data["scenario"],
            description=data["description"],
            wall_time_s=data["wall_time_s"],
            axes={name: RunSummary.from_dict(s) for name, s in data["axes"].items()},
            contour=None if contour is None else ContourSummary.from_dict(contour),
            health=RunHealth.from_dict(data["health"]) if "health" in data else None,
        )

    @classmethod
    def from_json(cls, source: str | Path) -> AxesSummary:
        """Read a summary from JSON text or from a ``summary.json`` path."""
        return cls.from_dict(_read(source))


def summary_from_dict(data: dict[str, Any]) -> RunSummary | AxesSummary:
    """:class:`AxesSummary` for a mapping with ``axes``, else :class:`RunSummary`."""
    return AxesSummary.from_dict(data) if "axes" in data else RunSummary.from_dict(data)


def load_summary(run_dir: Path) -> RunSummary | AxesSummary:
    """The ``summary.json`` of a run directory, single- or multi-axis.

    Raises
    ------
    ConfigError
        If ``run_dir`` is not a directory with a ``summary.json``
        (``<dir>: not a run directory: no summary.json``), or the file is not
        a summary this version reads (the message names the file and what is
        wrong).
    """
    path = Path(run_dir) / SUMMARY_FILE
    if not Path(run_dir).is_dir():
        raise ConfigError(f"{run_dir}: not a run directory: no such directory")
    if not path.is_file():
        raise ConfigError(f"{run_dir}: not a run directory: no {SUMMARY_FILE}")
    try:
        return summary_from_dict(_read(path))
    except OSError as err:
        raise ConfigError(f"{path}: cannot read it: {err}") from None
    except (ValueError, KeyError, TypeError, AttributeError) as err:
        what = f"missing key {err}" if isinstance(err, KeyError) else str(err)
        raise ConfigError(f"{path}: not a servo_axis run summary: {what}") from None


def cycle_errors(summary: RunSummary) -> dict[str, NDArray[Any]]:
    """Per-cycle tracking error of a run summary, as arrays (cycle number, m).

    Returns ``{"cycle", "max_m", "rms_m", "max_at_tr_m"}``; empty arrays when
    the reference is not periodic.
    """
    cycles = summary.tracking_error.cycles
    return {
        "cycle": np.array([c.cycle for c in cycles], dtype=int),
        "max_m": np.array([c.max_m for c in cycles], dtype=float),
        "rms_m": np.array([c.rms_m for c in cycles], dtype=float),
        "max_at_tr_m": np.array([c.reference_instants.max_m for c in cycles], dtype=float),
    }


def _axis_values(scenario: dict[str, Any]) -> dict[str, Any]:
    """Checked shared values of an axis (period, lead, mode, names), as its plant has them."""
    return node_values(scenario, "plant")


def error_unit(plant_values: dict[str, Any]) -> str:
    """``rad`` for a plant model whose table turns (its registry entry's ``rotary``), else ``m``.

    A rotary table's position is its angle, so the tracking error is
    ``r - y`` in rad (no lead); every other model's table moves along a
    line, ``x = R theta``: the error ``R (r - y)`` is in m.
    """
    return "rad" if plant_model(plant_values["model"], "plant.model").rotary else "m"


def position_scale(plant_values: dict[str, Any]) -> float:
    """Table position per rad of controlled output: ``R`` (m/rad), 1 for a rotary table."""
    return 1.0 if error_unit(plant_values) == "rad" else float(plant_values["lead_m_per_rad"])


def true_parameters(plant_values: dict[str, Any]) -> ParameterValues:
    """The plant's ``J, D, U, C`` (NaN for one its model does not have)."""
    return ParameterValues(*(float(plant_values.get(name, math.nan)) for name in IDENTIFIED))


def identification(
    scenario: dict[str, Any], sig: Signals, *, period_s: float | None
) -> Identification | None:
    """The identification of a run with an identifier whose estimates the bag has, else None.

    Estimates are the validated ones of :attr:`Signals.estimates`; the
    repeats and the junk are those of the ``identifier/estimates`` topics.
    """
    topics = [t for t in sig.counts if table_name(t) == "identifier/estimates"]
    if IDENTIFIER_SECTION not in scenario or not topics:
        return None
    plant = _axis_values(scenario)
    return summarise_estimates(
        sig.estimates,
        true=true_parameters(plant),
        control_period_s=plant["control_period_s"],
        period_s=period_s,
        repeated=sum(sig.repeated.get(t, 0) for t in topics),
        dropped=sum(sig.dropped.get(t, 0) for t in topics),
    )


def summarise(
    run_dir: Path,
    *,
    scenario: dict[str, Any],
    scenario_path: Path,
    wall_time_s: float,
    mode: str,
    health: RunHealth | None = None,
) -> RunSummary:
    """Compute the summary of a run, write ``summary.json`` and return it.

    Parameters
    ----------
    run_dir : Path
        The run directory (its bag is ``run_dir / "bag"``).
    scenario : dict
        The (single-axis) scenario the run used.
    scenario_path : Path
        Its file (relative friction-table paths are relative to its directory).
    wall_time_s : float
        Wall time of the run, s.
    mode : str
        How the nodes ran (``processes``, ``composed``).
    health : RunHealth or None
        What the runner saw (deaths, fallbacks, strangers, exit code).
    """
    run_dir = Path(run_dir)
    common = _axis_values(scenario)
    period = common["control_period_s"]
    unit = error_unit(common)
    ff = node_values(scenario, "feedforward")
    sig = load_signals(run_dir / "bag", period, scenario=scenario)
    target, y = tracking(scenario, scenario_path, sig)
    error = position_scale(common) * (target - y)
    learning = learning_enabled(scenario)
    reference_period: float | None = None
    if "feedforward" in scenario and (not learning or IDENTIFIER_SECTION in scenario):
        reference_period = build_reference(feedforward_values(scenario, scenario_path)).period_s
    cycle = ff["learning.cycle_s"] if learning else reference_period
    steps = int(sig.step.size)
    sim_time = steps * period
    summary = RunSummary(
        scenario=common["scenario.name"] or scenario_path.stem,
        description=common["scenario.description"],
        scenario_file=str(scenario_path),
        processes=mode,
        time_mode=common["mode"],
        control_period_s=period,
        steps=steps,
        sim_time_s=sim_time,
        wall_time_s=wall_time_s,
        steps_per_s=steps / wall_time_s if wall_time_s > 0 else math.nan,
        realtime_factor=sim_time / wall_time_s if wall_time_s > 0 else math.nan,
        message_counts=sig.counts,
        faults=tuple(sig.faults),
        ptc=bool(ff["ptc.enabled"]),
        friction_table=bool(ff["friction_table.enabled"]),
        reference_period_s=cycle,
        tracking_error=TrackingError.from_dict(
            error_statistics(error, sig.step, period_s=period, cycle_s=cycle)
        ),
        health=health,
        period_name="trial" if ff["reference.kind"] == "trials" else None,
        ilc_convergence=ilc_convergence(scenario, scenario_path),
        error_unit=None if unit == "m" else unit,
        identification=identification(scenario, sig, period_s=reference_period),
        deformation=deformation_summary(scenario, scenario_path, sig),
    )
    (run_dir / SUMMARY_FILE).write_text(summary.to_json())
    return summary


def ilc_convergence(scenario: dict[str, Any], scenario_path: Path) -> dict[str, float] | None:
    """``{"nq", "nominal", "plant"}``: the measure of 001 eq. (7) for a trial law, else None.

    The law's registry entry computes it (``LearningLawEntry.convergence``;
    None for a law without one): ``plant`` is the plant's rigid-body part
    (``J``, ``D``, ``K_T`` of the plant section) under the same PID and ``L``.
    """
    if "learning" not in scenario or "plant" not in scenario:
        return None
    values = node_values(scenario, "learning")
    convergence = learning_law(values["law"]).convergence
    if convergence is None:
        return None
    return convergence(values, node_values(scenario, "plant"))


@dataclass(frozen=True, eq=False)
class RunSeries:
    """A recorded run's summary, signals, target and controlled output.

    Attributes
    ----------
    summary : RunSummary
        Its ``summary.json``.
    signals : Signals
        Its bag's signals.
    target_rad, y_rad : ndarray
        Target and controlled output per recorded step (rad), from
        :func:`~servo_axis.analysis.signals.tracking`.
    lead_m_per_rad : float
        Table position per rad: ``R`` of the axis, 1 for a rotary table
        (:func:`position_scale`; the position is then the angle, rad).
    """

    summary: RunSummary
    signals: Signals
    target_rad: NDArray[np.float64]
    y_rad: NDArray[np.float64]
    lead_m_per_rad: float

    @property
    def time_s(self) -> NDArray[np.floating[Any]]:
        """Simulation time of each recorded step, s."""
        t: NDArray[np.floating[Any]] = self.signals.step * self.summary.control_period_s
        return t

    @property
    def error_m(self) -> NDArray[np.floating[Any]]:
        """Tracking error ``R (r - y)`` per recorded step, m (rad for a rotary table)."""
        e: NDArray[np.floating[Any]] = self.lead_m_per_rad * (self.target_rad - self.y_rad)
        return e


def run_series(run_dir: Path) -> RunSeries:
    """Summary, recorded signals, target and controlled output of a run directory."""
    run_dir = Path(run_dir)
    summary = RunSummary.from_json(run_dir / SUMMARY_FILE)
    scenario_path = Path(summary.scenario_file)
    scenario = load_scenario(scenario_path)
    lead = position_scale(_axis_values(scenario))
    sig = load_signals(run_dir / "bag", summary.control_period_s, scenario=scenario)
    target, y = tracking(scenario, scenario_path, sig)
    return RunSeries(summary, sig, target, y, lead)


def contour(run_dir: Path, axes: list[str] | tuple[str, ...]) -> ContourResult:
    """Contour error of the two axes (sub-directories of ``run_dir``) of a circle run.

    Positions are ``R`` times the target and the controlled output of each
    axis at the steps both recorded; the cycle is the first axis's reference
    period (see :func:`~servo_axis.analysis.metrics.contour_error`).

    Raises
    ------
    ConfigError
        Unless there are exactly two axes.
    """
    if len(axes) != 2:
        raise ConfigError(f"axes: expected two, got {axes!r}")
    series = [run_series(Path(run_dir) / a) for a in axes]
    steps = np.intersect1d(series[0].signals.step, series[1].signals.step)
    target = np.empty((steps.size, 2))
    measured = np.empty((steps.size, 2))
    for col, s in enumerate(series):
        idx = np.searchsorted(s.signals.step, steps)
        target[:, col] = s.lead_m_per_rad * s.target_rad[idx]
        measured[:, col] = s.lead_m_per_rad * s.y_rad[idx]
    first = series[0].summary
    period = float(first.control_period_s)
    cycle_s = first.reference_period_s
    per_cycle = round(cycle_s / period) if cycle_s else None
    return contour_error(target, measured, steps, per_cycle)


def summarise_axes(
    run_dir: Path,
    *,
    scenario: dict[str, Any],
    axes: dict[str, RunSummary],
    wall_time_s: float,
    health: RunHealth | None = None,
) -> AxesSummary:
    """Summary of a multi-axis run: the axes' summaries and, for two, the contour.

    Writes ``run_dir / "summary.json"`` and returns it.
    """
    run_dir = Path(run_dir)
    common = _axis_values(scenario)
    contour_summary = None
    if len(axes) == 2:
        names = sorted(axes)
        contour_summary = ContourSummary.from_result(names, contour(run_dir, names))
    summary = AxesSummary(
        scenario=common["scenario.name"],
        description=common["scenario.description"],
        wall_time_s=wall_time_s,
        axes=dict(axes),
        contour=contour_summary,
        health=health,
    )
    (run_dir / SUMMARY_FILE).write_text(summary.to_json())
    return summary
