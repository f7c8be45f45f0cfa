"""Message conversions: round trips and rejection of bad messages (no ROS graph)."""

from __future__ import annotations

import math

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import SignalError
from servo_axis.wire import layouts
from servo_axis.wire import messages as msgs
from servo_axis.wire.streams import decode_joint_stream, decode_step_stream

PERIOD_NS = 1_000_000


def test_stamp_step_round_trip_is_exact() -> None:
    for step in (0, 1, 999, 1000, 123_456_789, 2**40):
        stamp = msgs.stamp_from_step(step, PERIOD_NS)
        assert 0 <= stamp.nanosec < 1_000_000_000
        assert stamp.sec * 1_000_000_000 + stamp.nanosec == step * PERIOD_NS
        assert msgs.step_from_stamp(stamp, PERIOD_NS) == step


def test_off_grid_stamp_rejected() -> None:
    stamp = msgs.stamp_from_step(5, PERIOD_NS)
    stamp.nanosec += 1
    with pytest.raises(SignalError, match="control grid"):
        msgs.step_from_stamp(stamp, PERIOD_NS)


def test_period_ns_requires_whole_nanoseconds() -> None:
    assert msgs.period_ns(1e-3) == 1_000_000
    assert msgs.period_ns(0.4e-3) == 400_000
    with pytest.raises(SignalError, match="period_s"):
        msgs.period_ns(1.5e-10)


@pytest.mark.parametrize(
    ("sample", "encode", "decode"),
    [
        (
            msgs.StateSample(7, 1.25e-3, 2.3875e-6, -0.5, -9.55e-4, 1.43, -1675.4),
            msgs.state_to_msg,
            msgs.state_from_msg,
        ),
        (msgs.CommandSample(3, -2.5), msgs.command_to_msg, msgs.command_from_msg),
        (
            msgs.ReferenceSample(1999, 5.2356, 65.8, 0.0123),
            msgs.reference_to_msg,
            msgs.reference_from_msg,
        ),
        (
            msgs.InputCorrectionSample(4321, -0.123456789),
            msgs.input_correction_to_msg,
            msgs.input_correction_from_msg,
        ),
        (
            msgs.CorrectionSample(12, -1e-7, 3e-5),
            msgs.correction_to_msg,
            msgs.correction_from_msg,
        ),
    ],
)
def test_round_trip_through_cdr(sample: object, encode: object, decode: object) -> None:
    msg = encode(sample, axis="x", period_ns_=PERIOD_NS)  # type: ignore[operator]
    wire = deserialize_message(serialize_message(msg), type(msg))
    assert decode(wire, axis="x", period_ns_=PERIOD_NS) == sample  # type: ignore[operator]
    assert all(name.startswith("x_") for name in wire.name)


