"""The nodes' stepping logic without ROS: stream gates, peers, flow control, buffers."""

from __future__ import annotations

import math

import pytest

from servo_axis.core.errors import SignalError
from servo_axis.nodes.lockstep import (
    REALTIME_WINDOW,
    FlowControl,
    PeerWatch,
    PeriodCollector,
    SampleBuffer,
    stream_gate,
    stream_window,
    waited_too_long,
)


def test_stream_window_is_exactly_the_next_in_lockstep() -> None:
    assert stream_window(True) == 1
    assert stream_window(False) == REALTIME_WINDOW > 1


def test_peer_watch_times_a_gone_peer_and_remembers_a_lost_one() -> None:
    watch = PeerWatch()
    watch.look(False, 10.0)  # never seen: gone from the first look
    assert watch.gone_for(10.5) == 0.5 and watch.lost_at is None
    watch.look(True, 11.0)
    assert watch.gone_for(12.0) == 0.0  # alive: never "gone for" anything
    watch.look(False, 12.0)
    watch.look(False, 12.5)
    assert watch.gone_for(13.0) == 1.0 and watch.lost_at == 12.0
    watch.look(True, 13.0)  # back (a respawned peer): no longer gone, but it was lost
    assert watch.gone_for(14.0) == 0.0 and watch.lost_at == 12.0
    watch.forget()
    assert watch.lost_at is None


def test_flow_control_holds_the_plant_within_the_lag_and_to_the_end() -> None:
    flow = FlowControl(enabled=True, max_lag_steps=5, steps=20)
    assert not flow.ready and not flow.may_step_to(6)
    flow.acknowledge(0)
    assert flow.ready and flow.may_step_to(5) and not flow.may_step_to(6)
    flow.acknowledge(3)
    flow.acknowledge(1)  # an older acknowledgement does not move it back
    assert flow.may_step_to(8) and not flow.may_step_to(9)
    assert flow.may_step_to(20)  # past the last step: nothing more to publish
    assert not flow.complete
    flow.acknowledge(20)
    assert flow.complete
    off = FlowControl(enabled=False, max_lag_steps=1, steps=20)
    assert off.ready and off.may_step_to(19) and off.complete


def test_sample_buffer_and_period_collector() -> None:
    buf: SampleBuffer[str] = SampleBuffer()
    for k in (3, 4, 7):
        buf.put(k, f"s{k}")
    assert buf.take(4) == "s4" and buf.take(4) is None
    buf.drop_before(7)
    assert len(buf) == 1 and buf.take(7) == "s7"
    period = PeriodCollector(3)
    period.put(0, 1.0)
    period.put(2, -1.0)
    assert period.received == 2 and not period.complete
    error = period.restart()
    assert math.isnan(error[1]) and period.received == 0
    for i in range(3):
        period.put(i, float(i))
    assert period.complete


def test_a_node_takes_exactly_the_next_sample_in_lockstep_and_skips_a_few_in_realtime() -> None:
    exact = stream_gate(True, first=0, limit=100)
    exact.accept(0)
    with pytest.raises(SignalError, match="ahead of the stream"):
        exact.accept(2)
    exact.accept(1)
    ahead = stream_gate(False, first=0)
    ahead.accept(REALTIME_WINDOW - 1)  # the first may be up to a window in
    ahead.accept(2 * REALTIME_WINDOW - 1)
    with pytest.raises(SignalError, match="ahead of the stream"):
        ahead.accept(3 * REALTIME_WINDOW)
    assert ahead.last == 2 * REALTIME_WINDOW - 1  # a refused stamp moves nothing
    joining = stream_gate(True, first=None, stride=2, limit=10)
    joining.accept(6)  # a late joiner takes the first sample it gets
    with pytest.raises(SignalError, match="grid"):
        joining.accept(9)
    with pytest.raises(SignalError, match="beyond the run"):
        joining.accept(10)
    assert joining.expected == 8


def test_a_wait_ends_only_when_the_peer_is_gone_or_left_during_a_stall() -> None:
    def why(peer: PeerWatch, since: float, now: float, lockstep: bool = True) -> str | None:
        return waited_too_long(
            peer, waiting_since=since, timeout_s=1.0, now=now, name="unit", lockstep=lockstep
        )

    alive = PeerWatch()
    alive.look(True, 0.0)
    assert why(alive, 0.0, 100.0) is None  # lockstep: a live peer is waited for however long
    gone = PeerWatch()
    gone.look(False, 5.0)
    assert why(gone, 0.0, 6.0) is None  # gone for 1.0 s: not more than the timeout
    assert why(gone, 0.0, 6.5) == "the unit has been gone for 1.5 s"
    respawned = PeerWatch()
    respawned.look(True, 0.0)
    respawned.look(False, 3.0)  # lost at 3.0 ...
    respawned.look(True, 3.2)  # ... and back: it may not deliver what it owed
    assert why(respawned, 2.0, 3.9) is None  # still for 0.9 s since it left
    assert why(respawned, 3.5, 4.4) is None  # the plant moved at 3.5: still for 0.9 s
    text = why(respawned, 3.5, 4.6)
    assert text is not None and text.startswith("the unit went away during the wait")
    assert text.endswith("for 1.1 s")
    # Realtime: only the plant standing still counts, whether the peer lives or not.
    assert why(alive, 0.0, 0.9, lockstep=False) is None
    assert why(alive, 0.0, 1.25, lockstep=False) == "the plant stood still for 1.25 s"
