"""A drive's set-point out of the JointState commands of ros2_control's topic-based hardware
(joint_state_topic_hardware_interface 1.1.0: ``name`` = every joint of the tag in tag order,
``effort`` = one value per joint with an effort command interface)."""

from __future__ import annotations

import math

import pytest

from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import JointStateData
from servo_axis.wire.setpoint import setpoint_torque


def command(name: list[str], effort: list[float], **fields: list[float]) -> JointStateData:
    return JointStateData(
        stamp_ns=1_764_000_000_123_456_789,  # the plugin's own clock: never read
        frame_id="",
        name=tuple(name),
        position=tuple(fields.get("position", [])),
        velocity=tuple(fields.get("velocity", [])),
        effort=tuple(effort),
    )


def test_the_motor_torque_is_taken_by_name_or_as_the_one_effort_command() -> None:
    # The tag [x_motor (effort command), x_table (states only)]: effort = [tau].
    assert setpoint_torque(command(["x_motor", "x_table"], [0.5]), motor="x_motor") == 0.5
    # The table listed first: still the motor's, the one effort command interface.
    assert setpoint_torque(command(["x_table", "x_motor"], [-0.25]), motor="x_motor") == -0.25
    # One effort per name (the suite's own layout, or both joints declared): by name.
    assert setpoint_torque(command(["x_table", "x_motor"], [9.0, 1.5]), motor="x_motor") == 1.5
    # NaN: the plugin's "no controller has written yet", handed on as NaN (never applied).
    assert math.isnan(setpoint_torque(command(["x_motor"], [math.nan]), motor="x_motor"))


@pytest.mark.parametrize(
    ("msg", "match"),
    [
        (command(["y_motor", "y_table"], [0.5]), r"no joint 'x_motor' \(the axis's driven joint\)"),
        (command(["x_motor"], [], position=[0.1]), r"only position: declare an effort command"),
        (command(["x_motor", "x_table", "x_extra"], [0.1, 0.2]), r"got 2: only 'x_motor'"),
        (command(["x_motor"], [math.inf]), r"expected a finite torque or NaN, got inf"),
    ],
)
def test_a_command_without_the_motor_torque_is_refused_naming_what_is_missing(
    msg: JointStateData, match: str
) -> None:
    with pytest.raises(SignalError, match=match):
        setpoint_torque(msg, motor="x_motor")
