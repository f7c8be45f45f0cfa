"""StreamGate: which stamps of a per-sample stream are taken (no ROS)."""

from __future__ import annotations

import pytest

from servo_axis.core.errors import SignalError
from servo_axis.wire.streams import EarlyCommands, StampOrigin, StreamGate, gated


def refused(gate: StreamGate, step: int, text: str) -> None:
    """``step`` is refused with ``text`` and the gate is left as it was."""
    before = (gate.last, gate.expected)
    with pytest.raises(SignalError, match=text):
        gate.accept(step)
    assert (gate.last, gate.expected) == before


def test_lockstep_gate_takes_exactly_the_next_step() -> None:
    gate = StreamGate()  # window 1, from step 0
    assert gate.expected == 0
    refused(gate, 1, "ahead")  # step 0 first
    gate.accept(0)
    gate.accept(1)
    assert gate.expected == 2
    refused(gate, 3, "ahead")  # a skipped step is not taken
    refused(gate, 1, "stale")  # a replay
    refused(gate, 0, "stale")
    gate.accept(2)
    assert gate.last == 2


def test_junk_far_ahead_or_behind_never_displaces_the_stream() -> None:
    gate = StreamGate()  # no limit: only the stream's own order refuses them
    for k in range(5):
        gate.accept(k)
    # A stranger's step + 1000, a stamp of 1e9 s (10**12 steps of 1 ms), a replay.
    for junk in (4 + 1000, 10**12, 2):
        with pytest.raises(SignalError):
            gate.accept(junk)
        assert gate.last == 4
    gate.accept(5)  # the real stream goes on
    assert gate.last == 5


def test_realtime_window_bounds_how_far_the_stream_may_jump() -> None:
    gate = StreamGate(window=3)
    gate.accept(2)  # within 3 of first - 1 = -1
    refused(gate, 6, "at most 5")
    gate.accept(5)  # two samples lost: taken
    refused(gate, 5, "stale")
    refused(gate, 9, "ahead")
    gate.accept(8)
    # A junk stamp inside the window displaces the stream by at most the window.
    assert gate.expected == 9


def test_stride_only_takes_the_stream_grid() -> None:
    gate = StreamGate(stride=2, limit=20)
    refused(gate, 1, "grid")
    gate.accept(0)
    refused(gate, 4, "ahead")  # the next is 2
    refused(gate, 3, "grid")
    gate.accept(2)
    assert gate.expected == 4
    wide = StreamGate(stride=2, window=2)
    wide.accept(2)  # first - stride = -2; 2 is within two samples
    refused(wide, 8, "at most 6")
    wide.accept(6)


def test_first_none_joins_a_running_stream_at_the_first_step_it_gets() -> None:
    gate = StreamGate(first=None, limit=100)
    assert gate.expected is None
    refused(gate, 100, "beyond")  # the limit holds before the first step too
    refused(gate, -1, "negative")
    gate.accept(57)
    assert gate.expected == 58
    refused(gate, 59, "ahead")
    gate.accept(58)
    joining = StreamGate(first=None, stride=2)
    refused(joining, 7, "grid")
    joining.accept(40)
    assert joining.expected == 42


def test_limit_is_the_first_step_beyond_the_stream() -> None:
    gate = StreamGate(limit=3)
    for k in range(3):
        gate.accept(k)
    refused(gate, 3, "beyond the run's last step 2")
    refused(gate, 10**9, "beyond")


def test_check_changes_nothing_and_parameters_are_checked() -> None:
    gate = StreamGate()
    gate.check(0)
    assert gate.last == -1 and gate.expected == 0
    for kwargs in ({"window": 0}, {"stride": 0}):
        with pytest.raises(ValueError):
            StreamGate(**kwargs)


def test_gated_keeps_what_the_gate_takes_in_arrival_order() -> None:
    items = [(0, "a"), (1000, "junk"), (1, "b"), (1, "replay"), (3, "gap"), (2, "c")]
    assert list(gated(items, StreamGate())) == [(0, "a"), (1, "b"), (2, "c")]


# -- a plant that owns its clock (issue 31) ------------------------------------------

T_NS = 1_000_000


