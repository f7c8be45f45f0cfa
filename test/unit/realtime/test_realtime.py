"""A node's realtime parts without ROS: its priority, the clock thread, its record, the held
set-point, catching up."""

from __future__ import annotations

import itertools
import math
import threading
import time

import numpy as np
import pytest

from host_load import RunQueueWait, said
from servo_axis.core.errors import SignalError
from servo_axis.realtime import deadlines
from servo_axis.realtime import scheduling as scheduling_module
from servo_axis.realtime.clock import (
    SLIP_MIN_NS,
    SLIP_PERIODS,
    ClockRecord,
    ClockThread,
)
from servo_axis.realtime.late import CatchUp, DriveSetPoint, HeldSetPoint
from servo_axis.realtime.scheduling import RECEIVE_THREAD, RealtimeScheduling, realtime_priority


def test_only_a_realtime_run_asks_for_a_priority_and_each_role_below_the_pair() -> None:
    assert realtime_priority(mode="lockstep", thread_priority=50, below=0) is None
    assert realtime_priority(mode="realtime", thread_priority=0, below=0) is None
    assert realtime_priority(mode="realtime", thread_priority=50, below=None) is None
    assert realtime_priority(mode="realtime", thread_priority=50, below=0) == 50
    assert realtime_priority(mode="realtime", thread_priority=50, below=2) == 48
    assert realtime_priority(mode="realtime", thread_priority=2, below=2) == 1  # at least 1


def test_the_priority_is_applied_once_when_the_run_starts() -> None:
    asked: list[int] = []
    warnings: list[str] = []

    def apply(priority: int) -> dict[str, object]:
        asked.append(priority)
        return {"policy": "fifo", "priority": priority}

    scheduling = RealtimeScheduling(49, warn=warnings.append, apply=apply, favour=lambda: 7)
    assert scheduling.applied is None and not scheduling.fifo and asked == []
    scheduling.start()
    scheduling.start()
    assert asked == [49] and scheduling.fifo
    # Under SCHED_FIFO the middleware's threads are set too (its receive threads at
    # middleware_priority, 0 here: at the default policy with the rest).
    assert scheduling.applied == {
        **apply(49),
        "middleware_priority": 0,
        "middleware_nice": -10,
        "middleware_threads": 7,
    }
    assert warnings == []


def test_a_refused_priority_leaves_the_default_scheduler_and_says_why() -> None:
    warnings: list[str] = []
    refused = {"policy": "other", "priority": 0, "refused": "PermissionError: no"}
    scheduling = RealtimeScheduling(
        50, warn=warnings.append, apply=lambda p: refused, favour=lambda: 1 / 0
    )
    scheduling.start()
    assert not scheduling.fifo and scheduling.applied == refused
    assert warnings == ["thread_priority 50: refused (PermissionError: no); the default scheduler"]
    never = RealtimeScheduling(None, warn=warnings.append, apply=lambda p: refused)
    never.start()
    assert never.applied is None and len(warnings) == 1


def test_the_clock_thread_ticks_in_order_never_before_a_deadline() -> None:
    period_ns = 2_000_000
    seen: list[tuple[int, int, int]] = []

    last = threading.Event()

    def tick(j: int, deadline_ns: int) -> bool:
        seen.append((j, deadline_ns, time.monotonic_ns()))
        if j == 20:
            last.set()
        return j == 20

    clock = ClockThread(period_ns=period_ns, tick=tick, name="test-clock")
    assert not clock.started
    start = time.monotonic_ns()
    clock.start(start)
    assert last.wait(5.0)
    time.sleep(5 * period_ns * 1e-9)  # no tick after the last one
    clock.stop(timeout_s=5.0)
    assert clock.started and clock.error is None
    assert [j for j, _, _ in seen] == list(range(1, 21))
    assert [d for _, d, _ in seen] == [start + j * period_ns for j in range(1, 21)]
    assert all(now >= d for _, d, now in seen)


