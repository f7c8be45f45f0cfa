"""The runner's realtime supervisor: the checks that end a realtime run that will not end.

A check is asked on every pass of the runner's watch
(:class:`servo_axis.run.watch.Check`: ``failure(state) -> str | None``,
the first answer that is not None ends the run as a failure). The plant
itself ends a run whose clock stalled or whose loop is open
(``clock_stalled``, ``loop_open``); what is here is the last resort, from the
runner's side. No rclpy, no process: what a check reads of the run is its
state (:class:`Started`).
"""

from __future__ import annotations

import time
from typing import Protocol


class Started(Protocol):
    """What a supervisor reads of a running run (:class:`servo_axis.run.state.RunState`)."""

    #: ``time.monotonic()`` at the first recorded step; None before it.
    t_first: float | None


class OvertimeCheck:
    """Realtime: the run stops when it has lasted far longer than its simulated time.

    The last resort of a run that must end by itself (the plant ends a run
    whose clock stalled or whose loop is open on its own: ``clock_stalled``,
    ``loop_open``): from its first step, at most ``factor`` times its
    simulated time plus ``margin_s`` of wall time.
    """

    def __init__(self, simulated_s: float, *, factor: float = 3.0, margin_s: float = 60.0) -> None:
        self.limit_s = factor * simulated_s + margin_s
        self.simulated_s = simulated_s

    def failure(self, state: Started) -> str | None:
        """``overtime`` once the run has lasted :attr:`limit_s` since its first step."""
        if state.t_first is None:
            return None
        lasted = time.monotonic() - state.t_first
        if lasted > self.limit_s:
            return (
                f"overtime: a realtime run of {self.simulated_s:.3g} s simulated still ran "
                f"after {lasted:.0f} s of wall time (limit {self.limit_s:.0f} s)"
            )
        return None
