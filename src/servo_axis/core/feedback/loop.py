"""The per-sample feedback loop: PID + disturbance observer + safety trips.

``u = u_ff + C_fb(z) (r - y) - d_hat`` where ``C_fb`` is the pole-placement
PID (Tustin) and ``d_hat`` the inverse-model disturbance observer estimate
(paper 004 Sect. II, DOB on the motor angle). The loop trips to zero current,
for good, on a following error, a travel limit or a current demand beyond
the trip level, or when the caller reports a missing input.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from servo_axis.core.errors import ConfigError, require_positive
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.output import SENSORS, controlled_output
from servo_axis.core.feedback.pid import DiscretePid


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
        y = controlled_output(
            self._sensor, encoder_rad=encoder_rad, scale_m=scale_m, lead_m_per_rad=self._lead
        )
        observed = (
            y
            if self._dob_sensor == self._sensor
            else controlled_output(
                self._dob_sensor,
                encoder_rad=encoder_rad,
                scale_m=scale_m,
                lead_m_per_rad=self._lead,
            )
        )
        return self.update(
            angle_rad=y,
            reference_rad=reference_rad,
            feedforward_A=feedforward_A,
            observer_angle_rad=observed,
        )

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
        error = reference_rad - angle_rad
        if self.tripped:
            return LoopOutput(0.0, 0.0, 0.0, error)
        fb = self._pid.update(error)
        observed = angle_rad if observer_angle_rad is None else observer_angle_rad
        d_hat = self._dob.update(observed, self._previous_A) if self._dob is not None else 0.0
        u = (feedforward_A if self._use_ff else 0.0) + fb - d_hat
        fault, value = None, 0.0
        lim = self._limits
        if abs(error) * self._lead > lim.following_error_m:
            fault, value = Fault.FOLLOWING_ERROR, error * self._lead
        elif abs(angle_rad) * self._lead > lim.travel_m:
            fault, value = Fault.TRAVEL, angle_rad * self._lead
        elif abs(u) > lim.current_A:
            fault, value = Fault.CURRENT, u
        if fault is not None:
            self.trip(fault)
            return LoopOutput(0.0, fb, d_hat, error, fault, value)
        self._previous_A = u
        return LoopOutput(u, fb, d_hat, error)
