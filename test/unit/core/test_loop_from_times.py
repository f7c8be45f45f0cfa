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


def test_a_feedbacks_streaming_figures_are_loop_from_times_of_the_same_times() -> None:
    rng = np.random.default_rng(40)
    steps = 3_000
    arrivals = T0 + np.arange(steps) * T + rng.exponential(30_000.0, steps).astype(np.int64)
    arrivals[1_200] += 40 * T  # a stall: the states after it come late too
    arrivals[1_201:] += 40 * T
    skipped = set(rng.choice(steps, 30, replace=False).tolist())  # never arrived
    answers = rng.exponential(300_000.0, steps).astype(np.int64)
    answers[::97] += 2 * T  # late
    unanswered = set(rng.choice(steps, 20, replace=False).tolist())
    times = LoopTimes(steps=steps, period_ns=T)
    state_steps, state_times, command_steps, command_times = [], [], [], []
    for k in range(steps):
        if k in skipped:
            continue
        times.arrived(k, int(arrivals[k]))
        state_steps.append(k)
        state_times.append(int(arrivals[k]))
        if k not in unanswered:
            sent = int(arrivals[k] + answers[k])
            times.sent(k, sent)
            times.sent(k, sent + 5)  # a second send of the step: the first counts
            command_steps.append(k)
            command_times.append(sent)
    got = times.report()
    want = loop_from_times(
        period_ns=T,
        state_steps=state_steps,
        state_times_ns=state_times,
        command_steps=command_steps,
        command_times_ns=command_times,
    )
    assert got is not None and want is not None
    for key in ("period_ns", "ticks", "misses", "commands_missing", "commands_late"):
        assert got[key] == want[key], key
    assert got["commands_missing"] == len(unanswered - skipped) and got["commands_late"] > 20
    assert_allclose(got["timer_rate"], want["timer_rate"], rtol=1e-12)
    for key in ("tick_late_us", "command_late_us"):
        assert got[key]["max"] == want[key]["max"], key
        for q in ("p50", "p99"):  # to 1 % or 0.1 us
            assert_allclose(got[key][q], want[key][q], rtol=0.01, atol=0.1 + 1e-9, err_msg=key)
