"""The typed summary: exact JSON round trips and the text layout of summary.json."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.signals import FaultRecord
from servo_axis.analysis.summary import (
    AxesSummary,
    CycleStats,
    ErrorStats,
    RunSummary,
    TrackingError,
    load_summary,
    summary_from_dict,
)
from servo_axis.analysis.text import format_summary


def old_way(tracking_error: dict[str, Any], **over: Any) -> dict[str, Any]:
    """A summary mapping with the keys, in the order, the report module wrote them."""
    steps, period, wall = 1999, 1e-3, 0.7300000000000001
    summary = {
        "scenario": "rptc_ideal",
        "description": "ideal plant; RPTC from cycle 3",
        "scenario_file": "/somewhere/rptc_ideal.yaml",
        "processes": "processes",
        "time_mode": "lockstep",
        "control_period_s": period,
        "steps": steps,
        "sim_time_s": steps * period,
        "wall_time_s": wall,
        "steps_per_s": steps / wall,
        "realtime_factor": steps * period / wall,
        "message_counts": {"/x/state": 1999, "/clock": 200, "/x/reference": 2199, "/x/fault": 1},
        "faults": [
            {"step": 1500, "code": 1, "name": "following_error", "value": 0.0021000000000000003}
        ],
        "ptc": True,
        "friction_table": False,
        "reference_period_s": 0.5,
        "tracking_error": tracking_error,
    }
    summary.update(over)
    return summary


def stats(cycle_s: float | None) -> dict[str, Any]:
    rng = np.random.default_rng(11)
    step = np.arange(1, 2000)
    return error_statistics(
        rng.normal(scale=1e-7, size=step.size), step, period_s=1e-3, cycle_s=cycle_s
    )


@pytest.mark.parametrize("cycle_s", [0.5, None])
def test_run_summary_json_is_the_old_text_and_round_trips_exactly(
    cycle_s: float | None, tmp_path: Path
) -> None:
    old = old_way(stats(cycle_s), reference_period_s=cycle_s)
    old_text = json.dumps(old, indent=2, allow_nan=True)
    summary = RunSummary.from_dict(old)
    assert summary.to_json() == old_text
    assert summary.to_dict() == old
    assert list(summary.to_dict()) == list(old)
    assert RunSummary.from_json(old_text) == summary
    assert RunSummary.from_json(summary.to_json()).to_json() == old_text
    (tmp_path / "summary.json").write_text(old_text)
    assert RunSummary.from_json(tmp_path / "summary.json") == summary
    assert RunSummary.from_json(str(tmp_path / "summary.json")) == summary
    assert load_summary(tmp_path) == summary


def test_run_summary_fields_are_typed() -> None:
    summary = RunSummary.from_dict(old_way(stats(0.5)))
    assert summary.faults == (
        FaultRecord(step=1500, code=1, name="following_error", value=0.0021000000000000003),
    )
    te = summary.tracking_error
    assert isinstance(te, TrackingError)
    assert isinstance(te.all_samples, ErrorStats)
    assert all(isinstance(c, CycleStats) for c in te.cycles)
    assert [c.cycle for c in te.cycles] == [2, 3, 4]  # cycle 1 misses step 0
    assert te.after_first_cycle is not None
    # health is optional: the runner adds it, a summary made from a bag alone
    # has none; period_name is written only for trials
    assert {f.name for f in dataclasses.fields(RunSummary)} == set(old_way({})) | {
        "health",
        "period_name",
        "ilc_convergence",
        "error_unit",
        "identification",
        "deformation",
        "realtime",
        "startup_s",
        "finish_s",
        "overrides",
        "numerics",
    }
    assert summary.realtime is None and "realtime" not in summary.to_dict()
    # overrides: written only for a run given --set, kept as given, and shown
    assert summary.overrides is None and "overrides" not in summary.to_dict()
    # numerics: written by the runner (portable, native or host), absent from a bag alone
    assert summary.numerics is None and "numerics" not in summary.to_dict()
    pinned = dataclasses.replace(summary, numerics="portable")
    assert RunSummary.from_dict(pinned.to_dict()).numerics == "portable"
    given = ("shared.duration_s=1", "feedback.dob={enabled: true}")
    with_sets = dataclasses.replace(summary, overrides=given)
    assert with_sets.to_dict()["overrides"] == list(given)
    assert RunSummary.from_json(with_sets.to_json()) == with_sets
    assert (
        "overrides         --set shared.duration_s=1 --set 'feedback.dob={enabled: true}'"
        in format_summary(with_sets)
    )
    assert summary.startup_s is None and "startup_s" not in summary.to_dict()
    assert summary.ilc_convergence is None and "ilc_convergence" not in summary.to_dict()
    assert summary.period_name is None and "period_name" not in summary.to_dict()
    # error_unit (rad for a rotary table) and identification (paper 003) likewise
    assert summary.error_unit is None and summary.unit == "m"
    assert summary.identification is None and summary.deformation is None
    assert not {"error_unit", "identification", "deformation"} & set(summary.to_dict())
    trials = dataclasses.replace(
        summary,
        period_name="trial",
        ilc_convergence={"nq": 16, "nominal": 0.0223, "plant": 0.2526},
    )
    assert RunSummary.from_json(trials.to_json()) == trials
    assert "trial   RMS (um)" in format_summary(trials)
    assert "0.0223 (nominal), 0.2526 (plant), Nq = 16" in format_summary(trials)
    assert "cycle   RMS (um)" in format_summary(summary)
    with pytest.raises(dataclasses.FrozenInstanceError):
        summary.steps = 3  # type: ignore[misc]


def test_nan_values_survive_the_round_trip() -> None:
    te = error_statistics(np.array([]), np.array([], dtype=int), period_s=1e-3, cycle_s=None)
    old = old_way(te, wall_time_s=0.0, steps_per_s=math.nan, realtime_factor=math.nan)
    text = json.dumps(old, indent=2, allow_nan=True)
    summary = RunSummary.from_json(text)
    assert summary.to_json() == text
    assert math.isnan(summary.tracking_error.all_samples.rms_m)
    assert '"steps_per_s": NaN' in text


def test_axes_summary_round_trips_and_dispatches(tmp_path: Path) -> None:
    x, y = old_way(stats(0.5)), old_way(stats(None), scenario="xy/y")
    contour = {
        "axes": ["x", "y"],
        "centre_m": [0.01, -2.5e-17],
        "radius_m": 0.009999999999999998,
        "target_radial_deviation_m": 3.469446951953614e-18,
        "circular_deviation_m": 1.2e-06,
        "max_radial_m": 7e-07,
        "cycles": [{"cycle": 1, "circular_deviation_m": 1.2e-06, "max_radial_m": 7e-07}],
    }
    old = {
        "scenario": "xy",
        "description": "two axes",
        "wall_time_s": 3.5,
        "axes": {"x": x, "y": y},
        "contour": contour,
    }
    text = json.dumps(old, indent=2, allow_nan=True)
    summary = AxesSummary.from_json(text)
    assert summary.to_json() == text
    assert summary.axes["y"] == RunSummary.from_dict(y)
    assert summary.contour is not None and summary.contour.axes == ("x", "y")
    assert isinstance(summary_from_dict(old), AxesSummary)
    assert isinstance(summary_from_dict(x), RunSummary)
    (tmp_path / "summary.json").write_text(text)
    assert load_summary(tmp_path) == summary
    one = {k: v for k, v in old.items() if k != "contour"}
    one["axes"] = {"x": x}
    lone = AxesSummary.from_dict(one)
    assert lone.contour is None
    assert lone.to_json() == json.dumps(one, indent=2, allow_nan=True)