@pytest.mark.parametrize("topic", sorted(layouts.JOINT_LAYOUTS))
def test_every_joint_layout_round_trips_through_rclpy_and_the_bag_decoder(topic: str) -> None:
    """Each value lands where the layout says; the node's and the bag's decoders agree."""
    layout = layouts.JOINT_LAYOUTS[topic]
    short = topic.rpartition("/")[2]
    to_msg = getattr(msgs, f"{short}_to_msg")
    write = getattr(msgs, f"write_{short}")
    from_msg = getattr(msgs, f"{short}_from_msg")
    values = [(-1) ** i * 0.25 * (i + 1) for i in range(len(layout.values))]
    sample = layout.sample(41, *values)
    msg = to_msg(sample, axis="z", period_ns_=PERIOD_NS)
    assert list(msg.name) == layout.names("z") == [f"z_{j}" for j in layout.joints]
    for array in ("position", "velocity", "effort"):
        assert list(getattr(msg, array)) == [getattr(sample, f) for f in getattr(layout, array)]
    assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == 41 * PERIOD_NS
    data = serialize_message(msg)
    assert from_msg(deserialize_message(data, JointState), axis="z", period_ns_=PERIOD_NS) == sample
    assert decode_joint_stream(topic, data, axis="z", period_ns=PERIOD_NS) == (41, sample)
    assert decode_step_stream(topic, data, axis="z", period_ns=PERIOD_NS)[0] == 41
    # A publisher's template refilled in place carries the same message.
    template = to_msg(layout.sample(0, *[0.0] * len(values)), axis="z", period_ns_=PERIOD_NS)
    assert write(template, sample, period_ns_=PERIOD_NS) is template
    assert from_msg(template, axis="z", period_ns_=PERIOD_NS) == sample
    assert template == msg
    with pytest.raises(SignalError, match=r"name: expected \['x_motor"):
        from_msg(msg, axis="x", period_ns_=PERIOD_NS)
    # The recorder's count refuses what the node refuses, with the same words.
    getattr(msg, layout.arrays[-1]).append(1.0)
    with pytest.raises(SignalError) as node_err:
        from_msg(msg, axis="z", period_ns_=PERIOD_NS)
    with pytest.raises(SignalError) as bag_err:
        decode_step_stream(topic, serialize_message(msg), axis="z", period_ns=PERIOD_NS)
    assert str(bag_err.value) == str(node_err.value)
    assert str(node_err.value).startswith(
        f"{layout.arrays[-1]}: expected {len(layout.joints)} values"
    )


def test_state_rejects_nan_wrong_length_and_wrong_names() -> None:
    good = msgs.state_to_msg(msgs.StateSample(1, 0, 0, 0, 0, 0, 0), axis="x", period_ns_=PERIOD_NS)
    bad = JointState(
        header=good.header,
        name=good.name,
        position=[0.0, math.nan],
        velocity=good.velocity,
        effort=good.effort,
    )
    with pytest.raises(SignalError, match=r"position\[1\]"):
        msgs.state_from_msg(bad, axis="x", period_ns_=PERIOD_NS)
    short = JointState(
        header=good.header,
        name=good.name,
        position=[0.0],
        velocity=good.velocity,
        effort=good.effort,
    )
    with pytest.raises(SignalError, match="position: expected 2 values"):
        msgs.state_from_msg(short, axis="x", period_ns_=PERIOD_NS)
    with pytest.raises(SignalError, match="name"):
        msgs.state_from_msg(good, axis="y", period_ns_=PERIOD_NS)


def test_encoders_refuse_to_put_nan_on_the_wire() -> None:
    with pytest.raises(SignalError, match="effort"):
        msgs.command_to_msg(msgs.CommandSample(0, math.inf), axis="x", period_ns_=PERIOD_NS)


def test_joint_state_efforts_are_torques_in_N_m() -> None:
    from servo_axis.core.drive import current_from_torque, torque_from_current

    kt = 0.715
    current = 2.5
    cmd = msgs.command_to_msg(
        msgs.CommandSample(3, torque_from_current(current, torque_constant_Nm_per_A=kt)),
        axis="x",
        period_ns_=PERIOD_NS,
    )
    wire = deserialize_message(serialize_message(cmd), JointState)
    assert wire.effort[0] == current * kt
    back = msgs.command_from_msg(wire, axis="x", period_ns_=PERIOD_NS)
    assert back.torque_Nm == current * kt
    assert current_from_torque(back.torque_Nm, torque_constant_Nm_per_A=kt) == pytest.approx(
        current, rel=2.3e-16
    )


