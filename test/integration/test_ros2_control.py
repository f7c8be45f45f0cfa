"""The emulated axis as the hardware of a ros2_control stack (issue 31), through
``python -m servo_axis run --external feedback`` with ``command_source: drive_setpoint``.

The ros2_control side is ``ros2_control_standin.py``: plain rclpy reproducing on the wire
``joint_state_topic_hardware_interface`` 1.1.0 behind a controller manager at 500 Hz and
an effort controller doing a PD towards a set angle (NaN commands before it is active,
QoS(1) commands, SensorDataQoS states, its own stamps), remapped onto the run's topics as
a user would. The plant is ``ptc_nominal``'s rigid axis (no friction, no modes, no dead
time, ideal sensors), so the recorded states are checked against an exact replay of the
torques the plant reports it applied, and each of those torques against the commands the
stand-in sent. The plugin publishing every cycle (its threshold -1), as
docs/how-to/ros2-control.md has it: that page's commands, with this stand-in in
place of ros2_control (test_docs_pages.py::test_how_to_ros2_control).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose
from test_external import NS, RUN_TIMEOUT_S, finish, short, start_outside, start_run, stop, tails

from servo_axis.recording.deserialize import read_messages

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

STANDIN = Path(__file__).with_name("ros2_control_standin.py")
#: ptc_nominal's axis and the stand-in's PD: poles near 3 Hz, well damped, 1.95 N m at most.
INERTIA, DAMPING, PERIOD = 0.01, 0.1, 0.001
KP, KD, TARGET = 3.9, 0.25, 0.5


def ros2_control(
    tmp: Path, threshold: float, duration_s: float, *extra: str
) -> tuple[int | None, Path, dict[str, Any]]:
    """A realtime run of ptc_nominal whose feedback is the stand-in; its exit code, run
    directory and the stand-in's log."""
    path = short("ptc_nominal", tmp, duration_s=duration_s, mode="realtime")
    data = yaml.safe_load(path.read_text())
    data["plant"]["ros__parameters"].update(
        command_source="drive_setpoint", setpoint_period_s=0.002, setpoint_threshold_Nm=threshold
    )
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out, log = tmp / "run", tmp / "standin.json"
    proc = start_run(path, out, "--external", "feedback")
    args = [str(STANDIN), "--ros-args", "-r", f"/robot_joint_commands:={NS}/command",
            "-r", f"/robot_joint_states:={NS}/state", "-p", "update_rate:=500",
            "-p", f"trigger_joint_command_threshold:={threshold}", "-p", f"kp:={KP}",
            "-p", f"kd:={KD}", "-p", f"target_rad:={TARGET}", "-p", f"log:={log}", *extra]  # fmt: skip
    standin = start_outside(args, tmp / "standin.log")
    try:
        code = finish(proc, RUN_TIMEOUT_S)
    finally:
        stop(standin)
    return code, out, json.loads(log.read_text())


def states(bag: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Motor angle, speed and applied torque of every recorded state, in stamp order."""
    rows = sorted(
        (m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec, m.message)
        for m in read_messages(bag, topics=[f"{NS}/state"])
    )
    assert [s for s, _ in rows] == [k * 1_000_000 for k in range(len(rows))]
    angle, speed, torque = (
        np.array([getattr(m, f)[0] for _, m in rows]) for f in ("position", "velocity", "effort")
    )
    return angle, speed, torque


def check_applied(out: Path, log: dict[str, Any], steps: int) -> np.ndarray:
    """The states are the exact response of the rigid axis to the torques the plant says it
    applied, and each of those is zero (before the first) or a command the stand-in sent.
    The angles."""
    assert log["error"] == ""  # the hardware took every state the plant sent
    angle, speed, torque = states(out / "bag")
    assert len(angle) == steps
    applied = torque[1:]  # state k + 1 carries the torque applied over step k
    a = math.exp(-DAMPING * PERIOD / INERTIA)
    w_inf = applied / DAMPING
    for k in range(len(applied)):  # the exact zero-order-hold solution, written again
        expected_speed = w_inf[k] + (speed[k] - w_inf[k]) * a
        gained = w_inf[k] * PERIOD + (speed[k] - w_inf[k]) * (1 - a) * INERTIA / DAMPING
        assert_allclose(speed[k + 1], expected_speed, rtol=1e-9, atol=1e-12)
        assert_allclose(angle[k + 1] - angle[k], gained, rtol=1e-9, atol=1e-12)
    sent = np.array(sorted(v for v in log["published"] if v is not None))
    nearest = sent[np.clip(np.searchsorted(sent, applied), 0, len(sent) - 1)]
    below = sent[np.clip(np.searchsorted(sent, applied) - 1, 0, len(sent) - 1)]
    matched = np.isclose(applied, nearest, rtol=1e-12, atol=0) | np.isclose(
        applied, below, rtol=1e-12, atol=0
    )
    started = np.flatnonzero(applied != 0.0)[0]
    assert not applied[:started].any() and matched[started:].all()
    return angle


def test_a_commander_silent_while_its_command_holds_is_held_not_missed(
    ros_env: int, tmp_path: Path
) -> None:
    """The plugin's default threshold (1e-5 N m) on both sides, and the user's node stops
    sending after 0.5 s (the effort controller holds its last command): the plugin then
    publishes nothing (the effort it reads is its command); the plant holds the set-point,
    counts the ticks as quiet, not missed, and a silence longer than the 2 s after which a
    commander that publishes every cycle counts as gone (loop_open) does not end the run."""
    code, out, log = ros2_control(tmp_path, 1e-5, 3.5, "-p", "pd_cycles:=250")
    summary = json.loads((out / "summary.json").read_text())
    assert code == 0, tails(out)
    rt = summary["realtime"]
    assert rt["misses"] == 0 and rt["setpoints"]["quiet_ticks"] > 100
    assert log["last_state_s"] - log["publish_s"][-1] > 2.0  # silent for over 2 s of the run
    angle = check_applied(out, log, 3500)
    held = log["published"][-1]  # the rigid axis under that torque held: w -> tau / D
    assert_allclose(np.diff(angle[-100:]) / PERIOD, held / DAMPING, rtol=1e-3)
