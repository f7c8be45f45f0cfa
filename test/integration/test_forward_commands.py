"""The suite's feedback commanding ros2_control's forward effort controller (issue 31):
``forward_commands_topic`` sends each command as ``std_msgs/Float64MultiArray`` to a
stand-in of ``effort_controllers/JointGroupEffortController`` (ros2_controllers 4.42.1) in
plain rclpy, nothing imported from servo_axis: its ``~/commands`` reader with the system
default QoS, joints ``[x_motor]``, a message with a non-finite value dropped, one of
another length deactivating the controller."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml
from test_external import NS, RUN_TIMEOUT_S, finish, short, start_outside, start_run, stop, tails

from servo_axis.recording.deserialize import read_messages

pytestmark = pytest.mark.integration

#: The controller's subscription, as FCB.cpp 4.42.1 makes it; it logs what it takes.
CONTROLLER = """
import json, math, sys
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import qos_profile_system_default
from std_msgs.msg import Float64MultiArray
rclpy.init()
node = rclpy.create_node("effort_controller")
joints, taken, dropped, deactivated = ["x_motor"], [], 0, False
def on_commands(msg):
    global dropped, deactivated
    if deactivated:
        return
    if not all(math.isfinite(v) for v in msg.data):
        dropped += 1  # "Non-finite value received. Dropping message"
    elif len(msg.data) != len(joints):
        deactivated = True  # update() returns ERROR: the controller manager deactivates it
    else:
        taken.append(list(msg.data))
node.create_subscription(Float64MultiArray, "~/commands", on_commands, qos_profile_system_default)
print("listening", flush=True)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    with open(sys.argv[1], "w") as f:
        json.dump({"taken": taken, "dropped": dropped, "deactivated": deactivated}, f)
"""


def test_the_feedback_sends_each_command_to_a_forward_effort_controller(
    ros_env: int, tmp_path: Path
) -> None:
    """Lockstep, 0.5 s of ptc_nominal with the suite's own plant: every message the
    controller takes is ``[torque]`` with the torque of a recorded command, in the order of
    the samples, the last one the run's last command (what the controller holds). Its
    system-default reader (best effort, keep-last 1 with Fast DDS) keeps only the newest
    message, as the controller uses only the newest each cycle; a lockstep run outpaces
    it (measured: 275-440 of 500 taken), so not every command arrives."""
    path = short("ptc_nominal", tmp_path, duration_s=0.5)
    data = yaml.safe_load(path.read_text())
    data["feedback"]["ros__parameters"]["forward_commands_topic"] = "/effort_controller/commands"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    log = tmp_path / "controller.json"
    # The run's discovery profile (100 ms announcements): nothing in the run waits for
    # this reader, so it must be matched before the 0.5 s of lockstep are over.
    controller = start_outside(
        ["-c", CONTROLLER, str(log)], tmp_path / "controller.log", run_profile=True
    )
    try:
        # Listening before the run starts (not after a fixed 1 s: its start-up
        # is the host's); the run's own start-up leaves time for the match.
        said, deadline = tmp_path / "controller.log", time.monotonic() + 60
        while "listening" not in said.read_text():
            assert controller.poll() is None and time.monotonic() < deadline, said.read_text()
            time.sleep(0.05)
        out = tmp_path / "run"
        code = finish(start_run(path, out), RUN_TIMEOUT_S)
        time.sleep(0.5)
    finally:
        stop(controller)
    assert code == 0, tails(out)
    got = json.loads(log.read_text())
    assert got["dropped"] == 0 and not got["deactivated"]
    commands = [
        m.message.effort[0]
        for m in sorted(
            read_messages(out / "bag", topics=[f"{NS}/command"]),
            key=lambda m: m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec,
        )
    ]
    assert len(commands) == 500 and len(got["taken"]) >= 50
    assert all(len(d) == 1 for d in got["taken"])
    assert got["taken"][-1] == [commands[-1]]
    it = iter(commands)  # each taken value is the next recorded command it equals, in order
    assert all(any(d[0] == c for c in it) for d in got["taken"]), got["taken"][:5]
