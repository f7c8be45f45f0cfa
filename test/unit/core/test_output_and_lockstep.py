"""The controlled-output function and the nodes' stepping logic, without ROS."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_axis.core.errors import ConfigError
from servo_axis.core.feedback.output import controlled_output
from servo_axis.nodes.lockstep import (
    REALTIME_WINDOW,
    FlowControl,
    PeerWatch,
    PeriodCollector,
    SampleBuffer,
    stream_window,
)


def test_controlled_output_picks_the_sensor() -> None:
    kw = {"encoder_rad": 2.0, "scale_m": 0.00382, "lead_m_per_rad": 1.91e-3}
    assert controlled_output("encoder", **kw) == 2.0
    assert controlled_output("scale", **kw) == pytest.approx(2.0, rel=1e-15)
    arrays = controlled_output(
        "scale", encoder_rad=np.zeros(3), scale_m=np.array([0.0, 1.91e-3, -3.82e-3]),
        lead_m_per_rad=1.91e-3,
    )  # fmt: skip
    np.testing.assert_allclose(arrays, [0.0, 1.0, -2.0], rtol=1e-15)
    with pytest.raises(ConfigError, match="sensor"):
        controlled_output("laser", **kw)


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
