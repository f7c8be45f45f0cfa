"""Log times on the simulation timeline: stamps, the present, junk stamps."""

from __future__ import annotations

import struct

import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from servo_axis.core.errors import SignalError
from servo_axis.recording.timeline import MAX_LEAD_NS, MAX_STEP_NS, SimTimeline
from servo_axis.wire.cdr import clock_ns_from_cdr, decode_clock

MS = 1_000_000


def test_stamped_messages_are_logged_at_their_stamps_unstamped_at_the_present() -> None:
    tl = SimTimeline()
    assert tl.log_time(None) == 0  # nothing seen yet
    got = []
    for k in range(1, 2001):  # the plant's state, one per ms
        got.append(tl.log_time(k * MS, clock=True))
        if k % 50 == 0:
            got.append(tl.log_time(None))  # plant/status
        if k % 10 == 0:
            got.append(tl.log_time((k + 200) * MS))  # the reference, 200 steps ahead
    assert tl.now_ns == 2000 * MS
    assert got[:3] == [1 * MS, 2 * MS, 3 * MS]
    assert got.count(50 * MS) == 2  # state[50] and the status logged right after it
    # A stamp ahead of the present is logged at its stamp but does not move it.
    assert 2200 * MS in got and tl.log_time(None) == 2000 * MS


def test_junk_stamps_do_not_push_the_timeline() -> None:
    tl = SimTimeline()
    tl.log_time(5 * MS, clock=True)
    assert tl.log_time(10**9 * 10**9, clock=True) == 5 * MS  # a stranger's 1e9 s
    assert tl.log_time(10**9 * 10**9) == 5 * MS
    assert tl.log_time(-3 * MS, clock=True) == 5 * MS  # negative: never a log time
    assert tl.now_ns == 5 * MS
    # The bounds themselves: a step of at most 1 s moves it, a lead of 2.5 s is logged.
    assert tl.log_time(5 * MS + MAX_STEP_NS + 1, clock=True) == 5 * MS + MAX_STEP_NS + 1
    assert tl.now_ns == 5 * MS  # that was beyond the step: logged (within the lead), not moved
    assert tl.log_time(5 * MS + MAX_STEP_NS, clock=True) == 5 * MS + MAX_STEP_NS
    assert tl.now_ns == 5 * MS + MAX_STEP_NS
    now = tl.now_ns
    assert tl.log_time(now + MAX_LEAD_NS) == now + MAX_LEAD_NS
    assert tl.log_time(now + MAX_LEAD_NS + 1) == now
    assert tl.log_time(now - 1, clock=True) == now - 1  # late: its stamp, no step back
    assert tl.now_ns == now
    with pytest.raises(ValueError):
        SimTimeline(max_step_ns=-1)


def test_clock_is_read_in_place_in_both_byte_orders() -> None:
    for ns in (0, 1, 999_999_999, 12 * 10**9 + 345, 2**31 * 10**9 - 1):
        little = serialize_message(Clock(clock=Time(sec=ns // 10**9, nanosec=ns % 10**9)))
        assert clock_ns_from_cdr(little) == ns == decode_clock(little).stamp_ns
        big = b"\x00\x00\x00\x00" + struct.pack(">iI", ns // 10**9, ns % 10**9)
        assert clock_ns_from_cdr(big) == ns == decode_clock(big).stamp_ns
    for bad in (b"", b"\x00\x01\x00\x00" + bytes(7), b"\x01\x01\x00\x00" + bytes(8)):
        with pytest.raises(SignalError):
            clock_ns_from_cdr(bad)
    with pytest.raises(SignalError, match="nanosec"):
        clock_ns_from_cdr(b"\x00\x01\x00\x00" + struct.pack("<iI", 1, 10**9))


def test_recorder_reads_the_stamp_of_each_recorded_type() -> None:
    from servo_axis.nodes.recorder import stamp_reader

    js = JointState(name=["x_motor"], position=[1.0])
    js.header.stamp = Time(sec=3, nanosec=7)
    read_js = stamp_reader("sensor_msgs/msg/JointState")
    read_clock = stamp_reader("rosgraph_msgs/msg/Clock")
    assert read_js is not None and read_js(serialize_message(js)) == 3 * 10**9 + 7
    clock = serialize_message(Clock(clock=Time(sec=4, nanosec=9)))
    assert read_clock is not None and read_clock(clock) == 4 * 10**9 + 9
    assert stamp_reader("std_msgs/msg/Float64MultiArray") is None
