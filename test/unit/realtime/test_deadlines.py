"""The realtime clock's scheduling arithmetic (servo_axis.realtime.deadlines), without ROS."""

from __future__ import annotations

import math

import numpy as np
from numpy.testing import assert_allclose

from servo_axis.realtime import deadlines as dl

P = 1_000_000  # 1 ms in ns
START = 5_000_000_000


def test_deadlines_are_absolute_and_do_not_drift_with_late_ticks() -> None:
    # Tick j is due at start + j T whatever the lateness of the ticks before.
    assert dl.deadline_ns(START, P, 0) == START
    assert dl.deadline_ns(START, P, 1000) == START + 1_000_000_000
    assert dl.deadline_ns(START, 400_000, 2501) == START + 1_000_400_000


def test_due_ticks_counts_the_ticks_a_stall_left_behind() -> None:
    assert dl.due_ticks(START + P - 1, START, P, 1) == 0  # 1 ns before d_1: wait
    assert dl.due_ticks(START + P, START, P, 1) == 1  # at d_1
    assert dl.due_ticks(START + P + 999_999, START, P, 1) == 1
    # Woken 3.5 periods after d_1: ticks 1, 2, 3 and 4 are due at once.
    assert dl.due_ticks(START + 4 * P + P // 2, START, P, 1) == 4
    # After they ran, tick 5 waits again.
    assert dl.due_ticks(START + 4 * P + P // 2, START, P, 5) == 0


def test_sleep_leaves_the_spin_margin_and_never_goes_negative() -> None:
    assert_allclose(dl.sleep_s(START, START + P, 200_000), 800e-6, rtol=0, atol=1e-12)
    assert dl.sleep_s(START + 900_000, START + P, 200_000) == 0.0
    assert dl.sleep_s(START + 2 * P, START + P, 200_000) == 0.0  # already late


def test_a_command_counts_only_if_it_arrived_by_the_deadline() -> None:
    assert dl.command_on_time(START + P, START + P)
    assert not dl.command_on_time(START + P + 1, START + P)  # the tick may run later
    assert not dl.command_on_time(None, START + P)


def test_misses_of_the_command_lateness_are_the_late_and_the_missing() -> None:
    late = np.array([150e3, 999_999, 1_000_000, 1_000_001, 2.5e6, np.nan, 400e3])
    # > one period: 1_000_001 and 2.5e6; never arrived: the NaN.
    assert dl.misses_of(late, P) == 3
    assert dl.misses_of(np.full(10, 300e3), P) == 0


def test_lateness_stats_in_us_leave_out_what_never_came() -> None:
    late_ns = np.concatenate([np.arange(1, 101) * 1000.0, [np.nan, np.nan]])
    stats = dl.lateness_stats(late_ns)
    assert stats is not None
    assert_allclose(stats["p50"], 50.5, rtol=0, atol=0.05)
    assert_allclose(stats["p99"], 99.0, rtol=0, atol=0.05)
    assert stats["max"] == 100.0
    assert dl.lateness_stats(np.array([np.nan])) is None


def test_timer_rate_is_one_for_a_clock_that_kept_time() -> None:
    assert_allclose(dl.timer_rate(1000, P, START, START + 1000 * P), 1.0, rtol=1e-12)
    assert_allclose(dl.timer_rate(1000, P, START, START + 1001 * P), 1000 / 1001, rtol=1e-12)
    assert math.isnan(dl.timer_rate(0, P, START, START))


def test_an_answer_is_useful_until_the_tick_after_next() -> None:
    start, period = 1_000, 1_000_000
    d = lambda k: dl.deadline_ns(start, period, k)  # noqa: E731
    # command[7] counts for tick 8, and is held from tick 9 only if in before d_9.
    assert dl.answer_useful(d(7) + 10, start, period, 7, 6, 5)
    assert dl.answer_useful(d(9) - 1, start, period, 7, 6, 5)
    assert not dl.answer_useful(d(9), start, period, 7, 6, 5)
    # ... but never more than max_gap - 1 states in a row go unanswered.
    assert dl.answer_useful(d(30), start, period, 7, 2, 5)
    assert not dl.answer_useful(d(30), start, period, 7, 3, 5)


def simulate_backlog(
    *, stall_periods: int, answer_cost: float, skip_cost: float, useful: bool
) -> tuple[list[int], int | None]:
    """A controller that stalls, then works off the states queued meanwhile.

    State ``k`` goes out at ``d_k = k T``; the controller takes them in order,
    an answer costs ``answer_cost`` periods, a skipped state ``skip_cost``.
    Returns the answered steps and the first state after the stall whose
    answer is on time (in by ``d_{k+1}``), or None.
    """
    period = 1_000_000
    now = stall_periods * period  # woke up: states 0 .. stall_periods are queued
    answered: list[int] = []
    last = -1
    first_on_time = None
    for k in range(stall_periods + 200):
        now = max(now, k * period)  # state k is not out before d_k
        if k == 0 or not useful or dl.answer_useful(now, 0, period, k, last, 5):
            now += round(answer_cost * period)
            answered.append(k)
            last = k
            if k > 0 and now <= (k + 1) * period and first_on_time is None:
                first_on_time = k
        else:
            now += round(skip_cost * period)
    return answered, first_on_time


def test_skipping_unusable_answers_catches_up_after_a_stall() -> None:
    # 30 periods stalled; an answer costs 0.6 T (publish), a skip 0.1 T (decode).
    answered, on_time = simulate_backlog(
        stall_periods=30, answer_cost=0.6, skip_cost=0.1, useful=True
    )
    assert on_time is not None
    # The backlog drains at 1 - c T per state, c the mean cost of a state:
    # one answer in every 5 (0.6 + 4 x 0.1 = 1.0 T per 5 states, 0.2 T each),
    # so the 30 queued periods are gone after about 30 / 0.8 = 37.5 states.
    assert abs(on_time - 30 / (1 - (0.6 + 4 * 0.1) / 5)) <= 3
    gaps = np.diff(answered)
    assert gaps.max() <= 5
    # Answering every state, the same controller gains only 1 - 0.6 T per
    # state: on time again after about 30 / 0.4 = 75 states, twice as late.
    _, always = simulate_backlog(stall_periods=30, answer_cost=0.6, skip_cost=0.1, useful=False)
    assert always is not None
    assert abs(always - 30 / (1 - 0.6)) <= 3


def test_the_start_estimate_is_never_before_the_clock_start() -> None:
    # d_0 is when command[0] reached the plant; state[0] went out before it.
    rng = np.random.default_rng(7)
    period, d0 = 400_000, START
    latency = rng.integers(60_000, 900_000, size=500)  # tick lateness + transit, ns
    latency[137] = 41_000  # the least one
    estimate = dl.start_estimate_ns(None, d0 - 300_000, 0, period)  # state[0]: no estimate
    assert estimate is None
    for k in range(1, 500):
        estimate = dl.start_estimate_ns(estimate, d0 + k * period + int(latency[k]), k, period)
        assert estimate is not None and estimate >= d0
    assert estimate == d0 + 41_000


def test_an_on_time_controller_answers_every_state_with_the_estimate() -> None:
    # State k arrives 250 us after its tick (the suite's median at 0.4 ms).
    # Taking d_0 as when state[0] was answered, 1 ms before the plant had
    # command[0], every state looked more than 2 periods late: only every
    # 5th was answered. With the estimate from the arrivals, all of them.
    period, d0, late = 400_000, START, 250_000

    def answered(start_of: object) -> int:
        estimate, last, count = None, 0, 0
        for k in range(1, 1001):
            now = d0 + k * period + late
            if start_of == "arrivals":
                estimate = dl.start_estimate_ns(estimate, now, k, period)
            else:
                estimate = d0 - 1_000_000
            if dl.answer_useful(now, estimate, period, k, last, 5):
                last, count = k, count + 1
        return count

    assert answered("arrivals") == 1000
    assert answered("state 0") == 200


def _histogram_of(samples: np.ndarray) -> dl.LatenessHistogram:
    hist = dl.LatenessHistogram()
    for x in samples:
        hist.add(int(x))
    return hist


def test_the_lateness_histogram_gives_numpys_percentiles_to_its_resolution() -> None:
    rng = np.random.default_rng(40)
    series = {
        # A timer's lateness: tens of us, a heavy tail, one stall of 75 ms.
        "exponential with a stall": np.append(rng.exponential(20_000.0, 20_000), 75_000_000),
        "below 10 us": rng.uniform(0.0, 10_000.0, 5_000),
        "lognormal over 6 decades": rng.lognormal(10.0, 3.0, 10_000),
        "few samples": np.array([300.0, 1_500.0, 900.0, 2_500.0]),
        "one sample": np.array([12_345.0]),
    }
    for name, samples in series.items():
        samples = np.round(samples)
        hist = _histogram_of(samples)
        assert hist.count == samples.size, name
        assert hist.min_ns == samples.min() and hist.max_ns == samples.max(), name
        assert_allclose(hist.mean_ns, samples.mean(), rtol=1e-12, err_msg=name)
        for q in (0.0, 1.0, 50.0, 90.0, 99.0, 99.9, 100.0):
            # 1 % (the bins' width) or 100 ns (the bin below 100 ns).
            assert_allclose(
                hist.percentile(q),
                np.percentile(samples, q),
                rtol=dl.LATENESS_RELATIVE_RESOLUTION,
                atol=dl.LATENESS_FLOOR_NS,
                err_msg=f"{name}: p{q}",
            )
        stats, exact = hist.stats(), dl.lateness_stats(samples)
        assert stats is not None and exact is not None and stats.keys() == exact.keys()
        assert stats["max"] == exact["max"], name
        for key in ("p50", "p99"):  # us, rounded to 0.1 us
            assert_allclose(stats[key], exact[key], rtol=0.01, atol=0.1 + 1e-9, err_msg=name)


def test_negative_lateness_is_counted_and_bounded() -> None:
    samples = np.array([-400, -100, -50, 20_000, 30_000])
    hist = _histogram_of(samples)
    assert hist.count == 5 and hist.min_ns == -400 and hist.max_ns == 30_000
    assert -400 <= hist.percentile(25.0) < 0  # numpy: -100
    assert_allclose(hist.percentile(100.0), 30_000)
    assert_allclose(hist.percentile(75.0), 20_000, rtol=dl.LATENESS_RELATIVE_RESOLUTION)


def test_an_empty_lateness_histogram_has_no_figures() -> None:
    hist = dl.LatenessHistogram()
    assert hist.stats() is None and math.isnan(hist.percentile(50.0))
    assert math.isnan(hist.mean_ns) and hist.count == 0


def test_the_lateness_histogram_is_the_same_size_for_any_number_of_samples() -> None:
    import tracemalloc

    hist = dl.LatenessHistogram()
    for x in range(1, 2_000):  # every bin that these samples reach, once
        hist.add(x * 1_000)
    kept = []
    tracemalloc.start()
    try:
        for _ in range(2):
            before = tracemalloc.get_traced_memory()[0]
            for x in range(1, 20_000):
                hist.add(1_000 * (x % 2_000 + 1))
            kept.append(tracemalloc.get_traced_memory()[0] - before)
    finally:
        tracemalloc.stop()
    assert hist.count == 1_999 + 2 * 19_999
    # N samples, then N more: at most a few ints (count, sum), where a list
    # of 20k samples would be 160 kB.
    assert max(kept) < 500, kept
