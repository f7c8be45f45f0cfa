"""The suite's `state` from joint_state_broadcaster's `joint_states` (ros2_controllers 4.42.1:
names sorted or in its `joints` order, NaN where a joint lacks an interface or the hardware
has no value yet, stamps the controller manager's now())."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.wire.cdr import JointStateData
from servo_axis.wire.joint_states import AxisState, BridgeStream, axis_state

NAN = math.nan
LEAD = 0.00191


def states(
    name: list[str],
    position: Sequence[float],
    velocity: Sequence[float] = (),
    effort: Sequence[float] = (),
) -> JointStateData:
    return JointStateData(
        stamp_ns=1_764_000_000_000_000_000,
        frame_id="base_link",
        name=tuple(name),
        position=tuple(position),
        velocity=tuple(velocity),
        effort=tuple(effort),
    )


def test_a_full_message_is_taken_by_name_in_either_order() -> None:
    sorted_ = states(["x_motor", "x_table"], [2.0, 0.004], [3.0, 0.006], [0.5, -1.5])
    # The broadcaster's `joints` parameter [x_table, x_motor]: the same state.
    reordered = states(["x_table", "x_motor"], [0.004, 2.0], [0.006, 3.0], [-1.5, 0.5])
    want = AxisState(position=(2.0, 0.004), velocity=(3.0, 0.006), effort=(0.5, -1.5))
    assert axis_state(sorted_, axis="x", lead_m_per_rad=LEAD) == want
    assert axis_state(reordered, axis="x", lead_m_per_rad=LEAD) == want
    # Other joints (another axis on the same broadcaster) are ignored.
    other = states(["a_motor", "x_motor", "x_table"], [9.0, 2.0, 0.004], [9.0, 3.0, 0.006],
                   [9.0, 0.5, -1.5])  # fmt: skip
    assert axis_state(other, axis="x", lead_m_per_rad=LEAD) == want


def test_nan_of_a_missing_interface_is_replaced_by_the_documented_value() -> None:
    # x_table with a position state interface only: velocity[1], effort[1] NaN.
    msg = states(["x_motor", "x_table"], [2.0, 0.0039], [3.0, NAN], [0.5, NAN])
    got = axis_state(msg, axis="x", lead_m_per_rad=LEAD, held_torque_Nm=0.25)
    assert got is not None
    assert got.position == (2.0, 0.0039)  # the table's own scale, not R theta
    assert_allclose(got.velocity, (3.0, LEAD * 3.0), rtol=1e-15, atol=0)
    assert got.effort == (0.5, 0.0)  # the motor's own effort, no friction force
    # A motor with position only: speed 0, effort the torque last commanded.
    msg = states(["x_motor", "x_table"], [2.0, 0.0039], [NAN, NAN], [NAN, NAN])
    got = axis_state(msg, axis="x", lead_m_per_rad=LEAD, held_torque_Nm=0.25)
    assert got == AxisState(position=(2.0, 0.0039), velocity=(0.0, 0.0), effort=(0.25, 0.0))
    assert all(math.isfinite(v) for v in (*got.position, *got.velocity, *got.effort))


def test_a_motor_only_axis_gets_its_table_through_the_lead() -> None:
    for msg in (
        states(["x_motor"], [2.0], [3.0], [0.5]),  # no table joint in the tag
        states(["x_motor", "x_table"], [2.0, NAN], [3.0, NAN], [0.5, NAN]),  # no table value
        states(["x_motor"], [2.0]),  # velocity and effort empty (JointState allows it)
    ):
        got = axis_state(msg, axis="x", lead_m_per_rad=LEAD)
        assert got is not None
        assert_allclose(got.position, (2.0, LEAD * 2.0), rtol=1e-15, atol=0)
        assert math.isfinite(got.velocity[1]) and math.isfinite(got.effort[0])


def test_no_motor_position_yet_is_no_state() -> None:
    # The broadcaster before the hardware has a value: NaN everywhere.
    msg = states(["x_motor", "x_table"], [NAN, NAN], [NAN, NAN], [NAN, NAN])
    assert axis_state(msg, axis="x", lead_m_per_rad=LEAD) is None


@pytest.mark.parametrize(
    ("msg", "match"),
    [
        (states(["x_table"], [0.1]), "no joint 'x_motor'"),
        (states(["y_motor", "y_table"], [1.0, 0.1]), "no joint 'x_motor'"),
        (states(["x_motor", "x_table"], [1.0]), r"position: expected 0 or 2 values"),
        (states(["x_motor", "x_table"], [1.0, 0.1], [1.0]), r"velocity: expected 0 or 2"),
        (states(["x_motor", "x_table"], [math.inf, 0.1]), r"position\[0\] \('x_motor'\)"),
        (states(["x_motor", "x_table"], [1.0, 0.1], [], [0.0, -math.inf]), r"effort\[1\]"),
    ],
)
def test_what_is_not_a_broadcasters_message_of_the_axis_is_refused(
    msg: JointStateData, match: str
) -> None:
    with pytest.raises(SignalError, match=match):
        axis_state(msg, axis="x", lead_m_per_rad=LEAD)


def test_the_lead_must_be_positive() -> None:
    with pytest.raises(ConfigError, match="lead_m_per_rad"):
        axis_state(states(["x_motor"], [1.0]), axis="x", lead_m_per_rad=0.0)


def test_only_strictly_later_stamps_with_a_value_become_states() -> None:
    stream, state = BridgeStream(), AxisState((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    taken = [
        stream.take(ns, s)
        for ns, s in [(100, None), (200, state), (200, state), (150, state), (300, state)]
    ]
    assert taken == [False, True, False, False, True]
    assert (stream.taken, stream.out_of_order, stream.no_value) == (2, 2, 1)
    assert stream.last_ns == 300
