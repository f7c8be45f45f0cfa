"""The pure message checks (wire.checks, wire.layouts), which the nodes (wire.messages) and the analysis share."""

from __future__ import annotations

import math

import pytest

from servo_axis.core.errors import SignalError
from servo_axis.wire import cdr, checks, layouts
from servo_axis.wire import messages as msgs
from servo_axis.wire.streams import decode_array_stream, decode_joint_stream


def test_the_nodes_use_the_same_labels_names_and_checks() -> None:
    assert msgs.STATUS_LABELS == layouts.STATUS.labels
    assert msgs.FAULT_LABELS == layouts.FAULT.labels
    assert msgs.STATS_LABELS == layouts.CYCLE_STATS.labels
    assert msgs.PROGRESS_LABELS == layouts.PROGRESS.labels == cdr.PROGRESS_LABELS
    assert msgs.DEFORMATION_LABELS == layouts.DEFORMATION.labels
    assert msgs.ESTIMATE_LABELS == layouts.ESTIMATES.labels == cdr.ESTIMATE_LABELS
    assert msgs.state_names("y") == layouts.state_names("y") == ["y_motor", "y_table"]
    assert msgs.motor_names("y") == layouts.motor_names("y") == ["y_motor"]
    assert msgs.StateSample is layouts.StateSample and msgs.EstimateData is cdr.EstimateData


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
        checks.check_joint_arrays(got, ["x_motor"], arrays)
    else:
        with pytest.raises(SignalError, match=match):
            checks.check_joint_arrays(got, ["x_motor"], arrays)


def test_step_of_stamp_ns() -> None:
    assert checks.step_of_stamp_ns(6_000_000, 2_000_000) == 3
    for ns in (6_000_001, 1_000_000, -2_000_000):
        with pytest.raises(SignalError, match="not on the control grid"):
            checks.step_of_stamp_ns(ns, 2_000_000)


