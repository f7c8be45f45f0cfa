"""The per-sample JointState codec against an independent serialiser (rosbags) and the general decoder.

What the codec encodes must be the bytes a publisher of the message would
send (rosbags, like Fast DDS's publish, writes zero padding; rclpy's
``serialize_message`` leaves whatever was in its buffer there), and what it
decodes must be what the general path (:func:`decode_joint_state` then the
layout's checks) gives: the same sample, or the same error.
"""

from __future__ import annotations

import math
import random
import struct
from typing import Any

import numpy as np
import pytest

from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import decode_float64_multi_array, decode_joint_state
from servo_axis.wire.layouts import LAYOUTS, ArrayLayout, JointLayout
from servo_axis.wire.sample_cdr import ArrayCodec, JointCodec
from servo_axis.wire.streams import ARRAY_CODECS, JOINT_STREAMS

JS = "sensor_msgs/msg/JointState"
PERIOD_NS = 400_000
AXES = ("x", "tilt", "abc", "µ")  # each leaves a different padding after the names
JOINT_TOPICS = pytest.mark.parametrize("topic", sorted(JOINT_STREAMS))


@pytest.fixture(scope="module")
def store() -> Any:
    from rosbags.typesys import Stores, get_typestore

    jazzy = getattr(Stores, "ROS2_JAZZY", None)
    return get_typestore(jazzy if jazzy is not None else Stores.ROS2_HUMBLE)


def sample_of(layout: JointLayout[Any], step: int, rng: random.Random) -> Any:
    return layout.sample(step, *(rng.uniform(-1e3, 1e3) for _ in layout.values))


def payload(
    store: Any,
    layout: JointLayout[Any],
    sample: Any,
    axis: str,
    *,
    little_endian: bool = True,
    frame_id: str = "",
    period_ns: int = PERIOD_NS,
    names: list[str] | None = None,
    values: dict[str, list[float]] | None = None,
) -> bytes:
    """The message of ``sample`` as rosbags serialises it (what a foreign publisher sends)."""
    t = store.types
    ns = sample.step * period_ns
    given = dict(zip(layout.values, layout.value_getter()(sample), strict=True))
    n = len(layout.joints)
    arrays = {
        array: [given[f] for f in getattr(layout, array)] if array in layout.arrays else []
        for array in ("position", "velocity", "effort")
    }
    arrays.update(values or {})
    assert all(len(v) in (0, n) or values for v in arrays.values())
    msg = t[JS](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
            frame_id=frame_id,
        ),
        name=layout.names(axis) if names is None else names,
        **{a: np.array(v, dtype=np.float64) for a, v in arrays.items()},
    )
    return bytes(store.serialize_cdr(msg, JS, little_endian=little_endian))


def general(layout: JointLayout[Any], data: bytes, axis: str) -> Any:
    """What every subscriber took before the codec: the sample or the error's text."""
    try:
        msg = decode_joint_state(data)
        return layout.decode(msg.name, msg, msg.stamp_ns, axis, PERIOD_NS)
    except SignalError as err:
        return f"SignalError: {err}"


def fast(codec: JointCodec[Any], data: bytes) -> Any:
    try:
        return codec.decode(data)
    except SignalError as err:
        return f"SignalError: {err}"


