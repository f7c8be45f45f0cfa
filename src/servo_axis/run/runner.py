"""Run a scenario end to end: prepare, start, watch, stop, summarise.

``python -m servo_axis run <scenario name or file> [--out DIR] [--composed]``

:func:`run_scenario` goes through the parts of :mod:`servo_axis.run` in
order. It prepares the run (:mod:`servo_axis.run.prepare`: the options
checked, the scenario resolved once into a plan,
:class:`~servo_axis.params.run_plan.RunPlan`, each axis's parameter file
written), starts the nodes (:mod:`servo_axis.run.start`), which connect
through their own handshakes (no fixed sleeps), watches them
(:mod:`servo_axis.run.watch`: ``recorder/progress`` for the progress line,
the node-death policy of :mod:`servo_axis.run.deaths`, the outside nodes,
stalls), and when the plant has finished stops the rest with SIGINT, then
SIGKILL after a timeout (:mod:`servo_axis.run.stop`). It then writes
``summary.json`` and the plots (:mod:`servo_axis.run.summarise`).

A node that dies during the run (node-death policy, docs/explanation/reliability.md):

* learning unit: the axis runs on (the feedforward generator keeps the last
  correction once the unit's liveliness has lapsed) and the runner starts
  it again (``late_join``), up to ``respawn_limit`` times; it resumes from
  its memory file;
* identifier: the axis waits for it (the feedforward publishes no sample
  an estimate not yet in applies to) while the runner starts it again
  (``late_join``), up to ``respawn_limit`` times; it resumes from its memory
  file and the streams' history, bit-identically; gone for longer than
  ``adaptive.timeout_s``, the feedforward keeps its last estimates;
* feedforward generator: the feedback loop trips to zero current (its
  reference's publisher is gone), the plant runs to the end, the bag closes;
* plant, feedback or recorder: the run stops, every process is reaped, the
  bag closes (a dead recorder's bag is recovered, :mod:`servo_axis.recording.recover`).

In every case ``summary.json``'s ``health``
(:class:`servo_axis.analysis.health.RunHealth`) says what happened, and
:attr:`RunResult.exit_code` is not 0.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from servo_axis.analysis.health import RunHealth
from servo_axis.realtime.supervisor import OvertimeCheck
from servo_axis.run.deaths import NodeDeaths
from servo_axis.run.live_view import LiveView, live_axis
from servo_axis.run.options import RunOptions as RunOptions
from servo_axis.run.prepare import PreparedRun, announce, prepare
from servo_axis.run.processes import discovery_settings, ros_environment
from servo_axis.run.progress import ProgressLine
from servo_axis.run.start import open_watchers, start_axes
from servo_axis.run.state import AxisNodes, RunState
from servo_axis.run.stop import close_run, recover_bags, stop_axes
from servo_axis.run.summarise import interruption, summarise_run, summary_of_the_recorded_part
from servo_axis.run.watch import (
    OutsidePlantGone,
    OutsideWait,
    StallCheck,
    Watch,
)
from servo_axis.stop_signals import catch_stop_signals, restore_handlers

if TYPE_CHECKING:
    from servo_axis.analysis.summary import AxesSummary, RunSummary


class RunError(RuntimeError):
    """The run could not complete (a node failed, stalled or refused its configuration).

    ``summary`` is what could be made of the bag recorded so far (None if nothing).
    """

    def __init__(self, text: str, summary: RunSummary | AxesSummary | None = None) -> None:
        super().__init__(text)
        self.summary = summary


class RunInterruptedError(RunError):
    """SIGINT or SIGTERM stopped the run; the nodes were stopped and the bag closed.

    ``summary`` is what could be made of the bag recorded so far (its
    ``health.outcome`` is ``interrupted``; None if nothing was recorded).
    """

    def __init__(
        self, text: str, signum: int, summary: RunSummary | AxesSummary | None = None
    ) -> None:
        super().__init__(text, summary)
        self.signum = signum


@dataclass
class RunResult:
    """Outcome of :func:`run_scenario`.

    Attributes
    ----------
    run_dir : Path
        The run directory (bag, summary, plots, logs; one directory per
        axis for a multi-axis scenario).
    steps : int
        Control steps of the run.
    wall_time_s : float
        Wall time of the run's steps (the summary's ``wall_time_s``).
    exit_codes : dict
        Exit code of each node (``<axis>/<role>`` for a multi-axis run).
    summary : RunSummary or AxesSummary
        What :mod:`servo_axis.analysis.summary` made of the run (also in
        ``summary.json``); an :class:`AxesSummary` (each axis's summary and
        their contour) for a multi-axis run.
    """

    run_dir: Path
    steps: int
    wall_time_s: float
    exit_codes: dict[str, int]
    summary: RunSummary | AxesSummary

    @property
    def health(self) -> RunHealth:
        """Deaths, restarts, fallbacks, strangers (``summary.json``'s ``health``)."""
        assert self.summary.health is not None
        return self.summary.health

    @property
    def exit_code(self) -> int:
        """0 deterministic and complete, 3 not deterministic, 4 fault (:mod:`~servo_axis.analysis.health`)."""
        return self.health.exit_code


def run_scenario(scenario: str | Path, options: RunOptions | None = None) -> RunResult:
    """Run one scenario end to end and return where it was written.

    ``scenario`` is a scenario file or the name of a shipped scenario
    (``"rptc_detailed"``); ``options`` how (:class:`RunOptions`; default:
    all defaults). A scenario with per-axis sections (``/x/<node>``,
    ``/y/<node>``) runs one set of nodes per axis, each in its own namespace
    with its own ``/<axis>/clock``, all at once; each axis gets a
    subdirectory of the run directory (its own bag, logs, summary) and the
    run's summary holds the per-axis summaries and the contour (XY) figures.
    Roles that outside nodes play (``options.external``, the scenario's
    ``external_roles``) are not started: the run says what they must serve
    and waits for them. ``os.environ`` is left as it was.

    Raises
    ------
    ConfigError
        For a scenario that cannot be found, loaded or planned, or a bad
        option (:func:`~servo_axis.run.prepare.prepare`): before anything is
        written or started.
    RunError
        If the plant, the feedback or the recorder dies, a learning unit
        dies more than ``respawn_limit`` times, the run stalls, or a node
        refuses its parameters (its message is in the error; the summary of
        what was recorded, if any, in ``RunError.summary``).
    RunInterruptedError
        If SIGINT or SIGTERM reached the runner (called from the main
        thread): the nodes are stopped, the bag written so far is closed and
        readable, and ``summary.json`` holds what was recorded (``health.outcome``
        ``interrupted``).
    """
    run = prepare(scenario, options or RunOptions())
    plan, options = run.plan, run.options
    announce(run)
    line = ProgressLine(plan.steps, options.progress) if options.progress is not None else None
    axes, state = _run_nodes(run, line)
    recovered = recover_bags(axes)
    note = f"\nsummary of what was recorded: {plan.run_dir / 'summary.json'}"
    if state.signals:
        state.interrupted = interruption(axes, state, plan.steps)
        summary = summary_of_the_recorded_part(axes, plan, state, recovered)
        text = state.interrupted + (note if summary else "")
        raise RunInterruptedError(text, state.signals[0], summary)
    if state.failure is not None:
        summary = summary_of_the_recorded_part(axes, plan, state, recovered)
        raise RunError(state.failure + (note if summary else ""), summary)
    summary = summarise_run(
        axes, plan, state, plots=options.plots, recovered=recovered, floor=options.floor
    )
    if line is not None:
        line.show(plan.steps, summary.wall_time_s, final=True)
    return RunResult(plan.run_dir, plan.steps, summary.wall_time_s, state.exit_codes, summary)


def _run_nodes(run: PreparedRun, line: ProgressLine | None) -> tuple[list[AxisNodes], RunState]:
    """Start every axis's nodes, watch them until the plants are done, stop them all.

    With a live view, it is started first (the runner waits until it
    listens and prints its URL) and stopped after the nodes.
    """
    plan, options = run.plan, run.options
    axes = [AxisNodes(axis) for axis in plan.axes]
    logs = plan.axes[0].logs
    env = ros_environment(run.domain_id, logs, realtime=plan.realtime)
    state = RunState()
    started = time.time()  # epoch, for the shared-memory clean-up
    live = None
    if options.live_port is not None:
        live = LiveView(options.live_port, [live_axis(a) for a in plan.axes], options.progress)
    try:
        open_watchers(axes, run.domain_id, discovery_settings(logs, realtime=plan.realtime))
        state.t_start = time.monotonic()
        state.t_start_epoch = started
        previous_handlers = catch_stop_signals(state.signals)
        try:
            if live is not None:
                live.start(
                    env, logs if len(axes) == 1 else plan.run_dir, lambda: bool(state.signals)
                )
            start_axes(axes, env, options)
            _watch(axes, state, line, run)
        finally:
            stop_axes(axes, state)
            restore_handlers(previous_handlers)
    finally:
        close_run(axes, live, started)
    return axes, state


def _watch(
    axes: list[AxisNodes], state: RunState, line: ProgressLine | None, run: PreparedRun
) -> None:
    """Watch the started nodes until the run ends (:class:`~servo_axis.run.watch.Watch`)."""
    options = run.options
    Watch(
        axes,
        state,
        line,
        deaths=NodeDeaths(axes, options.respawn_limit),
        outside=OutsideWait(axes, options.external_timeout_s, options.progress),
        stall=StallCheck(options.stall_timeout_s, run.plan.run_dir),
        checks=[
            OutsidePlantGone(axes),
            *[
                OvertimeCheck(axis.steps * axis.control_period_s)
                for axis in run.plan.axes
                if axis.realtime
            ][:1],
        ],
    ).run()
