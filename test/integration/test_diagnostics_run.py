"""A run seen the ROS way: /diagnostics read by a default-QoS subscriber during a real run."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

pytestmark = pytest.mark.integration

ROLES = ("plant", "feedback", "feedforward", "recorder")


def test_every_node_reports_on_diagnostics_during_a_run(ros_env: int, tmp_path: Path) -> None:
    """``python -m servo_axis run ptc_nominal``: each node's status, its level and values."""
    ctx = Context()
    rclpy.init(args=[], context=ctx)
    node = rclpy.create_node("diagnostics_reader", context=ctx)
    seen: dict[str, list[DiagnosticStatus]] = {}

    stamps_of: dict[str, list[Any]] = {}

    def on_array(msg: Any) -> None:
        for status in msg.status:
            seen.setdefault(status.name, []).append(status)
            stamps_of.setdefault(status.name, []).append(msg.header.stamp)

    node.create_subscription(DiagnosticArray, "/diagnostics", on_array, 10)  # default QoS
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    run = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "run", "ptc_nominal", "--out", str(tmp_path / "run"),
         "--domain-id", str(ros_env), "--no-plots"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while run.poll() is None:
            assert time.monotonic() < deadline, "the run did not end"
            ex.spin_once(timeout_sec=0.05)
        for _ in range(20):  # what is still on its way
            ex.spin_once(timeout_sec=0.01)
        out = run.stdout.read() if run.stdout else ""
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert run.returncode == 0, out
    assert f"ROS 2: ROS_DOMAIN_ID={ros_env}, namespace /x (nodes /x/plant" in out  # the header
    # --no-plots: no PNG written, and none announced.
    assert (
        f"run directory: {tmp_path / 'run'}  (bag/, summary.json, scenario.yaml, params.yaml, logs/)"
        in out
    ), out[-800:]
    assert not list((tmp_path / "run").rglob("*.png"))
    names = {f"/x/{role}" for role in ROLES}
    assert names <= set(seen), sorted(seen)
    for name in names:
        statuses = seen[name]
        assert {s.hardware_id for s in statuses} == {"x"}
        assert {s.level for s in statuses} == {DiagnosticStatus.OK}, [s.message for s in statuses]
        values = {kv.key: kv.value for kv in statuses[-1].values}
        assert values["rejected"] == "0" and values["fallbacks"] == "0"
    plant = [{kv.key: kv.value for kv in s.values} for s in seen["/x/plant"]]
    assert all(p["mode"] == "lockstep" and p["deadline_misses"] == "0" for p in plant)
    steps = [int(p["step"]) for p in plant]
    assert steps == sorted(steps) and 0 <= steps[0] <= 2000
    # Every status is stamped on the simulation timeline, as the bag's messages
    # (docs/reference/topics.md): the plant at its step, the /clock consumers at
    # their sim time, the recorder at the simulation time it has seen (it was
    # once the wall clock's, 1.8e9 s, among stamps of a few seconds).
    end_ns = 2_000 * 1_000_000  # ptc_nominal: 2000 steps of 1 ms
    for name in names:
        stamps = [s.sec * 1_000_000_000 + s.nanosec for s in stamps_of[name]]
        assert all(0 <= t <= end_ns for t in stamps), (name, stamps)
        assert stamps == sorted(stamps), name
    assert [s.sec * 10**9 + s.nanosec for s in stamps_of["/x/plant"]] == [
        int(p["step"]) * 1_000_000 for p in plant
    ]
    feedback = {kv.key: kv.value for kv in seen["/x/feedback"][-1].values}
    assert feedback["tripped"] == "false" and feedback["fault"] == "none"
