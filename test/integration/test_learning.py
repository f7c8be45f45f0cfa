"""RPTC through the real node graph (paper 000, Sect. V-A): eq. (27) on the axis."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import pytest

from servo_axis.bringup import run_scenario

pytestmark = pytest.mark.integration

CONFIG = Path(__file__).resolve().parents[2] / "config"


def cycle_rms(summary: dict, cycle: int) -> float:
    (row,) = [c for c in summary["tracking_error"]["cycles"] if c["cycle"] == cycle]
    return float(row["rms_m"])


def test_n_times_filter_learns_n_times_faster_through_the_node_graph(
    ros_env: int, tmp_path: Path
) -> None:
    q3 = run_scenario(
        CONFIG / "rptc_ideal.yaml", out_dir=tmp_path / "q3", domain_id=ros_env, progress=None
    )
    q1 = run_scenario(
        CONFIG / "rptc_ideal_q.yaml", out_dir=tmp_path / "q1", domain_id=ros_env, progress=None
    )
    for run in (q3, q1):
        counts = run.summary["message_counts"]
        assert counts["/learning/correction"] == 6 * 250  # one correction per cycle boundary
        assert counts["/learning/cycle_stats"] == 6  # not for the cycle that ends the run
        assert not run.summary["faults"]
    # Learning cycle m is axis cycle m + 1 (cycle 1 lets the disturbance
    # response settle). Eq. (27): after 1 learning cycle with Q~3 the error
    # equals the error after 3 learning cycles with Q.
    ratio = cycle_rms(q3.summary, 3) / cycle_rms(q1.summary, 5)
    assert ratio == pytest.approx(1.0, abs=0.05)
    # Both far below the error before learning, and Q~3 ahead of Q at the
    # same cycle.
    before = cycle_rms(q3.summary, 2)
    assert cycle_rms(q3.summary, 3) < 1e-3 * before
    assert cycle_rms(q3.summary, 3) < 1e-2 * cycle_rms(q1.summary, 3)
    assert (q3.run_dir / "learning_memory.json").is_file()


def max_per_cycle(summary: dict) -> list[float]:
    return [float(c["max_m"]) for c in summary["tracking_error"]["cycles"]]


def test_detailed_axis_learns_and_is_deterministic(
    ros_env: int, tmp_path: Path, raw_payloads: Any
) -> None:
    q5 = run_scenario(
        CONFIG / "rptc_detailed.yaml", out_dir=tmp_path / "q5", domain_id=ros_env, progress=None
    )
    q1 = run_scenario(
        CONFIG / "rptc_detailed_q.yaml", out_dir=tmp_path / "q1", domain_id=ros_env, progress=None
    )
    again = run_scenario(
        CONFIG / "rptc_detailed.yaml",
        out_dir=tmp_path / "again",
        domain_id=ros_env,
        composed=True,
        progress=None,
    )
    # 000 Fig. 15: the max error falls cycle after cycle (6 cycles here), and
    # faster with Q~5 than with Q despite modes, dead time and friction.
    for run in (q5, q1):
        peaks = max_per_cycle(run.summary)
        assert len(peaks) == 6
        assert all(b < a for a, b in itertools.pairwise(peaks)), peaks
        assert not run.summary["faults"]
    assert max_per_cycle(q5.summary)[2] < 0.75 * max_per_cycle(q1.summary)[2]
    # Determinism across cycle boundaries: separate processes vs composed,
    # learning messages included.
    a, b = raw_payloads(q5.run_dir / "bag"), raw_payloads(again.run_dir / "bag")
    for topic in (
        "/state",
        "/command",
        "/reference",
        "/learning/correction",
        "/learning/cycle_stats",
    ):
        assert a[topic] == b[topic], topic
    assert len(a["/learning/correction"]) == 5 * 250
