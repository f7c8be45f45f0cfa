"""Two axes in one run (000 Fig. 18): namespaces, clocks, the contour error."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from servo_axis.run.runner import RunOptions, run_scenario

pytestmark = pytest.mark.integration

CONFIG = Path(__file__).resolve().parents[2] / "config"


def test_xy_circle_runs_two_namespaced_axes_and_circularity_falls(
    ros_env: int, tmp_path: Path
) -> None:
    from rosbags.highlevel import AnyReader

    result = run_scenario(
        CONFIG / "xy_circle.yaml",
        RunOptions(out_dir=tmp_path / "xy", domain_id=ros_env, progress=None),
    )
    s = result.summary.to_dict()
    assert sorted(s["axes"]) == ["x", "y"]
    angles = {}
    for axis in ("x", "y"):
        axis_summary = s["axes"][axis]
        assert not axis_summary["faults"]
        counts = axis_summary["message_counts"]
        # Each axis has its own namespace and its own clock.
        assert counts[f"/{axis}/state"] == counts[f"/{axis}/command"] == 3000
        assert counts[f"/{axis}/clock"] == 300
        with AnyReader([result.run_dir / axis / "bag"]) as reader:
            (conn,) = [c for c in reader.connections if c.topic == f"/{axis}/state"]
            angles[axis] = np.array(
                [
                    reader.deserialize(raw, conn.msgtype).position[0]
                    for _, _, raw in reader.messages([conn])
                ]
            )
    # The contour error computed here from the bags and the circle the
    # scenario asks for (centre (R, 0), radius R = 10 mm), independently of
    # the report's fitted circle.
    radius, lead = 0.01, 0.00191
    radial = np.hypot(lead * angles["x"] - radius, lead * angles["y"]) - radius
    per_cycle = radial.reshape(6, 500)
    deviation = per_cycle.max(axis=1) - per_cycle.min(axis=1)
    reported = [c["circular_deviation_m"] for c in s["contour"]["cycles"]]
    np.testing.assert_allclose(reported, deviation, rtol=0, atol=1e-11)  # 0.01 nm: the fit
    assert s["contour"]["radius_m"] == pytest.approx(radius, rel=1e-9)
    # Friction table from cycle 1, RPTC learning from cycle 2: the
    # circularity falls every cycle and ends well below the first.
    assert all(b < a for a, b in itertools.pairwise(deviation)), deviation
    assert deviation[-1] < 0.25 * deviation[0]
    assert (result.run_dir / "contour.png").is_file()
