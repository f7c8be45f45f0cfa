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


def test_the_bridge_starts_only_once_its_writer_has_matched_a_late_reader(ros_env: int) -> None:
    """A reader of ``state`` that appears just after ``command`` still gets step 0.

    The start rule alone (``command`` has a publisher) would publish at once: the second
    reader, made 0.2 s later, would miss the first states (measured in CI with the
    recorder, learned of late by the bridge's process). The bridge waits until its writer
    has matched every reader it lists, the counts held 0.5 s.
    """
    import time

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import JointState

    bridge = subprocess.Popen(
        [sys.executable, *BRIDGE, "-p", "mode:=realtime", "-p", "state_stamps:=plant_clock"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    context = rclpy.context.Context()
    rclpy.init(args=[], context=context, domain_id=ros_env)
    try:
        node = rclpy.create_node("late_reader_test", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        joint_states = node.create_publisher(JointState, "/joint_states", 10)
        got: dict[str, list[int]] = {"first": [], "late": []}

        def reader(name: str) -> None:
            node.create_subscription(
                JointState,
                f"{NS}/state",
                lambda m: got[name].append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec),
                QoSProfile(depth=1000),
            )

        def spin_for(seconds: float, tick: list[int]) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                tick[0] += 1
                msg = JointState(name=["x_motor"], position=[0.001 * tick[0]])
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(tick[0] * 10**7, 10**9)
                joint_states.publish(msg)
                executor.spin_once(timeout_sec=0.01)

        tick = [0]
        reader("first")
        deadline = time.monotonic() + 30
        while (
            node.count_publishers(f"{NS}/state") == 0
            or node.count_subscribers(f"{NS}/command") == 0
        ):  # the bridge is up
            assert time.monotonic() < deadline, "the bridge never came up"
            spin_for(0.05, tick)
        command = node.create_publisher(JointState, f"{NS}/command", 10)
        spin_for(0.2, tick)
        assert got["first"] == [], "published before its writer's counts held"
        reader("late")
        spin_for(2.0, tick)
        assert got["first"] and got["late"], got
        assert got["late"][0] == got["first"][0]  # step 0 reached the late reader too
        assert len(got["late"]) > 10, got["late"]
        node.destroy_publisher(command)
        spin_for(0.1, tick)
        out, _ = bridge.communicate(timeout=30)  # ends 1 s after command lost its publisher
        assert bridge.returncode == 0, out
    finally:
        bridge.kill()
        bridge.wait()
        rclpy.try_shutdown(context=context)