@pytest.mark.parametrize(
    "sample",
    [
        msgs.DeformationSample(812, 3.7e-5, 2.1e-6, 1.1e-3, True),
        msgs.DeformationSample(9, 0.0, 1e-7, 2e-5, False),
        msgs.DeformationSample(0, -4e-6, -1e-7, -2e-5, True),
    ],
)
def test_deformation_round_trip_through_cdr(sample: msgs.DeformationSample) -> None:
    msg = msgs.deformation_to_msg(sample)
    wire = deserialize_message(serialize_message(msg), Float64MultiArray)
    assert [(d.label, d.size, d.stride) for d in wire.layout.dim] == [
        ("step", 1, 1),
        ("d_r_m_per_rad", 1, 1),
        ("scale_increment_m", 1, 1),
        ("encoder_increment_rad", 1, 1),
        ("valid", 1, 1),
    ]
    assert wire.data[0] == sample.step
    assert msgs.deformation_from_msg(wire) == sample
    # The template is refilled in place (the feedback's per-sample path).
    again = msgs.write_deformation(msg, msgs.DeformationSample(10, 1.0, 2.0, 3.0, False))
    assert again is msg and list(msg.data) == [10.0, 1.0, 2.0, 3.0, 0.0]


def test_labelled_array_round_trip_and_checks() -> None:
    labels = ("step", "code", "value")
    msg = msgs.labelled_array(labels, [12, 4, 0.5])
    wire = deserialize_message(serialize_message(msg), Float64MultiArray)
    assert [(d.label, d.size, d.stride) for d in wire.layout.dim] == [
        ("step", 1, 1),
        ("code", 1, 1),
        ("value", 1, 1),
    ]
    assert wire.layout.data_offset == 0
    assert msgs.labelled_array_values(wire, labels) == [12.0, 4.0, 0.5]
    with pytest.raises(SignalError, match=r"layout\.dim"):
        msgs.labelled_array_values(wire, ("step", "code", "other"))
    wire.data = [1.0, 2.0]
    with pytest.raises(SignalError, match="data: expected 3 values"):
        msgs.labelled_array_values(wire, labels)
    with pytest.raises(SignalError, match="labels"):
        msgs.labelled_array(("a,b",), [1.0])
    with pytest.raises(SignalError, match="distinct"):
        msgs.labelled_array(("a", "a"), [1.0, 2.0])
    with pytest.raises(SignalError, match="values: expected 2 values"):
        msgs.labelled_array(("a", "b"), [1.0])
    with pytest.raises(SignalError, match=r"data\[1\]"):
        msgs.labelled_array(("a", "b"), [1.0, math.nan])


def test_labelled_array_with_segments_round_trip() -> None:
    labels = ("trial", "x_r_m", "torque_Nm")
    values = [2.0, 0.0, 1e-6, 2e-6, -0.3, 0.1, 0.3]
    msg = msgs.labelled_array(labels, values, sizes=(1, 3, 3))
    wire = deserialize_message(serialize_message(msg), Float64MultiArray)
    assert [(d.label, d.size, d.stride) for d in wire.layout.dim] == [
        ("trial", 1, 1),
        ("x_r_m", 3, 3),
        ("torque_Nm", 3, 3),
    ]
    assert msgs.labelled_array_values(wire, labels, sizes=(1, None, None)) == values
    assert msgs.labelled_array_values(wire, labels, sizes=(1, 3, 3)) == values
    with pytest.raises(SignalError, match=r"layout\.dim 'x_r_m': expected size 1, got 3"):
        msgs.labelled_array_values(wire, labels)
    with pytest.raises(SignalError, match="sizes: expected one size per label"):
        msgs.labelled_array(labels, values, sizes=(1, 6))


