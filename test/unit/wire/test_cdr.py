"""CDR decoders against an independent serialiser that needs no ROS (rosbags).

Every field must come back exactly: strings and ints equal, floats equal bit for
bit (so -0.0 and NaN payloads count), for both byte orders.
"""

from __future__ import annotations

import ast
import json
import math
import random
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import servo_axis.wire.cdr as cdr
from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import (
    ClockData,
    JointStateData,
    MultiArrayData,
    decode,
    decode_clock,
    decode_float64_multi_array,
    decode_joint_state,
)

JS = "sensor_msgs/msg/JointState"
FMA = "std_msgs/msg/Float64MultiArray"
CLOCK = "rosgraph_msgs/msg/Clock"

INT32_MIN, INT32_MAX, UINT32_MAX = -(2**31), 2**31 - 1, 2**32 - 1
SPECIAL = (
    0.0,
    -0.0,
    5e-324,  # smallest subnormal
    -2.225073858507201e-308,  # largest subnormal, negative
    2.2250738585072014e-308,  # smallest normal
    1.7976931348623157e308,
    -1.7976931348623157e308,
    -1e300,
    math.pi,
    math.inf,
    -math.inf,
    math.nan,
    struct.unpack("<d", struct.pack("<Q", 0x7FF0_0000_0000_0001))[0],  # a NaN with a payload
)
# Odd lengths and a multi-byte character: each string leaves a different padding
# before the uint32 or float64 after it.
NAMES = ("", "a", "ab", "abc", "abcd", "x_motor", "x_table_", "µ", "joint_with_a_long_name_9")
ENDIANS = pytest.mark.parametrize("little_endian", [True, False], ids=["le", "be"])


@pytest.fixture(scope="module")
def store() -> Any:
    from rosbags.typesys import Stores, get_typestore

    jazzy = getattr(Stores, "ROS2_JAZZY", None)
    return get_typestore(jazzy if jazzy is not None else Stores.ROS2_HUMBLE)


# ---------------------------------------------------------------- builders


def floats(values: tuple[float, ...] | list[float]) -> np.ndarray:
    return np.array(values, dtype=np.float64)


def bits(values: tuple[float, ...] | np.ndarray) -> bytes:
    """The IEEE 754 bits of a sequence of floats (exact comparison, NaN included)."""
    values = tuple(float(v) for v in values)
    return struct.pack(f"<{len(values)}d", *values)


def time_of(store: Any, sec: int, nanosec: int) -> Any:
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def joint_state(
    store: Any,
    *,
    sec: int = 0,
    nanosec: int = 0,
    frame_id: str = "",
    name: tuple[str, ...] = (),
    position: tuple[float, ...] = (),
    velocity: tuple[float, ...] = (),
    effort: tuple[float, ...] = (),
) -> Any:
    t = store.types
    return t[JS](
        header=t["std_msgs/msg/Header"](stamp=time_of(store, sec, nanosec), frame_id=frame_id),
        name=list(name),
        position=floats(position),
        velocity=floats(velocity),
        effort=floats(effort),
    )


def multi_array(
    store: Any, dims: list[tuple[str, int, int]], data_offset: int, data: tuple[float, ...]
) -> Any:
    t = store.types
    layout = t["std_msgs/msg/MultiArrayLayout"](
        dim=[
            t["std_msgs/msg/MultiArrayDimension"](label=label, size=size, stride=stride)
            for label, size, stride in dims
        ],
        data_offset=data_offset,
    )
    return t[FMA](layout=layout, data=floats(data))


def clock(store: Any, sec: int, nanosec: int) -> Any:
    return store.types[CLOCK](clock=time_of(store, sec, nanosec))


def serialize(store: Any, msg: Any, type_name: str, little_endian: bool) -> bytes:
    data = bytes(store.serialize_cdr(msg, type_name, little_endian=little_endian))
    assert data[:2] == (b"\x00\x01" if little_endian else b"\x00\x00")
    return data


# ------------------------------------------------------------- comparisons


def stamp_ns(t: Any) -> int:
    return int(t.sec) * 1_000_000_000 + int(t.nanosec)


def assert_joint_state(got: JointStateData, msg: Any) -> None:
    assert type(got) is JointStateData
    assert got.stamp_ns == stamp_ns(msg.header.stamp)
    assert got.frame_id == msg.header.frame_id
    assert got.name == tuple(msg.name)
    for field in ("position", "velocity", "effort"):
        value = getattr(got, field)
        assert type(value) is tuple and all(type(v) is float for v in value), field
        assert bits(value) == bits(getattr(msg, field)), field