def test_a_plant_clock_gives_one_step_per_state_from_the_first_stamp() -> None:
    """t_0 is the first stamp; a jitter of up to a period keeps one step per state; a stall
    leaves steps out; commands take their state's step by its stamp."""
    origin = StampOrigin(T_NS)
    t0 = 1_795_000_000_123_456_789  # a driver's ROS time, neither on the grid nor 0
    stamps = [t0, t0 + 1_400_000, t0 + 1_600_000, t0 + 3_000_000, t0 + 9_100_000]
    assert [origin.state_step(t) for t in stamps] == [0, 1, 2, 3, 9]
    assert origin.command_step(t0 + 1_600_000) == 2
    with pytest.raises(SignalError, match="not that of a state"):
        origin.command_step(t0 + 2_000_000)


def test_a_plant_clock_refuses_a_stamp_behind_or_ahead_of_its_arrival() -> None:
    origin = StampOrigin(T_NS, slack=10)
    origin.state_step(5 * T_NS, arrival_ns=0)
    assert origin.state_step(6 * T_NS, arrival_ns=T_NS) == 1
    with pytest.raises(SignalError, match="not after the last state's"):
        origin.state_step(6 * T_NS, arrival_ns=T_NS)
    with pytest.raises(SignalError, match="ahead of the plant's clock"):
        origin.state_step(5 * T_NS + 1000 * T_NS, arrival_ns=2 * T_NS)
    # the junk moved nothing: the real next state is taken
    assert origin.state_step(7 * T_NS, arrival_ns=2 * T_NS) == 2


def test_realtime_gate_takes_a_jump_the_wall_clock_allows_and_counts_what_it_skipped() -> None:
    """A node that fell behind takes the newest sample (issue 30); junk far ahead is refused."""
    import time

    period = 1_000_000  # 1 ms
    gate = StreamGate(window=10, first=0, period_ns=period)
    start = time.monotonic_ns()
    for step in range(0, 5):
        gate.accept(step)
    # The clock's start as the arrivals show it: step 4 arrived no earlier than d_4.
    time.sleep(0.2)  # 200 periods pass while the node is stopped
    with pytest.raises(SignalError, match="ahead of the stream"):
        gate.accept(4 + 100_000)  # a stranger's step + 100,000: beyond the wall clock
    assert gate.last == 4 and gate.skipped == 0
    now_step = (time.monotonic_ns() - start) // period
    gate.accept(now_step - 5)  # the newest sample after the stall
    assert gate.last == now_step - 5
    assert gate.skipped == now_step - 5 - 4 - 1 and gate.jumps == 1
    gate.accept(now_step - 3)  # a gap inside the window: counted, not a jump
    assert gate.skipped == now_step - 5 - 4 - 1 + 1 and gate.jumps == 1


def test_without_a_wall_clock_a_gate_refuses_every_jump_as_before() -> None:
    gate = StreamGate(window=10, first=0)
    gate.accept(0)
    with pytest.raises(SignalError, match="at most 10"):
        gate.accept(11)
    gate.accept(10)
    assert gate.skipped == 9 and gate.now_step() is None


def test_a_command_taken_before_its_state_waits_for_it() -> None:
    """The recorder's two callbacks in either order give every command its state's step;
    a command whose state cannot come any more is refused, at once or once a later state
    is taken."""
    origin = StampOrigin(1_000_000)
    early = EarlyCommands(origin, limit=3)
    t0 = 5_000_000_123  # a plant clock's own epoch
    assert early.step(t0) is None  # before any state
    assert early.step(t0 + 1_000_000) is None
    assert early.waiting == 2
    assert early.state_taken(t0, origin.state_step(t0)) == ([0], 0)
    assert early.step(t0) == 0  # its state is known now: at once
    # A junk stamp between two states is refused once the later state is taken.
    assert early.step(t0 + 1_500_000) is None
    s1 = origin.state_step(t0 + 1_000_000)
    assert early.state_taken(t0 + 1_000_000, s1) == ([1], 0)
    s2 = origin.state_step(t0 + 2_000_000)
    assert early.state_taken(t0 + 2_000_000, s2) == ([], 1)
    assert early.expired == 1 and early.waiting == 0
    with pytest.raises(SignalError, match="not that of a state taken"):
        early.step(t0 + 1_700_000)  # before the last state: it never will be
    for k in range(3):
        assert early.step(t0 + (10 + k) * 1_000_000) is None
    with pytest.raises(SignalError, match="3 commands already wait"):
        early.step(t0 + 20 * 1_000_000)