@JOINT_TOPICS
@pytest.mark.parametrize("axis", AXES)
def test_encode_gives_the_bytes_of_the_message_and_decode_takes_them_back(
    store: Any, topic: str, axis: str
) -> None:
    layout = JOINT_STREAMS[topic]
    codec = JointCodec(layout, axis=axis, period_ns=PERIOD_NS)
    rng = random.Random(f"{topic}/{axis}")
    for step in (0, 1, 2499, 2500, 123_457, 2**31 // 1000):
        sample = sample_of(layout, step, rng)
        data = codec.encode(sample)
        assert data == payload(store, layout, sample, axis)
        assert len(data) == codec.size
        assert codec.decode(data) == sample
        assert general(layout, data, axis) == sample


@JOINT_TOPICS
def test_any_other_payload_is_decoded_and_refused_as_before(store: Any, topic: str) -> None:
    layout = JOINT_STREAMS[topic]
    axis = "x"
    codec = JointCodec(layout, axis=axis, period_ns=PERIOD_NS)
    rng = random.Random(topic)
    sample = sample_of(layout, 77, rng)
    good = codec.encode(sample)
    n = len(layout.joints)
    first = layout.arrays[0]
    cases = {
        "big-endian": payload(store, layout, sample, axis, little_endian=False),
        "frame_id": payload(store, layout, sample, axis, frame_id="base_link"),
        "padded": good + b"\x00" * 8,
        "options": good[:2] + b"\x12\x34" + good[4:],
        "short": good[:-1],
        "empty": b"",
        "header only": good[:4],
        "garbage": bytes(rng.randrange(256) for _ in range(len(good))),
        "other axis": JointCodec(layout, axis="y", period_ns=PERIOD_NS).encode(sample),
        "wrong names": payload(
            store, layout, sample, axis, names=[*layout.names(axis)[1:], "x_other"]
        ),
        "off the grid": payload(store, layout, sample, axis, period_ns=PERIOD_NS + 1),
        "one value short": payload(store, layout, sample, axis, values={first: [1.0] * (n - 1)}),
        "an unused array filled": payload(
            store,
            layout,
            sample,
            axis,
            values={
                next(
                    (a for a in ("position", "velocity", "effort") if a not in layout.arrays),
                    first,
                ): [0.5] * (n + 1)
            },
        ),
    }
    for bad in (math.nan, math.inf, -math.inf, 1e308):
        values = [bad] + [1.0] * (n - 1)
        cases[f"{first}[0]={bad}"] = payload(store, layout, sample, axis, values={first: values})
    if len(layout.values) > 1:
        # Finite each, but a sum beyond the doubles: no physical signal.
        cases["huge"] = payload(
            store, layout, sample, axis, values={a: [1.7e308] * n for a in layout.arrays}
        )
    outcome = {}
    for name, data in cases.items():
        outcome[name] = expected = general(layout, data, axis)
        assert fast(codec, data) == expected, name
    # Another publisher's shapes of the same message pass as the sample; junk
    # is refused (with the general path's error, compared above).
    for name in ("big-endian", "frame_id", "padded", "options"):
        assert outcome[name] == sample, name
    refused = {name for name, got in outcome.items() if isinstance(got, str)}
    assert refused >= {
        "short",
        "empty",
        "header only",
        "garbage",
        "other axis",
        "wrong names",
        "off the grid",
        "one value short",
        f"{first}[0]=nan",
        f"{first}[0]=inf",
        f"{first}[0]=-inf",
    }


def test_encode_refuses_what_a_message_cannot_carry() -> None:
    layout = JOINT_STREAMS["state"]
    codec = JointCodec(layout, axis="x", period_ns=PERIOD_NS)
    values = [0.0] * len(layout.values)
    values[len(layout.joints) + 1] = math.nan  # velocity[1]
    with pytest.raises(SignalError, match=r"velocity\[1\]: expected a finite number, got nan"):
        codec.encode(layout.sample(3, *values))
    with pytest.raises(SignalError, match="too large"):
        codec.encode(layout.sample(3, *([1.7e308] * len(layout.values))))
    for period in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="period_ns: expected a whole number"):
            JointCodec(layout, axis="x", period_ns=period)  # type: ignore[arg-type]


def test_the_layout_of_an_encoded_state_is_cdr() -> None:
    # An independent reading of the bytes: header, stamp, frame_id, names,
    # and each array 8-byte aligned from the end of the header.
    layout = JOINT_STREAMS["state"]
    sample = layout.sample(2500, *range(1, 7))
    data = JointCodec(layout, axis="x", period_ns=PERIOD_NS).encode(sample)
    assert data[:4] == b"\x00\x01\x00\x00"
    assert struct.unpack_from("<iI", data, 4) == (1, 0)  # 2500 * 0.4 ms = 1 s
    assert struct.unpack_from("<I", data, 12)[0] == 1 and data[16] == 0
    assert data.count(b"x_motor\x00") == data.count(b"x_table\x00") == 1
    at = data.index(b"x_table\x00") + 8  # 52
    for array, start in zip(("position", "velocity", "effort"), (1.0, 3.0, 5.0), strict=True):
        at += -(at - 4) % 4
        assert struct.unpack_from("<I", data, at)[0] == 2, array
        at += 4
        at += -(at - 4) % 8
        assert struct.unpack_from("<2d", data, at) == (start, start + 1), array
        at += 16
    assert at == len(data)


