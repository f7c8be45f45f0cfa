"""CDR decoders against the payloads rclpy itself serialises (rmw_fastrtps).

``rclpy.serialization.serialize_message`` needs no ``rclpy.init``; its buffers
may end with padding bytes, which the decoders must ignore.
"""

from __future__ import annotations

import math
import random
import struct
from collections.abc import Sequence
from typing import Any

import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import (
    ClockData,
    decode,
    decode_clock,
    decode_float64_multi_array,
    decode_joint_state,
)

pytestmark = pytest.mark.ros

INT32_MIN, INT32_MAX, UINT32_MAX = -(2**31), 2**31 - 1, 2**32 - 1
SPECIAL = [
    0.0, -0.0, 5e-324, -2.225073858507201e-308, 1.7976931348623157e308, -1e300, math.pi,
    math.inf, -math.inf, math.nan,
]  # fmt: skip
NAMES = ["", "a", "ab", "abc", "abcd", "x_motor", "x_table_", "µ", "joint_with_a_long_name_9"]


def bits(values: Sequence[float]) -> bytes:
    """The IEEE 754 bits of a sequence of floats (exact comparison, NaN included)."""
    return struct.pack(f"<{len(values)}d", *(float(v) for v in values))


def stamp_ns(t: Time) -> int:
    return t.sec * 1_000_000_000 + t.nanosec


def joint_state(
    sec: int, nanosec: int, frame_id: str, name: list[str], *arrays: list[float]
) -> JointState:
    msg = JointState(name=name)
    msg.header.stamp = Time(sec=sec, nanosec=nanosec)
    msg.header.frame_id = frame_id
    msg.position, msg.velocity, msg.effort = arrays
    return msg


def check_joint_state(msg: JointState) -> None:
    for got in (decode_joint_state(serialize_message(msg)), decode(JS, serialize_message(msg))):
        assert got.stamp_ns == stamp_ns(msg.header.stamp)
        assert got.frame_id == msg.header.frame_id
        assert got.name == tuple(msg.name)
        assert bits(got.position) == bits(msg.position)
        assert bits(got.velocity) == bits(msg.velocity)
        assert bits(got.effort) == bits(msg.effort)


def multi_array(dims: list[tuple[str, int, int]], data_offset: int, data: list[float]) -> Any:
    msg = Float64MultiArray(data=data)
    msg.layout.dim = [MultiArrayDimension(label=lb, size=sz, stride=st) for lb, sz, st in dims]
    msg.layout.data_offset = data_offset
    return msg


def check_multi_array(msg: Float64MultiArray) -> None:
    for got in (
        decode_float64_multi_array(serialize_message(msg)),
        decode(FMA, serialize_message(msg)),
    ):
        assert got.labels == tuple(d.label for d in msg.layout.dim)
        assert got.sizes == tuple(d.size for d in msg.layout.dim)
        assert got.strides == tuple(d.stride for d in msg.layout.dim)
        assert got.data_offset == msg.layout.data_offset
        assert bits(got.data) == bits(msg.data)


JS = "sensor_msgs/msg/JointState"
FMA = "std_msgs/msg/Float64MultiArray"


def test_joint_states() -> None:
    check_joint_state(JointState())
    check_joint_state(joint_state(1, 2, "base", ["x"], [1.5], [-2.0], [0.25]))
    check_joint_state(joint_state(INT32_MIN, UINT32_MAX, "abc", NAMES, SPECIAL, [], SPECIAL[:3]))
    check_joint_state(joint_state(INT32_MAX, 0, "µ" * 3, ["ab", "cde"], [], [1.0, 2.0, 3.0], []))
    check_joint_state(joint_state(0, 0, "", [], [], [], [-0.0]))


def test_multi_arrays() -> None:
    check_multi_array(Float64MultiArray())
    check_multi_array(multi_array([("step", 3, 9), ("a,b,c", 3, 3)], 2, [i / 7 for i in range(9)]))
    check_multi_array(multi_array([(n, i, 2 * i + 1) for i, n in enumerate(NAMES)], 5, SPECIAL))
    check_multi_array(multi_array([("", UINT32_MAX, 0)], UINT32_MAX, [math.inf]))


@pytest.mark.parametrize(
    ("sec", "nanosec"), [(0, 0), (1, 2), (1_700_000_000, 999_999_999), (INT32_MIN, UINT32_MAX)]
)
def test_clocks(sec: int, nanosec: int) -> None:
    data = serialize_message(Clock(clock=Time(sec=sec, nanosec=nanosec)))
    expected = ClockData(stamp_ns=sec * 1_000_000_000 + nanosec)
    assert decode_clock(data) == expected == decode("rosgraph_msgs/msg/Clock", data)


def test_random_messages() -> None:
    rng = random.Random(11)

    def text() -> str:
        return "".join(rng.choice("abcxyz_09µ") for _ in range(rng.randrange(12)))

    def floats() -> list[float]:
        return [
            rng.choice(SPECIAL) if rng.random() < 0.2 else rng.uniform(-1e6, 1e6)
            for _ in range(rng.randrange(6))
        ]

    for _ in range(300):
        check_joint_state(
            joint_state(
                rng.randint(INT32_MIN, INT32_MAX),
                rng.randint(0, UINT32_MAX),
                text(),
                [text() for _ in range(rng.randrange(5))],
                floats(),
                floats(),
                floats(),
            )
        )
        dims = [
            (text(), rng.randint(0, UINT32_MAX), rng.randint(0, UINT32_MAX))
            for _ in range(rng.randrange(4))
        ]
        check_multi_array(multi_array(dims, rng.randint(0, UINT32_MAX), floats()))


def test_truncated_rclpy_payload_raises_signal_error() -> None:
    msg = joint_state(5, 6, "abc", ["x_motor", "x_table"], [1.0, 2.0], [3.0, 4.0], [5.0, 6.0])
    data = serialize_message(msg)
    # After the 4-byte header: stamp 8, "abc" 8, names 4 + 12 + 12 (to 44), position count
    # and data (to 64), velocity count, 4 padding bytes and data (to 88), effort likewise.
    content = 4 + 112
    assert len(data) >= content
    check_joint_state(msg)
    for size in range(content):
        with pytest.raises(SignalError):
            decode_joint_state(data[:size])
    assert decode_joint_state(data[:content]) == decode_joint_state(data)