def test_check_labelled_values() -> None:
    labels = ("step", "x")
    assert checks.check_labelled_values(["step", "x"], [1, 1], [1.0, 2.0], labels) == [1.0, 2.0]
    assert checks.check_labelled_values(
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
            checks.check_labelled_values(dim_labels, sizes, data, labels)
    with pytest.raises(SignalError, match="strides equal to the sizes"):
        checks.check_labelled_values(["step", "x"], [1, 1], [1.0, 2.0], labels, dim_strides=[2, 1])


def test_check_labelled_values_of_segments() -> None:
    labels = ("trial", "x_r_m", "torque_Nm")
    values = [3.0, 1e-6, 2e-6, 0.5, 0.6]
    got = checks.check_labelled_values(labels, [1, 2, 2], values, labels, sizes=(1, None, None))
    assert got == values
    with pytest.raises(SignalError, match=r"layout\.dim 'trial': expected size 1, got 2"):
        checks.check_labelled_values(labels, [2, 1, 2], values, labels, sizes=(1, None, None))
    with pytest.raises(SignalError, match="data: expected 6 values"):
        checks.check_labelled_values(labels, [1, 2, 3], values, labels, sizes=(1, None, None))


def test_deformation_field_rules() -> None:
    deformation = layouts.DEFORMATION
    got = deformation.sample_of(deformation.checked([12.0, 1e-5, 1e-6, 1e-3, 1.0]))
    assert got == layouts.DeformationSample(12, 1e-5, 1e-6, 1e-3, True)
    assert type(got.step) is int
    assert deformation.sample_of(deformation.checked([0.0] * 5)).valid is False
    for values, match in (
        ([1.5, 0.0, 0.0, 0.0, 1.0], "step: expected a whole number >= 0, got 1.5"),
        ([-1.0, 0.0, 0.0, 0.0, 1.0], "step"),
        ([2.0, 0.0, 0.0, 0.0, 0.5], "valid: expected 0 or 1, got 0.5"),
        ([2.0, 0.0, 0.0, 0.0], "data: expected 5 values, got 4"),
        ([2.0, math.nan, 0.0, 0.0, 1.0], r"data\[1\]: expected a finite number"),
    ):
        with pytest.raises(SignalError, match=match):
            deformation.checked(values)


@pytest.mark.parametrize(
    ("layout", "index", "value", "match"),
    [
        (layouts.STATUS, 0, 2.5, r"^step: expected a whole number >= 0, got 2.5"),
        (layouts.STATUS, 2, -1.0, r"^rejected_commands: expected a whole number >= 0, got -1.0"),
        (layouts.CYCLE_STATS, 0, 0.0, r"^cycle: expected a whole number >= 1, got 0.0"),
        (layouts.CYCLE_STATS, 1, -1e-9, r"^rms_m: expected a value >= 0, got -1e-09"),
        (layouts.CYCLE_STATS, 3, 0.5, r"^cycles_learned: expected a whole number >= 0"),
        (layouts.FAULT, 1, 1.5, r"^code: expected a whole number >= 0, got 1.5"),
        (layouts.PROGRESS, 0, -3.0, r"^steps_recorded: expected a whole number >= 0"),
        (layouts.ESTIMATES, 2, 0.0, r"^inertia_kgm2: expected a value > 0, got 0.0"),
        (layouts.PARAMETERS, 0, 0.0, r"^trial: expected a whole number >= 1"),
    ],
)
def test_each_field_rule_names_the_field(
    layout: layouts.ArrayLayout[object], index: int, value: float, match: str
) -> None:
    good = {"plant/status": [50, 0, 1, 0], "learning/cycle_stats": [2, 1e-6, 3e-6, 1],
            "fault": [7, 1, 2e-3], "recorder/progress": [10],
            "identifier/estimates": [9, 20, 5e-3, 1e-2, 0.3, 0.02, 1e-3, 1, 1, 1, 1],
            "learning/parameters": [1, 5e-3, 1e-2, 0.02]}[layout.topic]  # fmt: skip
    values = [float(v) for v in good]
    assert layout.checked(values) == values
    values[index] = value
    with pytest.raises(SignalError, match=match):
        layout.checked(values)
    # The same refusal when the values arrive as a message (node) and as a payload (bag).
    msg = msgs.labelled_array(layout.labels, values)
    with pytest.raises(SignalError, match=match):
        msgs._values(msg, layout)
    from rclpy.serialization import serialize_message

    decoded = cdr.decode_float64_multi_array(serialize_message(msg))
    with pytest.raises(SignalError, match=match):
        layout.values(decoded.labels, decoded.sizes, decoded.data, decoded.strides)


def test_fault_label_carries_the_codes_the_name_is_short() -> None:
    assert layouts.FAULT.names == ("step", "code", "value")
    assert layouts.FAULT.labels == (
        "step",
        "code(1=following_error;2=travel;3=current;4=input_timeout)",
        "value(m_or_A_or_s)",
    )


def test_every_topic_of_the_table_has_its_layout() -> None:
    from servo_axis.wire import topics

    for entry in topics.TOPICS:
        layout = layouts.LAYOUTS.get(entry.name)
        if entry.type_name == topics.JOINT_STATE:
            assert isinstance(layout, layouts.JointLayout), entry.name
        elif entry.type_name == topics.FLOAT64_MULTI_ARRAY:
            assert isinstance(layout, layouts.ArrayLayout), entry.name
        else:
            assert layout is None, entry.name
    assert set(layouts.LAYOUTS) <= set(topics.BY_NAME)


def test_a_layout_that_disagrees_with_its_sample_is_refused() -> None:
    with pytest.raises(TypeError, match=r"sample fields .* differ from the layout"):
        layouts.JointLayout(
            "command", layouts.CommandSample, joints=("motor",), position=("torque_Nm",),
            effort=("torque_Nm",),
        )  # fmt: skip
    with pytest.raises(TypeError, match="one field per joint"):
        layouts.JointLayout(
            "state", layouts.StateSample, joints=("motor",),
            position=("encoder_rad", "scale_m"), velocity=("velocity_rad_s", "velocity_m_s"),
            effort=("motor_torque_Nm", "friction_force_N"),
        )  # fmt: skip
    with pytest.raises(TypeError, match="sample fields"):
        layouts.ArrayLayout(
            "deformation", layouts.DEFORMATION.fields[:4], sample=layouts.DeformationSample
        )
    with pytest.raises(ValueError, match="rule 'integer'"):
        layouts.Field("step", "integer")


def test_decoded_payloads_are_checked_as_the_nodes_check_messages() -> None:
    """One rule: the same message refused by the node's decoder and by the analysis's."""
    from rclpy.serialization import serialize_message

    period_ns = 1_000_000
    good = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    short = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    short.effort = []
    off = msgs.command_to_msg(msgs.CommandSample(7, 1.5), axis="x", period_ns_=period_ns)
    off.header.stamp.nanosec += 1
    step, sample = decode_joint_stream(
        "command", serialize_message(good), axis="x", period_ns=period_ns
    )
    assert sample == msgs.command_from_msg(good, axis="x", period_ns_=period_ns)
    assert step == sample.step == 7
    for msg in (short, off):
        with pytest.raises(SignalError) as node_err:
            msgs.command_from_msg(msg, axis="x", period_ns_=period_ns)
        with pytest.raises(SignalError) as bag_err:
            decode_joint_stream("command", serialize_message(msg), axis="x", period_ns=period_ns)
        assert str(bag_err.value) == str(node_err.value)
    deformation = msgs.deformation_to_msg(msgs.DeformationSample(4, 1e-5, 2e-6, 0.2, True))
    assert decode_array_stream("deformation", serialize_message(deformation)) == (
        4,
        msgs.deformation_from_msg(deformation),
    )
    deformation.data[4] = 0.5
    with pytest.raises(SignalError) as node_err:
        msgs.deformation_from_msg(deformation)
    with pytest.raises(SignalError) as bag_err:
        decode_array_stream("deformation", serialize_message(deformation))
    assert str(bag_err.value) == str(node_err.value) == "valid: expected 0 or 1, got 0.5"
    status = msgs.labelled_array(msgs.STATUS_LABELS, [50, 0, 1, 0])
    decoded_status = cdr.decode_float64_multi_array(serialize_message(status))
    status_values = [50.0, 0.0, 1.0, 0.0]
    assert (
        layouts.STATUS.values(decoded_status.labels, decoded_status.sizes, decoded_status.data)
        == status_values
    )
    assert msgs.labelled_array_values(status, msgs.STATUS_LABELS) == [50.0, 0.0, 1.0, 0.0]
    # A layout the node's decoder refuses, the analysis refuses with the same words.
    wrong = msgs.labelled_array(msgs.STATUS_LABELS, [50, 0, 1, 0])
    wrong.layout.dim[2].size = 2
    with pytest.raises(SignalError) as node_err:
        msgs.labelled_array_values(wrong, msgs.STATUS_LABELS)
    decoded = cdr.decode_float64_multi_array(serialize_message(wrong))
    with pytest.raises(SignalError) as bag_err:
        layouts.STATUS.values(decoded.labels, decoded.sizes, decoded.data, decoded.strides)
    assert str(bag_err.value) == str(node_err.value)
    assert "rejected_commands" in str(node_err.value)