def test_a_tick_that_raises_ends_the_clock_and_is_kept() -> None:
    def tick(j: int, deadline_ns: int) -> bool:
        raise ZeroDivisionError("model blew up")

    clock = ClockThread(period_ns=1_000_000, tick=tick, name="test-clock")
    clock.start(time.monotonic_ns(), priority=0)
    deadline = time.monotonic() + 5.0
    while clock.error is None and time.monotonic() < deadline:
        time.sleep(0.001)
    assert isinstance(clock.error, ZeroDivisionError)
    clock.stop(timeout_s=5.0)


def test_stop_ends_a_running_clock() -> None:
    ticks = threading.Event()

    def tick(j: int, deadline_ns: int) -> bool:
        ticks.set()
        return False  # never the last one

    clock = ClockThread(period_ns=1_000_000, tick=tick, name="test-clock")
    clock.start(time.monotonic_ns())
    assert ticks.wait(5.0)
    t0 = time.monotonic()
    host = RunQueueWait()
    clock.stop(timeout_s=5.0)
    # A tick and a 1 ms sleep at most, whatever a busy host withheld from the thread.
    elapsed, wait = time.monotonic() - t0, host.seconds()
    assert elapsed < 1.0 + wait and clock.error is None, said(elapsed, 1.0, wait)
    assert clock._thread is not None and not clock._thread.is_alive()  # ended, not timed out


def test_the_clock_record_counts_what_came_late_or_never_against_the_deadlines() -> None:
    period, start, steps = 1_000, 50_000, 6
    record = ClockRecord(steps=steps, period_ns=period)
    record.start_ns = start
    arrivals = {0: 300, 1: 1_500, 3: 900, 4: 2_500}  # ns after the tick of their state
    for k, late in arrivals.items():
        record.arrived(k, start + k * period + late)
    record.arrived(steps, start)  # beyond the run: not kept
    tick_late = [0, 40, 10, 3_000, 5, 20, 7]  # tick j (1..6) ran this late
    for j in range(1, steps + 1):
        record.ticked(j, start + j * period, start + j * period + tick_late[j])
    record.misses = 3
    report = record.report(steps, {"policy": "other", "priority": 0})
    late = np.array([arrivals.get(k, math.nan) for k in range(steps)])
    assert report["ticks"] == steps and report["misses"] == 3 and report["period_ns"] == period
    assert report["commands_missing"] == int(np.isnan(late).sum()) == 2
    assert report["commands_late"] == int(np.sum(late > period)) == 2
    # Streaming summaries: to 1 % or 0.1 us of what the whole series gives.
    for key, series in (("command_late_us", late), ("tick_late_us", tick_late[1:])):
        exact = deadlines.lateness_stats(series)
        assert exact is not None and report[key].keys() == exact.keys()
        for name, value in exact.items():
            np.testing.assert_allclose(report[key][name], value, rtol=0.01, atol=0.1 + 1e-9)
    assert report["timer_rate"] == deadlines.timer_rate(
        steps, period, start, start + steps * period + tick_late[steps]
    )
    assert report["scheduling"] == {"policy": "other", "priority": 0}


def test_a_drive_applies_the_command_on_time_else_holds_the_newest() -> None:
    """The sequence of test_realtime_plant_holds_the_newest_command_and_counts_misses,
    without a plant: the deadline of step k's tick is 1000 (k + 1)."""
    drive = HeldSetPoint()

    def deadline(step: int) -> int:
        return 1_000 * (step + 1)

    applied, on_time = [], []

    def tick(step: int) -> None:
        current, ok = drive.take(deadline(step), step)
        applied.append(current)
        on_time.append(ok)

    drive.check(0, 0)
    drive.arrived(0, 1.0, 500, 0)  # on time
    tick(0)
    tick(1)  # nothing came: the held 1.0
    drive.check(1, 2)
    drive.arrived(1, 2.0, 2_500, 2)  # after tick 1 ran, newer than the held: held from now
    tick(2)
    drive.check(3, 3)
    drive.arrived(3, 3.0, 3_500, 3)
    tick(3)
    with pytest.raises(SignalError, match=r"stale stamp \(step 2, expected 4\)"):
        drive.check(2, 4)  # older than the held one
    with pytest.raises(SignalError, match=r"future stamp \(step 5, expected 4\)"):
        drive.check(5, 4)
    tick(4)
    drive.check(5, 5)
    drive.arrived(5, 4.0, 5_900, 5)
    with pytest.raises(SignalError, match="a second command for step 5"):
        drive.check(5, 5)
    tick(5)
    assert applied == [1.0, 1.0, 2.0, 3.0, 3.0, 4.0]
    assert on_time == [True, False, False, True, False, True]


