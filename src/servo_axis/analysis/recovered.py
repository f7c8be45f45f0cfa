"""The summary of a run whose runner ended before writing it: from its directory alone.

A runner killed with its nodes (SIGKILL of the whole run, the machine going
down) leaves a run directory with an unfinished bag and no
``summary.json``. Once ``bag recover`` has made the bag readable (and
calls :func:`summarise_unfinished`), the run gets the summary of what it
recorded, so that every command reads it as any run. Nothing here imports
rclpy.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from servo_axis.analysis.health import assess
from servo_axis.analysis.summary import SUMMARY_FILE, RunSummary, summarise
from servo_axis.params.factories import run_steps
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.resolve import Resolved
from servo_axis.recording.reader import UNFINISHED_SUFFIX
from servo_axis.wire.node_report import read_health


def summarise_unfinished(run_dir: Path) -> RunSummary:
    """Write ``summary.json`` of a run whose runner ended before it did so, from what was recorded.

    A runner killed with its nodes (SIGKILL of the whole run, the machine
    going down) leaves a run directory without ``summary.json`` and an
    unfinished bag; once ``bag recover`` has made the bag readable, this
    writes the summary of its recorded part, as the runner does for a run
    that failed: from the run's own scenario
    (:func:`~servo_axis.params.recorded.recorded_scenario`), the bag and the
    nodes' reports that were written. Its ``health`` is ``failed`` (exit 1),
    its first reason how many of the run's steps were recorded; the wall
    time is not known (NaN). ``bag recover`` calls it (no plots).

    Raises
    ------
    ConfigError
        If ``run_dir`` recorded no scenario (not a single-axis run directory).
    SignalError, BagError
        If the bag cannot be summarised (unreadable, too short).
    """
    run_dir = Path(run_dir)
    recorded = recorded_scenario(run_dir)
    resolved = Resolved(recorded.scenario, recorded.path)
    planned = run_steps(resolved.plant)
    summary = summarise(
        run_dir,
        scenario=resolved,
        scenario_path=recorded.path,
        source_file=recorded.started_from,
        wall_time_s=math.nan,
        mode="composed" if (run_dir / "logs" / "composed.log").is_file() else "separate processes",
    )
    recovered = any((run_dir / "bag").glob(f"*{UNFINISHED_SUFFIX}*"))
    failure = (
        f"the run ended before its runner wrote summary.json (killed with its nodes?): "
        f"{summary.steps} of its {planned} steps were recorded; this summary of them was "
        "made afterwards (bag recover)"
    )
    reports = read_health(run_dir / "logs")
    health = assess(
        failure=failure,
        deaths=[],
        reports=reports,
        faults=len(summary.faults),
        bag_recovered=recovered,
        realtime=summary.time_mode == "realtime",
    )
    summary = dataclasses.replace(summary, health=health)
    (run_dir / SUMMARY_FILE).write_text(summary.to_json())
    return summary
