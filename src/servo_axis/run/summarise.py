"""Summarising a run: each axis's ``summary.json`` with its health, the plots, the contour.

The summary itself is the analysis's (:mod:`servo_axis.analysis.summary`,
from the bag and the axis's scenario); the runner adds what only it saw:
the wall time of the plant's steps (:func:`stepping_span`), the health of
the run (:func:`~servo_axis.analysis.health.assess`: deaths, restarts,
fallbacks, strangers, why it stopped) and, in realtime, the nodes' counts
of their clock with the host's floor. A run that failed or was interrupted
gets the summary of what was recorded, without plots, if its bag allows
one (:func:`summary_of_the_recorded_part`).
"""

from __future__ import annotations

import dataclasses
import signal
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from servo_axis import numerics
from servo_axis.analysis.health import EXIT_LOOP_NOT_CLOSED, NodeDeath, assess, loop_not_closed
from servo_axis.params.run_plan import RunPlan
from servo_axis.run.state import AxisNodes, RunState
from servo_axis.wire.node_report import NodeHealth, read_health

if TYPE_CHECKING:
    from servo_axis.analysis.summary import AxesSummary, RunSeries, RunSummary


def stepping_span(
    plant: NodeHealth | None, started_s: float, ended_s: float
) -> tuple[float, float] | None:
    """When the plant's steps ran: ``(first_s, last_s)`` on ``time.monotonic()``'s clock.

    From the plant's report (:attr:`~servo_axis.wire.node_report.NodeHealth.stepping`):
    state 0 out, the last step integrated. None when it did not report them
    (an outside plant, a run stopped before its end) or when they do not lie
    within the runner's ``started_s`` .. ``ended_s`` (the node processes'
    start and stop): then the run's wall time is the runner's view.
    """
    stepping = plant.stepping if plant is not None else {}
    try:
        first, last = float(stepping["first_s"]), float(stepping["last_s"])
    except (KeyError, TypeError, ValueError):
        return None
    if not started_s < first <= last <= ended_s:
        return None
    return first, last


@dataclass
class _Axes:
    """What the axes' summaries gather for the run's."""

    summaries: dict[str, RunSummary] = field(default_factory=dict)
    deaths: list[NodeDeath] = field(default_factory=list)
    reports: dict[str, NodeHealth] = field(default_factory=dict)
    spans: list[tuple[float, float]] = field(default_factory=list)


def summarise_run(
    axes: list[AxisNodes],
    plan: RunPlan,
    state: RunState,
    *,
    plots: bool,
    recovered: set[str] | None = None,
    floor: dict[int, dict[str, Any]] | None = None,
) -> RunSummary | AxesSummary:
    """Write each axis's ``summary.json`` (with its health) and plots, and the contour of a multi-axis run.

    A realtime run's summary holds the plant's report on its clock
    (``realtime``), with the host's floor at its period from ``floor``
    (``python -m servo_axis floor --json`` results by period in us) if given.
    """
    from servo_axis.analysis import plots as figures
    from servo_axis.analysis import summary as summaries

    recovered = recovered or set()
    gathered = _Axes()
    for axis in axes:
        series, reports, span = _summarise_axis(axis, plan, state, recovered, floor)
        summary = series.summary
        (axis.plan.dir / summaries.SUMMARY_FILE).write_text(summary.to_json())
        gathered.summaries[axis.plan.axis] = summary
        gathered.deaths += axis.deaths
        gathered.reports.update({axis.where(role): h for role, h in reports.items()})
        if span is not None:
            gathered.spans.append(span)
        if plots:
            figures.plot(axis.plan.dir, series=series)  # the signals the summary read
    if not plan.multi_axis:
        return gathered.summaries[""]
    axes_summary = _summarise_axes(plan, state, gathered, bool(recovered))
    if plots:
        figures.plot_contour(plan.run_dir)
    return axes_summary


