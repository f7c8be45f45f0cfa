"""A point through the node graph (``backend: nodes``) gives the plain-call loop's figures."""

from __future__ import annotations

import pytest

from servo_axis.sweep import point
from servo_axis.sweep.point import run_point

pytestmark = pytest.mark.integration


def test_the_nodes_backend_reproduces_the_plain_backend(
    ros_env: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Point 7 runs in domain DOMAIN_BASE + 7: the test's own, not one of another suite's.
    monkeypatch.setattr(point, "DOMAIN_BASE", ros_env - 7)
    overrides = {"/**.duration_s": 0.5, "feedback.bandwidth_hz": 30.0}
    figures = {
        "max": "tracking_error.all_samples.max_m",
        "rms_last": "tracking_error.cycles[-1].rms_m",
        "steps": "steps",
    }
    plain = run_point(7, "pid_disturbance", overrides, figures, "plain")
    nodes = run_point(7, "pid_disturbance", overrides, figures, "nodes")
    assert plain["status"] == "ok" and nodes["status"] == "ok", nodes["error"]
    assert plain["steps"] == nodes["steps"] == 500
    assert plain["max"] > 0
    # The node graph reproduces the plain loop bit for bit.
    assert nodes["max"] == plain["max"] and nodes["rms_last"] == plain["rms_last"]