def test_a_command_that_came_before_the_tick_but_after_its_deadline_is_a_miss_yet_held() -> None:
    drive = HeldSetPoint()
    drive.arrived(0, 5.0, 1_200, 0)  # due at 1000: late, but the tick had not run
    current, ok = drive.take(1_000, 0)
    assert (current, ok) == (0.0, False)  # the miss applies the held value ...
    assert drive.held == 5.0 and drive.held_step == 0  # ... and the late one is held on


def test_a_drive_set_point_is_the_newest_held_and_misses_by_its_own_period() -> None:
    """A set-point period of 2 ticks (ros2_control at 500 Hz on a 1 kHz axis), publishing
    every cycle: a tick keeps its deadline while the newest set-point is at most 1.5
    periods old, and the newest one is applied even when it came after the deadline."""
    tick_ns, period_ns = 1_000, 2_000
    drive = DriveSetPoint(period_ns=period_ns, threshold_Nm=-1.0)
    assert drive.take(1 * tick_ns) == (0.0, False)  # nothing yet: zero current, a miss
    drive.arrived(1.0, 1_500)
    assert drive.take(2 * tick_ns) == (1.0, True)
    assert drive.take(3 * tick_ns) == (1.0, True)  # 1.5 us old: in time
    assert drive.take(4 * tick_ns) == (1.0, True)  # 2.5 us old: in time
    assert drive.take(5 * tick_ns) == (1.0, False)  # 3.5 us old: a miss, the held one
    drive.arrived(2.0, 5_200)  # after the deadline of tick 5, before tick 6's
    assert drive.take(6 * tick_ns) == (2.0, True)
    assert drive.report() == {"period_ns": 2_000, "received": 2, "unset": 0, "quiet_ticks": 0}


def test_a_drive_set_point_of_a_commander_silent_while_unchanged_is_held_not_missed() -> None:
    """threshold >= 0 (the plugin's default 1e-5): silence means "no change": after the
    first set-point a tick without a fresh one is held and counted, never a miss."""
    drive = DriveSetPoint(period_ns=1_000, threshold_Nm=1e-5)
    assert drive.silent_when_unchanged
    assert drive.take(1_000) == (0.0, False)  # before the first set-point: a miss
    drive.arrived(3.0, 1_500)
    assert [drive.take(d) for d in (2_000, 9_000, 60_000)] == [(3.0, True)] * 3
    assert drive.quiet_ticks == 2


def test_catching_up_skips_exactly_what_answer_useful_says() -> None:
    """After a stall the node answers only what can still be used, at least every
    ``gap`` steps and always the last: the same decisions as the core's rule."""
    period, gap, last = 1_000_000, 5, 60
    catch_up = CatchUp(period_ns=period, last_step=last, gap=gap)
    start = 10_000_000
    rng = np.random.default_rng(3)
    answered, expected = [], []
    estimate, last_answered = None, -1
    for k in range(last + 1):
        # Steps 20-40 arrive in one burst after a stall of 25 periods.
        arrival = start + (45 if 20 <= k <= 40 else k) * period + int(rng.integers(0, 300_000))
        now = arrival + 50_000
        catch_up.arrived(k, arrival)
        estimate = deadlines.start_estimate_ns(estimate, arrival, k, period)
        if catch_up.answer(k, now):
            answered.append(k)
        useful = (
            k >= last
            or estimate is None  # state[0]: nothing is known of the clock yet
            or deadlines.answer_useful(now, estimate, period, k, last_answered, gap)
        )
        if useful:
            expected.append(k)
            last_answered = k
    assert answered == expected
    assert catch_up.skipped == last + 1 - len(answered) > 0
    assert last in answered and max(np.diff(answered)) <= gap


