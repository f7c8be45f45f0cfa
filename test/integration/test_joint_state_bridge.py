"""The suite's controllers against an axis ros2_control drives (issue 31, 3(b)).

The ros2_control side is ``ros2_control_axis_standin.py``: plain rclpy reproducing on the
wire a controller manager at 1000 Hz (ros2_control 4.46.0) with joint_state_broadcaster and
an ``effort_controller`` (JointGroupEffortController; ros2_controllers 4.42.1) on a
simulated rigid axis of the scenario's parameters, publishing ``/joint_states`` from before
the run. The run is ``python -m servo_axis run --external plant`` in realtime with
``state_stamps: plant_clock``; the plant is ``python -m servo_axis.nodes.joint_state_bridge``
given the scenario's file; the feedback sends its torques to the controller through
``forward_commands_topic``. That run is the commands of docs/how-to/ros2-control.md with
the stand-in in place of ros2_control (test_docs_pages.py::test_how_to_ros2_control);
here, what the bridge refuses.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from test_external import NS

pytestmark = pytest.mark.integration

BRIDGE = ["-m", "servo_axis.nodes.joint_state_bridge", "--ros-args", "-r", f"__ns:={NS}"]


def test_the_bridge_refuses_lockstep(ros_env: int) -> None:
    """A ros2_control stack has no lockstep: exit 2, saying so, before any publisher."""
    done = subprocess.run(
        [sys.executable, *BRIDGE, "-p", "mode:=lockstep"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert "mode: expected realtime, got 'lockstep'" in done.stderr
    assert "has no lockstep" in done.stderr