def assert_multi_array(got: MultiArrayData, msg: Any) -> None:
    assert type(got) is MultiArrayData
    assert got.labels == tuple(d.label for d in msg.layout.dim)
    assert got.sizes == tuple(d.size for d in msg.layout.dim)
    assert got.strides == tuple(d.stride for d in msg.layout.dim)
    assert got.data_offset == msg.layout.data_offset
    assert type(got.data) is tuple and bits(got.data) == bits(msg.data)


# -------------------------------------------------------------- round trips

JOINT_STATES: dict[str, dict[str, Any]] = {
    "empty": {},
    "one_joint": {"sec": 12, "nanosec": 345, "frame_id": "base", "name": ("x",),
                  "position": (1.5,), "velocity": (-2.0,), "effort": (0.25,)},
    "odd_names": {"sec": 1_700_000_000, "nanosec": 999_999_999, "frame_id": "abc",
                  "name": NAMES, "position": tuple(range(len(NAMES))),
                  "velocity": SPECIAL[: len(NAMES)], "effort": ()},
    "special_floats": {"frame_id": "a", "name": ("µm",), "position": SPECIAL,
                       "velocity": (), "effort": tuple(-v for v in SPECIAL)},
    "unequal_lengths": {"frame_id": "ab", "name": ("x_motor", "x_table"),
                        "position": (1.0, 2.0, 3.0), "velocity": (), "effort": (4.0,)},
    "int32_min_stamp": {"sec": INT32_MIN, "nanosec": UINT32_MAX, "frame_id": "abcd"},
    "int32_max_stamp": {"sec": INT32_MAX, "nanosec": 0, "frame_id": "µ" * 3},
    "names_only": {"name": ("a", "bc", "def")},
}  # fmt: skip


@ENDIANS
@pytest.mark.parametrize("case", list(JOINT_STATES))
def test_joint_state_round_trip(store: Any, case: str, little_endian: bool) -> None:
    msg = joint_state(store, **JOINT_STATES[case])
    data = serialize(store, msg, JS, little_endian)
    assert_joint_state(decode_joint_state(data), msg)
    assert_joint_state(decode(JS, data), msg)


MULTI_ARRAYS: dict[str, tuple[list[tuple[str, int, int]], int, tuple[float, ...]]] = {
    "empty": ([], 0, ()),
    "data_only": ([], 0, (1.0, -0.0, 5e-324)),
    "two_dims": ([("step", 3, 9), ("position_m,velocity_mps,current_A", 3, 3)], 2,
                 tuple(float(i) / 7 for i in range(9))),
    "odd_labels": ([(label, i, 2 * i + 1) for i, label in enumerate(NAMES)], 5, SPECIAL),
    "uint32_extremes": ([("", UINT32_MAX, 0), ("ab", 0, UINT32_MAX)], UINT32_MAX, (math.inf,)),
}  # fmt: skip


@ENDIANS
@pytest.mark.parametrize("case", list(MULTI_ARRAYS))
def test_float64_multi_array_round_trip(store: Any, case: str, little_endian: bool) -> None:
    msg = multi_array(store, *MULTI_ARRAYS[case])
    data = serialize(store, msg, FMA, little_endian)
    assert_multi_array(decode_float64_multi_array(data), msg)
    assert_multi_array(decode(FMA, data), msg)


@ENDIANS
@pytest.mark.parametrize(
    ("sec", "nanosec"), [(0, 0), (1, 2), (1_700_000_000, 999_999_999), (INT32_MIN, UINT32_MAX)]
)
def test_clock_round_trip(store: Any, sec: int, nanosec: int, little_endian: bool) -> None:
    data = serialize(store, clock(store, sec, nanosec), CLOCK, little_endian)
    expected = ClockData(stamp_ns=sec * 1_000_000_000 + nanosec)
    assert decode_clock(data) == expected
    assert decode(CLOCK, data) == expected
    assert decode("rosgraph_msgs/Clock", data) == expected


def random_string(rng: random.Random) -> str:
    return "".join(rng.choice("abcxyz_09µ") for _ in range(rng.randrange(12)))


def random_floats(rng: random.Random) -> tuple[float, ...]:
    return tuple(
        rng.choice(SPECIAL) if rng.random() < 0.2 else rng.uniform(-1e6, 1e6)
        for _ in range(rng.randrange(6))
    )


@ENDIANS
def test_random_messages_round_trip(store: Any, little_endian: bool) -> None:
    """Many random shapes: every combination of paddings between fields occurs."""
    rng = random.Random(20240611)
    for _ in range(300):
        n = rng.randrange(5)
        msg = joint_state(
            store,
            sec=rng.randint(INT32_MIN, INT32_MAX),
            nanosec=rng.randint(0, UINT32_MAX),
            frame_id=random_string(rng),
            name=tuple(random_string(rng) for _ in range(n)),
            position=random_floats(rng),
            velocity=random_floats(rng),
            effort=random_floats(rng),
        )
        assert_joint_state(decode(JS, serialize(store, msg, JS, little_endian)), msg)
        dims = [
            (random_string(rng), rng.randint(0, UINT32_MAX), rng.randint(0, UINT32_MAX))
            for _ in range(rng.randrange(4))
        ]
        fma = multi_array(store, dims, rng.randint(0, UINT32_MAX), random_floats(rng))
        assert_multi_array(decode(FMA, serialize(store, fma, FMA, little_endian)), fma)


