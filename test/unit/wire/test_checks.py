"""The pure message checks of wire.cdr, which the nodes (wire.messages) and the analysis share."""

from __future__ import annotations

import math

import pytest

from servo_axis.core.errors import SignalError
from servo_axis.wire import cdr
from servo_axis.wire import messages as msgs


def test_the_nodes_use_the_same_labels_names_and_checks() -> None:
    assert msgs.STATUS_LABELS is cdr.STATUS_LABELS
    assert msgs.FAULT_LABELS is cdr.FAULT_LABELS
    assert msgs.STATS_LABELS is cdr.STATS_LABELS
    assert msgs.PROGRESS_LABELS is cdr.PROGRESS_LABELS
    assert msgs.DEFORMATION_LABELS is cdr.DEFORMATION_LABELS
    assert msgs.state_names("y") == cdr.state_names("y") == ["y_motor", "y_table"]
    assert msgs.motor_names("y") == cdr.motor_names("y") == ["y_motor"]


@pytest.mark.parametrize(
    ("got", "arrays", "match"),
    [
        (["x_motor"], [("effort", [1.0])], None),
        ([], [("effort", [])], "name: expected"),
        (["y_motor"], [("effort", [1.0])], "name: expected"),
        (["x_motor"], [("effort", [])], "effort: expected 1 values, got 0"),
        (["x_motor"], [("effort", [1.0, 2.0])], "effort: expected 1 values, got 2"),
        (["x_motor"], [("effort", [math.nan])], r"effort\[0\]: expected a finite number"),
        (["x_motor"], [("effort", [-math.inf])], r"effort\[0\]"),
        (["x_motor"], [("position", [1e308]), ("velocity", [1.0])], None),
    ],
)
def test_check_joint_arrays(
    got: list[str], arrays: list[tuple[str, list[float]]], match: str | None
) -> None:
    if match is None:
        cdr.check_joint_arrays(got, ["x_motor"], arrays)
    else:
        with pytest.raises(SignalError, match=match):
            cdr.check_joint_arrays(got, ["x_motor"], arrays)


def test_step_of_stamp_ns() -> None:
    assert cdr.step_of_stamp_ns(6_000_000, 2_000_000) == 3
    for ns in (6_000_001, 1_000_000, -2_000_000):
        with pytest.raises(SignalError, match="not on the control grid"):
            cdr.step_of_stamp_ns(ns, 2_000_000)


def test_check_labelled_values() -> None:
    labels = ("step", "x")
    assert cdr.check_labelled_values(["step", "x"], [1, 1], [1.0, 2.0], labels) == [1.0, 2.0]
    assert cdr.check_labelled_values(
        ["step", "x"], [1, 1], [1.0, 2.0], labels, dim_strides=[1, 1]
    ) == [1.0, 2.0]
    bad = [
        ([], [], [1.0, 2.0], "layout.dim: expected one dimension per field"),
        (["step,x"], [2], [1.0, 2.0], "layout.dim: expected one dimension per field"),
        (["step", "y"], [1, 1], [1.0, 2.0], r"\['step', 'x'\], got \['step', 'y'\]"),
        (["step", "x", "y"], [1, 1, 1], [1.0, 2.0, 3.0], "layout.dim"),
        (["step", "x"], [1, 2], [1.0, 2.0, 3.0], "layout.dim 'x': expected size 1, got 2"),
        (["step", "x"], [1, 1], [1.0], r"data: expected 2 values \(sizes \[1, 1\]"),
        (["step", "x"], [1, 1], [1.0, 2.0, 3.0], "data: expected 2 values"),
        (["step", "x"], [1, 1], [math.inf, 2.0], r"data\[0\]"),
    ]
    for dim_labels, sizes, data, match in bad:
        with pytest.raises(SignalError, match=match):
            cdr.check_labelled_values(dim_labels, sizes, data, labels)
    with pytest.raises(SignalError, match="strides equal to the sizes"):
        cdr.check_labelled_values(["step", "x"], [1, 1], [1.0, 2.0], labels, dim_strides=[2, 1])


def test_check_labelled_values_of_segments() -> None:
    labels = ("trial", "x_r_m", "torque_Nm")
    values = [3.0, 1e-6, 2e-6, 0.5, 0.6]
    got = cdr.check_labelled_values(labels, [1, 2, 2], values, labels, sizes=(1, None, None))
    assert got == values
    with pytest.raises(SignalError, match=r"layout\.dim 'trial': expected size 1, got 2"):
        cdr.check_labelled_values(labels, [2, 1, 2], values, labels, sizes=(1, None, None))
    with pytest.raises(SignalError, match="data: expected 6 values"):
        cdr.check_labelled_values(labels, [1, 2, 3], values, labels, sizes=(1, None, None))


def test_check_deformation_values() -> None:
    assert cdr.check_deformation_values([12.0, 1e-5, 1e-6, 1e-3, 1.0]) == 12
    assert cdr.check_deformation_values([0.0, 0.0, 0.0, 0.0, 0.0]) == 0
    for values, match in (
        ([1.5, 0.0, 0.0, 0.0, 1.0], "step: expected a whole number >= 0, got 1.5"),
        ([-1.0, 0.0, 0.0, 0.0, 1.0], "step"),
        ([2.0, 0.0, 0.0, 0.0, 0.5], "valid: expected 0 or 1, got 0.5"),
    ):
        with pytest.raises(SignalError, match=match):
            cdr.check_deformation_values(values)


def test_decoded_payloads_are_checked_as_the_nodes_check_messages() -> None:
    """One rule: the same message refused by the node's decoder and by the analysis's."""
    from rclpy.serialization import serialize_message

    period_ns = 1_000_000
    good = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    short = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    short.effort = []
    off = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    off.header.stamp.nanosec += 1
    names = cdr.motor_names("x")
    assert (
        cdr.joint_state_step(
            cdr.decode_joint_state(serialize_message(good)), names, ("effort",), period_ns
        )
        == msgs.command_from_msg(good, axis="x", period_ns_=period_ns).step
        == 7
    )
    for msg in (short, off):
        with pytest.raises(SignalError) as node_err:
            msgs.command_from_msg(msg, axis="x", period_ns_=period_ns)
        decoded = cdr.decode_joint_state(serialize_message(msg))
        with pytest.raises(SignalError) as bag_err:
            cdr.joint_state_step(decoded, names, ("effort",), period_ns)
        assert str(bag_err.value) == str(node_err.value)
    status = msgs.labelled_array(msgs.STATUS_LABELS, [50, 0, 1, 0])
    decoded_status = cdr.decode_float64_multi_array(serialize_message(status))
    assert cdr.labelled_values(decoded_status, cdr.STATUS_LABELS) == [50.0, 0.0, 1.0, 0.0]
    assert msgs.labelled_array_values(status, msgs.STATUS_LABELS) == [50.0, 0.0, 1.0, 0.0]
    # A layout the node's decoder refuses, the analysis refuses with the same words.
    wrong = msgs.labelled_array(msgs.STATUS_LABELS, [50, 0, 1, 0])
    wrong.layout.dim[2].size = 2
    with pytest.raises(SignalError) as node_err:
        msgs.labelled_array_values(wrong, msgs.STATUS_LABELS)
    with pytest.raises(SignalError) as bag_err:
        cdr.labelled_values(
            cdr.decode_float64_multi_array(serialize_message(wrong)), cdr.STATUS_LABELS
        )
    assert str(bag_err.value) == str(node_err.value)
    assert "rejected_commands" in str(node_err.value)