def test_stamp_from_cdr_reads_the_header_without_deserialising() -> None:
    for step in (0, 7, 123_457, 2**31 // 1000):
        msg = msgs.state_to_msg(
            msgs.StateSample(step, 1, 2, 3, 4, 5, 6), axis="x", period_ns_=PERIOD_NS
        )
        assert msgs.stamp_ns_from_cdr(serialize_message(msg)) == step * PERIOD_NS
    with pytest.raises(SignalError, match="CDR"):
        msgs.stamp_ns_from_cdr(b"\x07\x07")


def test_input_correction_rejects_nan_and_other_fields() -> None:
    msg = msgs.input_correction_to_msg(
        msgs.InputCorrectionSample(2, 0.5), axis="x", period_ns_=PERIOD_NS
    )
    msg.effort = [math.nan]
    with pytest.raises(SignalError, match="effort"):
        msgs.input_correction_from_msg(msg, axis="x", period_ns_=PERIOD_NS)
    msg.effort = []
    with pytest.raises(SignalError, match="effort"):
        msgs.input_correction_from_msg(msg, axis="x", period_ns_=PERIOD_NS)
    target_side = msgs.correction_to_msg(
        msgs.CorrectionSample(2, 0.1, 0.2), axis="x", period_ns_=PERIOD_NS
    )
    with pytest.raises(SignalError, match="effort"):
        msgs.input_correction_from_msg(target_side, axis="x", period_ns_=PERIOD_NS)


def test_friction_table_round_trip_and_checks() -> None:
    x_r = [0.0, 2.5e-6, 1e-5, 9.9e-5]
    torque = [-3.2, -1.1, 2.9, 3.2]
    msg = msgs.friction_table_to_msg(4, x_r, torque)
    wire = deserialize_message(serialize_message(msg), Float64MultiArray)
    assert msgs.friction_table_from_msg(wire) == (4, x_r, torque)
    empty = deserialize_message(
        serialize_message(msgs.friction_table_to_msg(1, [], [])), Float64MultiArray
    )
    assert msgs.friction_table_from_msg(empty) == (1, [], [])
    with pytest.raises(SignalError, match="torque_Nm"):
        msgs.friction_table_to_msg(1, x_r, torque[:-1])
    with pytest.raises(SignalError, match="x_r_m"):
        msgs.friction_table_to_msg(1, [math.nan], [0.0])
    short = msgs.friction_table_to_msg(4, x_r, torque)
    short.data = list(short.data)[:-1]
    with pytest.raises(SignalError, match="data: expected 9 values"):
        msgs.friction_table_from_msg(short)
    relabelled = msgs.friction_table_to_msg(4, x_r, torque)
    relabelled.layout.dim[1].label = "x"
    with pytest.raises(SignalError, match="one dimension per field"):
        msgs.friction_table_from_msg(relabelled)
    uneven = msgs.friction_table_to_msg(4, x_r, torque)
    uneven.layout.dim[1].size = uneven.layout.dim[1].stride = 3
    uneven.layout.dim[2].size = uneven.layout.dim[2].stride = 5
    with pytest.raises(SignalError, match="'torque_Nm': expected size 3"):
        msgs.friction_table_from_msg(uneven)
    zero_trial = msgs.friction_table_to_msg(0, x_r, torque)
    with pytest.raises(SignalError, match="trial"):
        msgs.friction_table_from_msg(zero_trial)


def test_deformation_rejects_a_valid_flag_that_is_not_0_or_1_nan_and_other_layouts() -> None:
    msg = msgs.deformation_to_msg(msgs.DeformationSample(5, 1e-5, 1e-6, 1e-3, True))
    msg.data[4] = 0.5
    with pytest.raises(SignalError, match=r"valid: expected 0 or 1, got 0.5"):
        msgs.deformation_from_msg(msg)
    msg.data[4] = 1.0
    msg.data[1] = float("nan")
    with pytest.raises(SignalError, match=r"data\[1\]"):
        msgs.deformation_from_msg(msg)
    msg.data[1] = 0.0
    msg.data[0] = 5.5
    with pytest.raises(SignalError, match="step: expected a whole number"):
        msgs.deformation_from_msg(msg)
    short = msgs.deformation_to_msg(msgs.DeformationSample(5, 1e-5, 1e-6, 1e-3, True))
    short.data = list(short.data)[:4]
    with pytest.raises(SignalError, match="data: expected 5 values"):
        msgs.deformation_from_msg(short)
    old_layout = msgs.labelled_array(
        ["step,d_r_m_per_rad,scale_increment_m,encoder_increment_rad,valid".replace(",", ";")],
        [1.0],
    )
    with pytest.raises(SignalError, match="one dimension per field"):
        msgs.deformation_from_msg(old_layout)