def test_bytes_like_payloads_and_trailing_padding_accepted(store: Any) -> None:
    msg = joint_state(store, frame_id="abc", name=("ab",), position=(1.0,))
    data = serialize(store, msg, JS, True)
    expected = decode_joint_state(data)
    for payload in (bytearray(data), memoryview(data), data + bytes(8), data + b"\xab\xcd"):
        assert decode_joint_state(payload) == expected  # type: ignore[arg-type]
    # the option bytes of the header carry no meaning for plain CDR
    assert decode_joint_state(data[:2] + b"\x00\x03" + data[4:]) == expected


def test_zero_length_string_is_empty() -> None:
    # Not valid CDR (the length counts the NUL), but tolerated as an empty string.
    zero = b"\x00\x01\x00\x00" + bytes(8) + bytes(4) + bytes(4 * 4)
    assert decode_joint_state(zero) == JointStateData(0, "", (), (), (), ())


# ------------------------------------------------------------------ errors


def payloads(store: Any) -> list[tuple[str, bytes]]:
    return [
        (JS, serialize(store, joint_state(store, **JOINT_STATES["odd_names"]), JS, True)),
        (JS, serialize(store, joint_state(store, **JOINT_STATES["unequal_lengths"]), JS, False)),
        (FMA, serialize(store, multi_array(store, *MULTI_ARRAYS["two_dims"]), FMA, True)),
        (FMA, serialize(store, multi_array(store, *MULTI_ARRAYS["odd_labels"]), FMA, False)),
        (CLOCK, serialize(store, clock(store, 5, 6), CLOCK, True)),
    ]


def test_every_truncation_raises_signal_error(store: Any) -> None:
    for type_name, data in payloads(store):
        for size in range(len(data)):
            with pytest.raises(SignalError, match=type_name) as info:
                decode(type_name, data[:size])
            message = str(info.value)
            if size < 4:
                assert "encapsulation header" in message, size
            else:
                assert "truncated" in message, (size, message)


def test_truncation_message_names_the_field(store: Any) -> None:
    data = serialize(store, joint_state(store, frame_id="abc", effort=(1.0, 2.0)), JS, True)
    with pytest.raises(SignalError, match=r"at effort: 2 elements need at least 16 bytes, 15 are"):
        decode_joint_state(data[:-1])
    # the count fits the bytes left, the 4 padding bytes before the float64 do not
    data = serialize(store, joint_state(store, name=("abcde",), position=(1.0,)), JS, True)
    assert len(data) == 4 + 40 + 8 + 8
    with pytest.raises(SignalError, match=r"truncated at position: needs 8 bytes at offset 44, "):
        decode_joint_state(data[:48])
    with pytest.raises(SignalError, match=r"truncated at header\.stamp\.sec"):
        decode_joint_state(data[:6])
    with pytest.raises(SignalError, match=r"truncated at clock\.nanosec"):
        decode_clock(data[:10])


@pytest.mark.parametrize(
    "header", [b"\x00\x02", b"\x00\x03", b"\x00\x07", b"\x01\x00", b"\xff\xff"]
)
def test_wrong_encapsulation_header(store: Any, header: bytes) -> None:
    for type_name, data in payloads(store):
        with pytest.raises(SignalError, match=f"encapsulation header {header.hex()}"):
            decode(type_name, header + data[2:])


def test_string_without_nul(store: Any) -> None:
    data = serialize(store, joint_state(store, frame_id="abc", name=("xy",)), JS, True)
    frame_nul = 4 + 8 + 4 + 3
    assert data[frame_nul] == 0
    with pytest.raises(SignalError, match=r"header\.frame_id .*NUL"):
        decode_joint_state(data[:frame_nul] + b"d" + data[frame_nul + 1 :])
    name_nul = data.index(b"xy\x00") + 2
    with pytest.raises(SignalError, match=r"name\[0\] .*NUL"):
        decode_joint_state(data[:name_nul] + b"z" + data[name_nul + 1 :])
    fma = serialize(store, multi_array(store, [("lbl", 1, 1)], 0, ()), FMA, False)
    label_nul = fma.index(b"lbl\x00") + 3
    with pytest.raises(SignalError, match=r"layout\.dim\[0\]\.label .*NUL"):
        decode_float64_multi_array(fma[:label_nul] + b"!" + fma[label_nul + 1 :])


