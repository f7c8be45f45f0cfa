"""The per-sample feedback loop: PID + disturbance observer + safety trips.

``u = u_ff + C_fb(z) (r - y) - d_hat`` where ``C_fb`` is the pole-placement
PID (Tustin) and ``d_hat`` the inverse-model disturbance observer estimate
(paper 004 Sect. II, DOB on the motor angle), plus an optional friction
compensation from the measured table position added outside the DOB's view
(004 eq. (9) from the stage, :mod:`~servo_axis.core.feedback.stage_sigmoid`).
The loop trips to zero current,
for good, on a following error, a travel limit or a current demand beyond
the trip level, or when the caller reports a missing input.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from servo_axis.core.errors import ConfigError, require_positive
from servo_axis.core.feedback.discrete import DiscreteFilter
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.output import SENSORS
from servo_axis.core.feedback.pid import DiscretePid
from servo_axis.core.feedback.stage_sigmoid import StageSigmoid

#: One sample inside the loop: current, PID output, DOB estimate, error, fault, value.
_Sample = tuple[float, float, float, float, "Fault | None", float]


class Fault(IntEnum):
    """Why the loop tripped (the ``code`` of the ``fault`` topic)."""

    FOLLOWING_ERROR = 1
    TRAVEL = 2
    CURRENT = 3
    INPUT_TIMEOUT = 4


@dataclass(frozen=True, kw_only=True)
class SafetyLimits:
    """Trip levels of the feedback loop.

    Parameters
    ----------
    following_error_m : float
        Largest allowed ``|r - y|`` at the table, m, > 0.
    travel_m : float
        Largest allowed ``|y|`` at the table, m, > 0.
    current_A : float
        Largest allowed current demand ``|u|``, A, > 0.
    """

    following_error_m: float = 2e-3
    travel_m: float = 0.2
    current_A: float = 50.0

    def __post_init__(self) -> None:
        require_positive("following_error_m", self.following_error_m)
        require_positive("travel_m", self.travel_m)
        require_positive("current_A", self.current_A)


@dataclass(frozen=True)
class LoopOutput:
    """One sample of the loop.

    Attributes
    ----------
    current_A : float
        Current command, A (0 once tripped).
    feedback_A, disturbance_A : float
        PID output and DOB estimate, A.
    error_rad : float
        ``r - y``, rad.
    fault : Fault or None
        Set on the sample that tripped the loop.
    fault_value : float
        The offending value (m or A) for the fault.
    """

    current_A: float
    feedback_A: float
    disturbance_A: float
    error_rad: float
    fault: Fault | None = None
    fault_value: float = 0.0


class FeedbackLoop:
    """PID + DOB + safety logic, stepped once per control sample.

    Parameters
    ----------
    pid : DiscretePid
        The feedback controller on the angle error (rad -> A).
    dob : DisturbanceObserver or None
        Disturbance observer, or None for none.
    lead_m_per_rad : float
        Lead ``R`` to express the limits at the table.
    limits : SafetyLimits
        Trip levels.
    use_feedforward : bool
        False ignores ``feedforward_A`` (PID alone).
    sensor : str
        The controlled output of :meth:`step` (``encoder`` or ``scale``,
        :func:`~servo_axis.core.feedback.output.controlled_output`).
    dob_sensor : str
        The angle the DOB observes in :meth:`step`: paper 004 closes the PID
        on the table (``scale``) and the DOB on the motor (``encoder``), for
        the DOB's bandwidth.
    compensation : StageSigmoid or None
        A friction compensation from the measured table position (the linear
        scale, m), e.g. 004 eq. (9) with sign and distance from the stage
        (:class:`~servo_axis.core.feedback.stage_sigmoid.StageSigmoid`): its
        ``current_A(scale_m)`` is added after the point where the DOB reads
        the current, as 004 Fig. 5 adds ``F_c`` (the DOB's input is the
        command without it). Needs the scale: :meth:`step` or :meth:`current`.
    """

    def __init__(
        self,
        *,
        pid: DiscretePid,
        dob: DisturbanceObserver | None,
        lead_m_per_rad: float,
        limits: SafetyLimits,
        use_feedforward: bool = True,
        sensor: str = "encoder",
        dob_sensor: str = "encoder",
        compensation: StageSigmoid | None = None,
    ) -> None:
        self._pid = pid
        self._dob = dob
        self._lead = require_positive("lead_m_per_rad", lead_m_per_rad)
        self._limits = limits
        self._use_ff = use_feedforward
        self._previous_A = 0.0
        self.fault: Fault | None = None
        for name, value in (("sensor", sensor), ("dob_sensor", dob_sensor)):
            if value not in SENSORS:
                raise ConfigError(f"{name}: expected one of {SENSORS}, got {value!r}")
        self._sensor = sensor
        self._dob_sensor = dob_sensor
        self._on_scale = sensor == "scale"
        self._dob_on_scale = dob_sensor == "scale"
        self._fused = _FusedFilters.of(pid, dob)
        self._compensation = compensation

    @property
    def tripped(self) -> bool:
        """True once the loop has tripped."""
        return self.fault is not None

    def trip(self, fault: Fault) -> None:
        """Trip for a reason found outside the loop (e.g. a missing input)."""
        if self.fault is None:
            self.fault = fault
        self._previous_A = 0.0

    def step(
        self, *, encoder_rad: float, scale_m: float, reference_rad: float, feedforward_A: float
    ) -> LoopOutput:
        """:meth:`update` from the sensor readings: the PID on ``sensor``, the DOB on ``dob_sensor``.

        Parameters
        ----------
        encoder_rad, scale_m : float
            Rotary encoder (rad) and linear scale (m) readings.
        reference_rad, feedforward_A : float
            As in :meth:`update`.
        """
        u, fb, d_hat, error, fault, value = self._sample(
            *self._observed(encoder_rad, scale_m), reference_rad, feedforward_A, scale_m
        )
        return LoopOutput(u, fb, d_hat, error, fault, value)

    def current(
        self, *, encoder_rad: float, scale_m: float, reference_rad: float, feedforward_A: float
    ) -> float:
        """``step(...).current_A``, the same state change, without building the :class:`LoopOutput`.

        The per-sample path of the plain-call loops (:mod:`servo_axis.simulate`).
        """
        # _observed, without the call.
        y = scale_m / self._lead if self._on_scale else encoder_rad
        if self._dob_on_scale == self._on_scale:
            observed = y
        else:
            observed = scale_m / self._lead if self._dob_on_scale else encoder_rad
        return self._sample(y, observed, reference_rad, feedforward_A, scale_m)[0]

    def _observed(self, encoder_rad: float, scale_m: float) -> tuple[float, float]:
        """``(y, the DOB's angle)`` of :meth:`step` from the readings.

        :func:`~servo_axis.core.feedback.output.controlled_output` of
        ``sensor`` and ``dob_sensor``, its two cases written out (the same
        division), since this runs every sample.
        """
        y = scale_m / self._lead if self._on_scale else encoder_rad
        if self._dob_on_scale == self._on_scale:
            return y, y
        return y, (scale_m / self._lead if self._dob_on_scale else encoder_rad)

    def update(
        self,
        *,
        angle_rad: float,
        reference_rad: float,
        feedforward_A: float,
        observer_angle_rad: float | None = None,
    ) -> LoopOutput:
        """Compute the current command of this sample.

        Parameters
        ----------
        angle_rad : float
            Measured controlled output ``y`` (rad of motor angle).
        reference_rad : float
            Reference ``r``, rad.
        feedforward_A : float
            Feedforward current ``u_ff``, A.
        observer_angle_rad : float or None
            The angle the DOB observes, rad (None: ``angle_rad``).
        """
        if self._compensation is not None:
            raise ConfigError(
                "compensation: a compensation from the scale needs step() or current(), "
                "which get the scale reading; update() gets only the angle"
            )
        observed = angle_rad if observer_angle_rad is None else observer_angle_rad
        u, fb, d_hat, error, fault, value = self._sample(
            angle_rad, observed, reference_rad, feedforward_A
        )
        return LoopOutput(u, fb, d_hat, error, fault, value)

    def _sample(
        self,
        angle_rad: float,
        observed: float,
        reference_rad: float,
        feedforward_A: float,
        scale_m: float = 0.0,
    ) -> _Sample:
        """One sample of :meth:`update` as a tuple (no dataclass on the per-sample path)."""
        error = reference_rad - angle_rad
        if self.fault is not None:
            return 0.0, 0.0, 0.0, error, None, 0.0
        fused = self._fused
        if fused is not None:
            fb, d_hat = fused.update(error, observed, self._previous_A)
        else:
            fb = self._pid.update(error)
            d_hat = self._dob.update(observed, self._previous_A) if self._dob is not None else 0.0
        u = (feedforward_A if self._use_ff else 0.0) + fb - d_hat
        observer_A = u
        if self._compensation is not None:
            # 004 Fig. 5: F_c enters after the DOB's view of the current.
            u = observer_A + self._compensation.current_A(scale_m)
        lead = self._lead
        lim = self._limits
        fault: Fault | None = None
        value = 0.0
        if abs(error) * lead > lim.following_error_m:
            fault, value = Fault.FOLLOWING_ERROR, error * lead
        elif abs(angle_rad) * lead > lim.travel_m:
            fault, value = Fault.TRAVEL, angle_rad * lead
        elif abs(u) > lim.current_A:
            fault, value = Fault.CURRENT, u
        if fault is not None:
            self.trip(fault)
            return 0.0, fb, d_hat, error, fault, value
        self._previous_A = observer_A
        return u, fb, d_hat, error, None, 0.0


class _FusedFilters:
    """The loop's filters advanced in one call: the PID's and the DOB's, inlined.

    ``DiscretePid.update`` and ``DisturbanceObserver.update`` as written
    (:meth:`DiscreteFilter.update <servo_axis.core.feedback.discrete.DiscreteFilter.update>`
    of order 2 for the PID, of order 1 for the DOB's inverse model and
    low-pass), operation for operation and in the same order, on the filter
    objects' own state lists and the DOB's last angle: the same floats, and
    the objects stay what they would be (``test_loop`` compares the two).
    Five Python calls a sample fewer, on every scenario's per-sample path.
    Only for the classes whose ``update`` this is (:meth:`of` gives None
    otherwise, and the loop calls the objects).
    """

    def __init__(self, pid: DiscreteFilter, dob: DisturbanceObserver | None) -> None:
        self._pz = pid._z
        (self._pb0, self._pb1, self._pb2), (_, self._pa1, self._pa2) = pid.b, pid.a
        self._dob = dob
        if dob is not None:
            inverse, lpf = dob._inverse, dob._lpf
            self._iz, self._lz = inverse._z, lpf._z
            (self._ib0, self._ib1), (_, self._ia1) = inverse.b, inverse.a
            (self._lb0, self._lb1), (_, self._la1) = lpf.b, lpf.a
            self._period = dob.period_s

    @classmethod
    def of(cls, pid: DiscretePid, dob: DisturbanceObserver | None) -> _FusedFilters | None:
        """The fused update of these objects, or None if they are not the ones it inlines."""
        if type(pid) is not DiscretePid or type(pid.filter) is not DiscreteFilter:
            return None
        if pid.filter.order != 2:
            return None
        if dob is not None:
            if type(dob) is not DisturbanceObserver:
                return None
            if any(type(f) is not DiscreteFilter or f.order != 1 for f in (dob._inverse, dob._lpf)):
                return None
        return cls(pid.filter, dob)

    def update(self, error: float, observed: float, previous_A: float) -> tuple[float, float]:
        """``(pid.update(error), dob.update(observed, previous_A) or 0.0)``."""
        z = self._pz
        fb = self._pb0 * error + z[0]
        z[0] = self._pb1 * error - self._pa1 * fb + z[1]
        z[1] = self._pb2 * error - self._pa2 * fb + 0.0
        dob = self._dob
        if dob is None:
            return fb, 0.0
        last = dob._last_angle
        if last is None:
            last = observed
        dob._last_angle = observed
        velocity = (observed - last) / self._period
        z = self._iz
        inverse = self._ib0 * velocity + z[0]
        z[0] = self._ib1 * velocity - self._ia1 * inverse + 0.0
        z = self._lz
        filtered = self._lb0 * previous_A + z[0]
        z[0] = self._lb1 * previous_A - self._la1 * filtered + 0.0
        return fb, inverse - filtered