def test_a_clock_far_behind_slips_to_the_next_deadline_instead_of_running_the_missed_ticks() -> (
    None
):
    """A tick that returns 150 periods late (the process was stopped) does not cause 150
    ticks back to back: the deadlines are re-based to the first one after now (issue 30)."""
    period_ns = 1_000_000
    stall_ns = 150 * period_ns  # beyond SLIP_PERIODS periods and SLIP_MIN_NS
    assert stall_ns > max(SLIP_PERIODS * period_ns, SLIP_MIN_NS)
    seen: list[tuple[int, int, int]] = []
    last = threading.Event()

    def tick(j: int, deadline_ns: int) -> bool:
        seen.append((j, deadline_ns, time.monotonic_ns()))
        if j == 3:
            time.sleep(stall_ns * 1e-9)
        if j == 10:
            last.set()
        return j == 10

    clock = ClockThread(period_ns=period_ns, tick=tick, name="test-clock")
    host = RunQueueWait()
    start = time.monotonic_ns()
    clock.start(start)
    assert last.wait(5.0)
    clock.stop(timeout_s=5.0)
    assert [j for j, _, _ in seen] == list(range(1, 11))
    slip_s, wait = max(SLIP_PERIODS * period_ns, SLIP_MIN_NS) * 1e-9, host.seconds()
    if clock.slips > 1 and wait > slip_s:
        # Only a thread kept from running for longer than the slip threshold slips
        # again; the host did that here (measured), not the clock.
        pytest.skip(
            f"this host kept the clock thread waiting for a CPU for {wait:.3f} s of the "
            f"run (slip threshold {slip_s:.3f} s): {clock.slips - 1} slip(s) beyond the stall's"
        )
    assert clock.slips == 1 and clock.slipped_periods >= 145
    # Tick 4 is due on the grid, after the stall: no earlier than when tick 3 returned.
    (_, d3, t3), (_, d4, _) = seen[2], seen[3]
    assert (d4 - start) % period_ns == 0 and d4 >= t3 + stall_ns - period_ns
    assert d4 - d3 == (clock.slipped_periods + 1) * period_ns
    # After it the ticks follow one period apart again.
    assert [b[1] - a[1] for a, b in itertools.pairwise(seen[3:])] == [period_ns] * 6
    assert all(now >= d for _, d, now in seen)


def test_the_receive_threads_stay_below_the_executor() -> None:
    def apply(priority: int) -> dict[str, object]:
        return {"policy": "fifo", "priority": priority}

    for executor, asked, got in ((50, 49, 49), (50, 60, 49), (10, 49, 9), (1, 49, 0), (50, 0, 0)):
        scheduling = RealtimeScheduling(
            executor, warn=print, apply=apply, favour=lambda: 0, middleware_priority=asked
        )
        assert scheduling.middleware_priority == got, (executor, asked)


def test_the_receive_threads_get_the_priority_below_the_executor_not_the_one_asked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    given: list[int] = []

    def favour(nice: int = 0, receive_priority: int = 0) -> int:
        given.append(receive_priority)
        return 4

    monkeypatch.setattr(scheduling_module, "favour_middleware_threads", favour)
    scheduling = RealtimeScheduling(
        10,
        warn=print,
        apply=lambda priority: {"policy": "fifo", "priority": priority},
        middleware_priority=49,
    )
    scheduling.start()
    assert given == [9]
    assert scheduling.applied is not None and scheduling.applied["middleware_threads"] == 4