def test_string_not_utf8(store: Any) -> None:
    data = serialize(store, joint_state(store, frame_id="abc"), JS, True)
    with pytest.raises(SignalError, match="frame_id is not UTF-8"):
        decode_joint_state(data.replace(b"abc\x00", b"a\xffc\x00"))


def test_huge_counts_are_rejected_before_allocating(store: Any) -> None:
    data = serialize(store, joint_state(store, frame_id="abc"), JS, True)
    position_count = 4 + 8 + 8 + 4  # header, stamp, "abc" string, name count
    for count in (2**32 - 1, 2**31, 10_000):
        bad = data[:position_count] + struct.pack("<I", count) + data[position_count + 4 :]
        with pytest.raises(SignalError, match=f"position: {count} elements"):
            decode_joint_state(bad)
    name_count = 4 + 8 + 8
    bad = data[:name_count] + struct.pack("<I", 2**32 - 1) + data[name_count + 4 :]
    with pytest.raises(SignalError, match="name: 4294967295 elements"):
        decode_joint_state(bad)


DECODERS: list[tuple[str, Callable[[bytes], Any]]] = [
    (JS, decode_joint_state),
    (FMA, decode_float64_multi_array),
    (CLOCK, decode_clock),
]


def test_garbage_raises_only_signal_error(store: Any) -> None:
    """Random bytes and bit flips: a result or a SignalError, never anything else."""
    rng = random.Random(5)
    samples = [rng.randbytes(rng.randrange(64)) for _ in range(2000)]
    samples += [b"\x00" + bytes([rng.randrange(2)]) + s[2:] for s in samples]
    for _type_name, data in payloads(store):
        for _ in range(500):
            flipped = bytearray(data)
            for _ in range(rng.randrange(1, 4)):
                flipped[rng.randrange(4, len(data))] ^= 1 << rng.randrange(8)
            samples.append(bytes(flipped))
    for data in samples:
        for _type_name, decoder in DECODERS:
            try:
                decoder(data)
            except SignalError:
                pass


def test_decode_rejects_unknown_types_and_non_bytes(store: Any) -> None:
    data = serialize(store, clock(store, 1, 2), CLOCK, True)
    for type_name in ("sensor_msgs/msg/Imu", "Clock", "", "rosgraph_msgs/msg/Clock/x", None):
        with pytest.raises(SignalError, match="no CDR decoder"):
            decode(type_name, data)  # type: ignore[arg-type]
    assert decode("sensor_msgs/JointState", serialize(store, joint_state(store), JS, True))
    for value in ("0001", 12, None, [0, 1, 0, 0]):
        with pytest.raises(SignalError, match="bytes-like"):
            decode_clock(value)  # type: ignore[arg-type]
    assert set(cdr.SUPPORTED_TYPES) == {JS, FMA, CLOCK}


def test_results_are_frozen(store: Any) -> None:
    got = decode_joint_state(serialize(store, joint_state(store, name=("a",)), JS, True))
    with pytest.raises(AttributeError):
        got.frame_id = "x"  # type: ignore[misc]
    assert hash(got) == hash(JointStateData(0, "", ("a",), (), (), ()))


# ------------------------------------------------------------------ imports


@pytest.mark.parametrize("module", ["cdr", "checks", "layouts", "topics"])
def test_module_imports_only_the_standard_library_and_pure_wire_modules(module: str) -> None:
    """The decoders and the layouts they are checked by need nothing but the standard library."""
    path = Path(cdr.__file__).with_name(f"{module}.py")
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0
            names = [node.module or ""]
        else:
            continue
        allowed = (
            "__future__",
            "servo_axis.core.errors",
            "servo_axis.wire",
            "servo_axis.wire.checks",
            "servo_axis.wire.layouts",
            "servo_axis.wire.topics",
        )
        for name in names:
            assert name.split(".")[0] in sys.stdlib_module_names or name in allowed, name


def test_decoding_loads_no_ros_module(store: Any) -> None:
    data = serialize(store, joint_state(store, frame_id="abc", position=(1.0,)), JS, True)
    script = f"""
import json, sys
from servo_axis.wire.cdr import decode
d = decode("{JS}", bytes.fromhex("{data.hex()}"))
print(json.dumps([d.frame_id, d.position, sorted(sys.modules)]))
"""
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    frame_id, position, modules = json.loads(result.stdout)
    assert (frame_id, position) == ("abc", [1.0])
    ros = ("rclpy", "rosidl", "sensor_msgs", "std_msgs", "builtin_interfaces", "rosgraph_msgs")
    assert [m for m in modules if m.split(".")[0].startswith(ros)] == []
