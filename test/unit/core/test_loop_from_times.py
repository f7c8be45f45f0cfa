"""A loop's misses and lateness from arrival and send times (an outside plant's loop)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.realtime.clock import MEASURED_AT_FEEDBACK, LoopTimes
from servo_axis.realtime.deadlines import loop_from_times

T = 1_000_000  # ns
T0 = 5_000_000_000  # a monotonic clock's reading


def test_a_command_later_than_a_period_or_never_sent_is_a_miss() -> None:
    rng = np.random.default_rng(3)
    steps = np.array([0, 1, 2, 3, 5, 6, 7, 8, 9])  # the plant's timer skipped step 4
    arrived = T0 + steps * T + rng.integers(0, 300_000, steps.size)
    late = rng.integers(100_000, 2_500_000, steps.size)
    answered = np.ones(steps.size, dtype=bool)
    answered[[2, 7]] = False
    got = loop_from_times(
        period_ns=T,
        state_steps=steps.tolist(),
        state_times_ns=arrived.tolist(),
        command_steps=steps[answered].tolist(),
        command_times_ns=(arrived + late)[answered].tolist(),
    )
    assert got is not None
    expected_late = np.where(answered, late, np.inf)
    assert got["ticks"] == 9 and got["commands_missing"] == 2
    assert got["misses"] == int(np.count_nonzero(expected_late > T))
    assert got["commands_late"] == got["misses"] - 2
    finite = late[answered]
    assert_allclose(got["command_late_us"]["max"], finite.max() / 1e3, atol=0.05)
    assert_allclose(got["command_late_us"]["p50"], np.percentile(finite, 50) / 1e3, atol=0.05)
    # 9 periods from step 0 to step 9, over the arrivals of their states.
    assert_allclose(got["timer_rate"], 9 * T / (arrived[-1] - arrived[0]), rtol=1e-12)
    tick_late = arrived - arrived[0] - (steps - steps[0]) * T
    assert_allclose(got["tick_late_us"]["max"], max(0, tick_late.max()) / 1e3, atol=0.05)


def test_only_the_first_command_of_a_step_counts() -> None:
    got = loop_from_times(
        period_ns=T,
        state_steps=[0, 1],
        state_times_ns=[T0, T0 + T],
        command_steps=[0, 0, 1],
        command_times_ns=[T0 + 2 * T, T0 + 100, T0 + T + 10],
    )
    assert got is not None and got["misses"] == 1 and got["commands_late"] == 1


def test_bad_arguments_are_named() -> None:
    assert loop_from_times(
        period_ns=T, state_steps=[], state_times_ns=[], command_steps=[], command_times_ns=[]
    ) is None  # fmt: skip
    with pytest.raises(ValueError, match="period_ns"):
        loop_from_times(period_ns=0, state_steps=[0], state_times_ns=[T0],
                        command_steps=[], command_times_ns=[])  # fmt: skip
    with pytest.raises(ValueError, match="state_times_ns"):
        loop_from_times(period_ns=T, state_steps=[0, 1], state_times_ns=[T0],
                        command_steps=[], command_times_ns=[])  # fmt: skip
    with pytest.raises(ValueError, match="command_times_ns"):
        loop_from_times(period_ns=T, state_steps=[0], state_times_ns=[T0],
                        command_steps=[0], command_times_ns=[])  # fmt: skip


def test_a_feedback_keeps_the_first_arrival_and_send_of_each_step() -> None:
    times = LoopTimes(steps=3, period_ns=T)
    assert times.report() is None
    times.arrived(0, T0)
    times.arrived(0, T0 + 5)  # a repeat: the first counts
    times.sent(0, T0 + 400_000)
    times.arrived(1, T0 + T)
    times.arrived(2, T0 + 2 * T)
    times.sent(2, T0 + 2 * T + 1_500_000)  # late
    times.arrived(3, T0 + 3 * T)  # past the run: not kept
    got = times.report()
    assert got is not None and got["measured_from"] == MEASURED_AT_FEEDBACK
    assert (got["ticks"], got["misses"], got["commands_missing"]) == (3, 2, 1)
    assert_allclose(got["command_late_us"]["max"], 1500.0)
