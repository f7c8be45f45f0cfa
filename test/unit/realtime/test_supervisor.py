"""The runner's realtime supervisor (servo_axis.realtime.supervisor), without a run."""

from __future__ import annotations

import time
from dataclasses import dataclass

from servo_axis.realtime.supervisor import OvertimeCheck
from servo_axis.run.state import RunState


@dataclass
class Started:
    t_first: float | None


def test_a_realtime_run_ends_only_once_it_has_lasted_its_limit() -> None:
    check = OvertimeCheck(2.0, factor=3.0, margin_s=60.0)
    assert check.limit_s == 66.0
    assert check.failure(Started(None)) is None  # no step yet: the start-up is not timed
    assert check.failure(Started(time.monotonic() - 65.0)) is None
    reason = check.failure(Started(time.monotonic() - 70.0))
    assert reason is not None and reason.startswith("overtime: a realtime run of 2 s simulated")
    assert "(limit 66 s)" in reason


def test_it_reads_the_runners_state() -> None:
    state = RunState()
    assert OvertimeCheck(1.0, margin_s=0.0).failure(state) is None
    state.t_first = time.monotonic() - 10.0
    assert "overtime" in (OvertimeCheck(1.0, margin_s=0.0).failure(state) or "")
