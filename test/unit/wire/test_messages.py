"""Message conversions: round trips and rejection of bad messages (no ROS graph)."""

from __future__ import annotations

import math

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import SignalError
from servo_axis.wire import messages as msgs

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
            msgs.DeformationSample(812, 3.7e-5, 2.1e-6, 1.1e-3, True),
            msgs.deformation_to_msg,
            msgs.deformation_from_msg,
        ),
        (
            msgs.DeformationSample(9, 0.0, 1e-7, 2e-5, False),
            msgs.deformation_to_msg,
            msgs.deformation_from_msg,
        ),
    ],
)
def test_round_trip_through_cdr(sample: object, encode: object, decode: object) -> None:
    msg = encode(sample, axis="x", period_ns_=PERIOD_NS)  # type: ignore[operator]
    wire = deserialize_message(serialize_message(msg), type(msg))
    assert decode(wire, axis="x", period_ns_=PERIOD_NS) == sample  # type: ignore[operator]
    assert all(name.startswith("x_") for name in wire.name)


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


def test_labelled_array_round_trip_and_checks() -> None:
    labels = ("step", "code", "value")
    msg = msgs.labelled_array(labels, [12, 4, 0.5])
    wire = deserialize_message(serialize_message(msg), Float64MultiArray)
    assert wire.layout.dim[0].label == "step,code,value"
    assert wire.layout.dim[0].size == 3
    assert msgs.labelled_array_values(wire, labels) == [12.0, 4.0, 0.5]
    with pytest.raises(SignalError, match=r"layout\.dim"):
        msgs.labelled_array_values(wire, ("step", "code", "other"))
    wire.data = [1.0, 2.0]
    with pytest.raises(SignalError, match="data"):
        msgs.labelled_array_values(wire, labels)
    with pytest.raises(SignalError, match="labels"):
        msgs.labelled_array(("a,b",), [1.0])


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
    with pytest.raises(SignalError, match="sizes"):
        msgs.friction_table_from_msg(short)
    relabelled = msgs.friction_table_to_msg(4, x_r, torque)
    relabelled.layout.dim[1].label = "x"
    with pytest.raises(SignalError, match="segments"):
        msgs.friction_table_from_msg(relabelled)
    zero_trial = msgs.friction_table_to_msg(0, x_r, torque)
    with pytest.raises(SignalError, match="trial"):
        msgs.friction_table_from_msg(zero_trial)


def test_deformation_rejects_a_valid_flag_that_is_not_0_or_1_and_nan() -> None:
    msg = msgs.deformation_to_msg(
        msgs.DeformationSample(5, 1e-5, 1e-6, 1e-3, True), axis="x", period_ns_=PERIOD_NS
    )
    msg.position[3] = 0.5
    with pytest.raises(SignalError, match=r"position\[3\] \(valid\)"):
        msgs.deformation_from_msg(msg, axis="x", period_ns_=PERIOD_NS)
    msg.position[3] = 1.0
    msg.position[0] = float("nan")
    with pytest.raises(SignalError):
        msgs.deformation_from_msg(msg, axis="x", period_ns_=PERIOD_NS)
    short = msgs.deformation_to_msg(
        msgs.DeformationSample(5, 1e-5, 1e-6, 1e-3, True), axis="x", period_ns_=PERIOD_NS
    )
    short.name = short.name[:3]
    with pytest.raises(SignalError):
        msgs.deformation_from_msg(short, axis="x", period_ns_=PERIOD_NS)