def _summarise_axis(
    axis: AxisNodes,
    plan: RunPlan,
    state: RunState,
    recovered: set[str],
    floor: dict[int, dict[str, Any]] | None,
) -> tuple[RunSeries, dict[str, NodeHealth], tuple[float, float] | None]:
    """One axis's summary with its health and realtime block (with the signals it read); its
    nodes' reports; the plant's steps."""
    from servo_axis.analysis import summary as summaries

    reports = read_health(axis.plan.logs)
    span = stepping_span(reports.get("plant"), state.t_start, state.t_end)
    series = summaries.summarise_series(
        axis.plan.dir,
        scenario=axis.plan.summary_scenario(),
        scenario_path=axis.plan.scenario_path,
        source_file=axis.plan.source_path,
        wall_time_s=state.wall_time_s if span is None else span[1] - span[0],
        mode="composed" if plan.composed else "separate processes",
    )
    summary = series.summary
    if span is not None:
        summary = dataclasses.replace(
            summary, startup_s=span[0] - state.t_start, finish_s=state.t_end - span[1]
        )
    plant = reports.get("plant")
    # The feedback's and the generator's counts, with the plant's clock: the
    # suite's plant's report, or of an outside plant the loop as the feedback
    # measured it.
    counts = {k: v for h in reports.values() for k, v in h.realtime.items()}
    rt = None
    if plant is not None and plant.realtime:
        rt = summaries.Realtime.from_dict({**counts, **plant.realtime})
    elif "ticks" in counts:
        rt = summaries.Realtime.from_dict(counts)  # an outside plant: the feedback's figures
    if rt is not None:
        at = (floor or {}).get(round(rt.period_ns / 1000))
        rt = dataclasses.replace(rt, floor=at)
    summary = dataclasses.replace(summary, realtime=rt)
    realtime = summary.time_mode == "realtime"
    health = assess(
        failure=state.failure,
        interrupted=state.interrupted,
        deaths=axis.deaths,
        reports=reports,
        faults=len(summary.faults),
        bag_recovered=axis.plan.axis in recovered,
        realtime=realtime,
        open_loop=loop_not_closed(summary.realtime, axis.plan.max_miss_fraction, reports)
        if realtime
        else None,
    )
    summary = dataclasses.replace(
        summary, health=health, overrides=plan.overrides or None, numerics=numerics.mode()
    )
    return dataclasses.replace(series, summary=summary), reports, span


def _summarise_axes(
    plan: RunPlan, state: RunState, gathered: _Axes, recovered: bool
) -> AxesSummary:
    """The run's summary of several axes: theirs, the run's health, the contour."""
    from servo_axis.analysis import summary as summaries

    per_axis = gathered.summaries
    open_loops = [
        s.health.reasons[0]
        for s in per_axis.values()
        if s.health is not None and s.health.exit_code == EXIT_LOOP_NOT_CLOSED
    ]
    health = assess(
        failure=state.failure,
        interrupted=state.interrupted,
        deaths=gathered.deaths,
        reports=gathered.reports,
        faults=sum(len(s.faults) for s in per_axis.values()),
        bag_recovered=recovered,
        realtime=any(s.time_mode == "realtime" for s in per_axis.values()),
        open_loop=open_loops[0] if open_loops else None,
    )
    spans = gathered.spans
    stepped = max(b for _, b in spans) - min(a for a, _ in spans) if spans else None
    return summaries.summarise_axes(
        plan.run_dir,
        scenario=plan.scenario,
        axes=per_axis,
        wall_time_s=state.wall_time_s
        if stepped is None or len(spans) < len(plan.axes)
        else stepped,
        health=health,
        overrides=plan.overrides or None,
    )


def summary_of_the_recorded_part(
    axes: list[AxisNodes], plan: RunPlan, state: RunState, recovered: set[str]
) -> RunSummary | AxesSummary | None:
    """``summary.json`` of a failed or interrupted run (no plots); None if the bag does not allow one."""
    try:
        return summarise_run(axes, plan, state, plots=False, recovered=recovered)
    except Exception as err:  # the bag may be too short to summarise
        print(f"no summary of the recorded part: {err}", file=sys.stderr)
        return None


def interruption(axes: list[AxisNodes], state: RunState, steps: int) -> str:
    """What a run stopped by a signal says: the signal, the step, where the bag is."""
    signame = signal.Signals(state.signals[0]).name
    bags = ", ".join(str(axis.plan.bag) for axis in axes if axis.plan.bag.is_dir())
    kept = f"the bag written so far is in {bags}" if bags else "no bag had been started yet"
    return (
        f"interrupted by {signame} at step {max(state.steps, 0)} of {steps}; "
        f"the nodes were stopped, {kept}"
    )
