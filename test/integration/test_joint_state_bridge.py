"""The suite's controllers against an axis ros2_control drives (issue 31, 3(b)).

The ros2_control side is ``ros2_control_axis_standin.py``: plain rclpy reproducing on the
wire a controller manager at 1000 Hz (ros2_control 4.46.0) with joint_state_broadcaster and
an ``effort_controller`` (JointGroupEffortController; ros2_controllers 4.42.1) on a
simulated rigid axis of the scenario's parameters, publishing ``/joint_states`` from before
the run. The run is ``python -m servo_axis run --external plant`` in realtime with
``state_stamps: plant_clock``; the plant is ``python -m servo_axis.nodes.joint_state_bridge``
given the scenario's file; the feedback sends its torques to the controller through
``forward_commands_topic``.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose
from test_external import NS, RUN_TIMEOUT_S, finish, start_outside, start_run, stop, tails
from test_outside_plant import (
    DAMPING,
    INERTIA,
    LEAD,
    STEPS,
    TORQUE_LIMIT,
    joint_arrays,
    plant_clock_rms_m,
    plant_clock_steps,
    scenario,
)

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

STANDIN = Path(__file__).with_name("ros2_control_axis_standin.py")
BRIDGE = ["-m", "servo_axis.nodes.joint_state_bridge", "--ros-args", "-r", f"__ns:={NS}"]


def realtime_scenario(dst: Path) -> Path:
    """ptc_nominal, 1 s, the PID alone, realtime on the plant's clock, the torques also to
    the forward effort controller (a 10 Hz loop: a stalled Python timer trips it less)."""
    path = scenario(dst)
    data = yaml.safe_load(path.read_text())
    data["/**"]["ros__parameters"].update(mode="realtime", state_stamps="plant_clock")
    fb = data["feedback"]["ros__parameters"]
    fb.update(bandwidth_hz=10.0, forward_commands_topic="/effort_controller/commands")
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def run(module_ros_env: tuple[int, Path]) -> Iterator[dict[str, Any]]:
    """One run: the stand-in started 1 s before the run, the bridge beside the run."""
    _domain, tmp = module_ros_env
    path = realtime_scenario(tmp)
    log = tmp / "standin.json"
    params = {"update_rate": 1000, "inertia_kgm2": INERTIA, "damping_Nms_per_rad": DAMPING,
              "lead_m_per_rad": LEAD, "torque_limit_Nm": TORQUE_LIMIT, "log": str(log)}  # fmt: skip
    args = [str(STANDIN), "--ros-args"] + [
        a for k, v in params.items() for a in ("-p", f"{k}:={v}")
    ]
    standin = start_outside(args, tmp / "standin.log", run_profile=True)
    out = tmp / "run"
    try:
        time.sleep(1.0)  # the broadcaster publishes long before the run
        proc = start_run(path, out, "--external", "plant")
        bridge = start_outside([*BRIDGE, "--params-file", str(path)], tmp / "bridge.log")
        try:
            code = finish(proc, RUN_TIMEOUT_S)
            bridge_code = finish(bridge, 10.0)  # it ends by itself once the run is over
        finally:
            stop(bridge)
    finally:
        stop(standin)
    yield {
        "code": code,
        "bridge_code": bridge_code,
        "bridge_log": (tmp / "bridge.log").read_text(errors="replace"),
        "out": out,
        "summary": json.loads((out / "summary.json").read_text()),
        "standin": json.loads(log.read_text()),
    }


def test_the_run_completes_on_the_broadcasters_clock_and_its_error_is_the_bags(
    run: dict[str, Any],
) -> None:
    """The run completes (exit 0, or 3/4/5 with its reason: the stand-in's Python loop
    stalls for tens of ms on a loaded machine and may trip the loop; 5 exactly when the
    misses exceed realtime.max_miss_fraction). The states carry the broadcaster's stamps
    from after the run started (its first messages are not step 0), in the suite's
    layout, x_table's NaN replaced as documented. The summary's tracking error is that
    of the bag's states against the references of their steps by the plant-clock rule,
    computed here."""
    out, done, standin = run["out"], run["summary"], run["standin"]
    code = run["code"]
    assert done["health"]["outcome"] == "complete", tails(out)
    assert code in (0, 3, 4, 5), tails(out)
    rt = done["realtime"]
    fraction = rt["misses"] / rt["ticks"]
    assert (code == 5) == (fraction > 0.05 and code not in (3, 4)), (code, fraction)
    assert run["bridge_code"] == 0, run["bridge_log"]
    bag = out / "bag"
    stamps, position, velocity, effort = joint_arrays(bag, f"{NS}/state")
    published = np.array(standin["stamps"])
    assert set(stamps.tolist()) <= set(published.tolist())  # the broadcaster's own stamps
    assert stamps[0] - published[0] > 10**9  # not its first message: the start rule
    assert np.all(np.diff(stamps) > 0)
    steps = plant_clock_steps(stamps)
    assert steps[-1] >= STEPS - 1  # the run ended on the broadcaster's clock
    assert_allclose(position[:, 1], LEAD * position[:, 0], rtol=1e-12, atol=0)
    assert_allclose(velocity[:, 1], LEAD * velocity[:, 0], rtol=1e-12, atol=0)  # NaN -> R w
    assert np.all(effort[:, 1] == 0.0)  # NaN friction force -> 0
    assert np.all(np.abs(effort[:, 0]) <= TORQUE_LIMIT)  # the torque the axis held
    rms = plant_clock_rms_m(bag, steps, position)
    assert_allclose(done["tracking_error"]["all_samples"]["rms_m"], rms, rtol=1e-9)


def test_every_torque_the_axis_applied_is_one_the_suite_sent(run: dict[str, Any]) -> None:
    """Each value the effort controller took is the torque of a recorded command, in the
    order sent; none was dropped or of another length; the axis moved unless the loop
    tripped (with two CPU hogs beside it the stand-in's Python loop stalled 53 ms between
    its first states and the feedback tripped on following error before the axis moved:
    exit 4, as the summary says)."""
    standin, out = run["standin"], run["out"]
    assert standin["dropped"] == 0 and not standin["deactivated"]
    command_stamps, _, _, torque = joint_arrays(out / "bag", f"{NS}/command")
    commands = torque[:, 0].tolist()
    taken = standin["taken"]
    assert len(taken) >= 100, len(taken)
    it = iter(commands)  # each taken value is the next recorded command it equals, in order
    assert all(any(t == c for c in it) for t in taken), taken[:5]
    stamps, position, _, _ = joint_arrays(out / "bag", f"{NS}/state")
    assert set(command_stamps.tolist()) <= set(stamps.tolist())  # each answers a state
    if run["code"] in (0, 5):  # not tripped: the axis followed the reference
        assert np.ptp(position[:, 0]) > 0.01, run["code"]  # rad


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
