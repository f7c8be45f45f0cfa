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

from servo_axis.core.errors import require_positive
from servo_axis.core.feedback.dob import DisturbanceObserver
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
    """

    def __init__(
        self,
        *,
        pid: DiscretePid,
        dob: DisturbanceObserver | None,
        lead_m_per_rad: float,
        limits: SafetyLimits,
        use_feedforward: bool = True,
    ) -> None:
        self._pid = pid
        self._dob = dob
        self._lead = require_positive("lead_m_per_rad", lead_m_per_rad)
        self._limits = limits
        self._use_ff = use_feedforward
        self._previous_A = 0.0
        self.fault: Fault | None = None

    @property
    def tripped(self) -> bool:
        """True once the loop has tripped."""
        return self.fault is not None

    def trip(self, fault: Fault) -> None:
        """Trip for a reason found outside the loop (e.g. a missing input)."""
        if self.fault is None:
            self.fault = fault
        self._previous_A = 0.0

    def update(self, *, angle_rad: float, reference_rad: float, feedforward_A: float) -> LoopOutput:
        """Compute the current command of this sample.

        Parameters
        ----------
        angle_rad : float
            Measured motor angle ``y``, rad.
        reference_rad : float
            Reference ``r``, rad.
        feedforward_A : float
            Feedforward current ``u_ff``, A.
        """
        error = reference_rad - angle_rad
        if self.tripped:
            return LoopOutput(0.0, 0.0, 0.0, error)
        fb = self._pid.update(error)
        d_hat = self._dob.update(angle_rad, self._previous_A) if self._dob is not None else 0.0
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