# ------------------------------------------------- per-sample vectors of scalars


def array_payload(
    store: Any,
    labels: list[str],
    values: list[float],
    *,
    sizes: list[int] | None = None,
    data_offset: int = 0,
    little_endian: bool = True,
) -> bytes:
    t = store.types
    sizes = [1] * len(labels) if sizes is None else sizes
    msg = t["std_msgs/msg/Float64MultiArray"](
        layout=t["std_msgs/msg/MultiArrayLayout"](
            dim=[
                t["std_msgs/msg/MultiArrayDimension"](label=label, size=n, stride=n)
                for label, n in zip(labels, sizes, strict=True)
            ],
            data_offset=data_offset,
        ),
        data=np.array(values, dtype=np.float64),
    )
    return bytes(
        store.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray", little_endian=little_endian)
    )


def general_array(layout: ArrayLayout[Any], data: bytes) -> Any:
    try:
        msg = decode_float64_multi_array(data)
        return layout.sample_of(layout.values(msg.labels, msg.sizes, msg.data, msg.strides))
    except SignalError as err:
        return f"SignalError: {err}"


def fast_array(codec: ArrayCodec[Any], data: bytes) -> Any:
    try:
        return codec.decode(data)
    except SignalError as err:
        return f"SignalError: {err}"


@pytest.mark.parametrize("topic", sorted(ARRAY_CODECS))
def test_a_per_sample_vector_is_the_labelled_array_and_back(store: Any, topic: str) -> None:
    layout = LAYOUTS[topic]
    assert isinstance(layout, ArrayLayout)
    codec = ArrayCodec(layout)
    rng = random.Random(topic)
    labels = list(layout.labels)
    for step in (0, 1, 77, 10**6):
        values = [float(step)] + [rng.uniform(-1.0, 1.0) for _ in labels[1:]]
        for i, f in enumerate(layout.fields):
            if f.rule == "flag":
                values[i] = float(rng.random() < 0.5)
        sample = layout.sample_of(values)
        data = codec.encode(sample)
        assert data == array_payload(store, labels, values) and len(data) == codec.size
        assert codec.decode(data) == sample == general_array(layout, data)
    good = codec.encode(sample)
    flag = next((i for i, f in enumerate(layout.fields) if f.rule == "flag"), None)
    cases = {
        "big-endian": array_payload(store, labels, values, little_endian=False),
        "data_offset": array_payload(store, labels, values, data_offset=3),
        "padded": good + b"\x00" * 4,
        "short": good[:-8],
        "empty": b"",
        "other labels": array_payload(store, [*labels[:-1], "other"], values),
        "a field of two": array_payload(
            store, labels, [*values, 0.0], sizes=[1] * (len(labels) - 1) + [2]
        ),
        "step not whole": array_payload(store, labels, [0.5, *values[1:]]),
        "step negative": array_payload(store, labels, [-1.0, *values[1:]]),
        "nan": array_payload(store, labels, [*values[:-1], math.nan]),
        "inf": array_payload(store, labels, [math.inf, *values[1:]]),
    }
    if flag is not None:
        cases["flag 0.5"] = array_payload(store, labels, [*values[:flag], 0.5, *values[flag + 1 :]])
    outcome = {name: general_array(layout, data) for name, data in cases.items()}
    for name, data in cases.items():
        assert fast_array(codec, data) == outcome[name], name
    for name in ("big-endian", "data_offset", "padded"):
        assert outcome[name] == sample, name
    assert {n for n, got in outcome.items() if isinstance(got, str)} == set(cases) - {
        "big-endian",
        "data_offset",
        "padded",
    }
    with pytest.raises(SignalError, match=r"data\[1\]: expected a finite number"):
        codec.encode(layout.sample_of([5.0, math.nan, *values[2:]]))


def test_only_per_sample_vectors_of_scalars_have_an_array_codec() -> None:
    for name, layout in LAYOUTS.items():
        if isinstance(layout, ArrayLayout) and name not in ARRAY_CODECS:
            with pytest.raises(ValueError, match="expected a per-step vector of scalars"):
                ArrayCodec(layout)