def test_the_feedforward_and_its_receive_threads_run_below_the_pairs_receive_threads() -> None:
    from servo_axis.nodes.feedback import FeedbackNode
    from servo_axis.nodes.feedforward import FeedforwardNode
    from servo_axis.nodes.plant import PlantNode

    def apply(priority: int) -> dict[str, object]:
        return {"policy": "fifo", "priority": priority}

    for pair_priority in (50, 10, 3):
        pair = [
            RealtimeScheduling(
                realtime_priority(mode="realtime", thread_priority=pair_priority, below=node),
                warn=print,
                apply=apply,
                favour=lambda: 0,
                middleware_priority=49,
            )
            for node in (PlantNode.realtime_below, FeedbackNode.realtime_below)
        ]
        ff_priority = realtime_priority(
            mode="realtime", thread_priority=pair_priority, below=FeedforwardNode.realtime_below
        )
        assert ff_priority is not None
        ff = RealtimeScheduling(
            ff_priority, warn=print, apply=apply, favour=lambda: 0, middleware_priority=49
        )
        pair_receive = min(s.middleware_priority for s in pair)
        assert pair_receive == pair_priority - 1
        # Below the pair's receive threads, its own receive threads below it.
        assert ff_priority == max(1, pair_priority - 2) and ff_priority < pair_receive
        assert ff.middleware_priority < ff_priority or ff.middleware_priority == 0
    assert realtime_priority(mode="lockstep", thread_priority=50, below=2) is None


def test_only_fast_dds_receive_threads_are_receive_threads() -> None:
    # Thread names of a realtime plant on Jazzy's Fast DDS (summary.json's
    # realtime.scheduling.threads).
    receive = ["dds.shm.58663", "dds.shm.7001", "dds.udp.58662", "dds.udp.7001"]
    other = ["dds.asyn.0.0", "dds.ev.0", "dds.shm.wdog", "dds.gc", "plant-clock", "python"]
    assert [n for n in receive + other if RECEIVE_THREAD.fullmatch(n)] == receive


def test_the_clock_record_is_the_same_size_for_a_run_of_any_length() -> None:
    import tracemalloc

    sizes = []
    tracemalloc.start()
    try:
        for steps in (10, 36_000_000):  # and 10 h at 1 kHz
            before = tracemalloc.get_traced_memory()[0]
            record = ClockRecord(steps=steps, period_ns=1_000_000)
            sizes.append(tracemalloc.get_traced_memory()[0] - before)
            del record
    finally:
        tracemalloc.stop()
    assert abs(sizes[1] - sizes[0]) < 100 and sizes[0] < 200_000, sizes  # the int `steps`


def test_the_plants_per_step_path_keeps_nothing() -> None:
    """The plant model's step and the clock record's, called as the realtime tick
    calls them, N steps and N more: what the second N leave is not per step."""
    import tracemalloc
    from pathlib import Path

    from servo_axis.params import factories
    from servo_axis.params.resolve import Resolved
    from servo_axis.params.scenario import load_scenario

    path = Path(__file__).resolve().parents[3] / "config" / "ptc_friction.yaml"
    plant = factories.build_plant(Resolved(load_scenario(path), path).plant)
    period = 1_000_000
    record = ClockRecord(steps=10**7, period_ns=period)
    record.start_ns = start = 10**12

    def run(first: int, n: int) -> None:
        for k in range(first, first + n):
            deadline = start + (k + 1) * period
            record.ticked(k + 1, deadline, deadline + 7_000 + k % 300)
            plant.step(0.5 * math.sin(k * 1e-3))
            record.arrived(k + 1, deadline + 200_000 + k % 5_000)

    run(0, 3_000)  # compiled kernels, caches, every lateness bin these reach
    kept = []
    tracemalloc.start()
    try:
        for first in (3_000, 8_000):
            before = tracemalloc.get_traced_memory()[0]
            run(first, 5_000)
            kept.append(tracemalloc.get_traced_memory()[0] - before)
    finally:
        tracemalloc.stop()
    # 5,000 steps of 12 bytes each (the growth issue 40 measured) would be 60 kB.
    assert max(kept) < 2_000, kept
    assert record.tick_late.count == 13_000 and record.arrival_late.count == 13_000
