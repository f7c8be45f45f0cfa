"""Run a scenario end to end: prepare, start, watch, stop, summarise.

``python -m servo_axis run <scenario name or file> [--out DIR] [--composed]``

The runner writes each axis's parameter file (:mod:`servo_axis.run.plan`),
starts the nodes (:mod:`servo_axis.run.processes`), waits for them to
connect through their own handshakes (no fixed sleeps), follows
``recorder/progress`` to show progress (:mod:`servo_axis.run.progress`), and
when the plant has finished it stops the rest with SIGINT, then SIGKILL
after a timeout. It then writes ``summary.json`` and the plots
(:mod:`servo_axis.analysis`).
"""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from servo_axis.core.errors import ConfigError
from servo_axis.params.factories import checked_values, node_values, run_steps
from servo_axis.params.scenario import (
    axes_of,
    axis_view,
    dump_params,
    find_scenario,
    load_scenario,
    node_params,
    roles_of,
    shared,
)
from servo_axis.run.plan import handshake_overrides, write_run_params
from servo_axis.run.processes import (
    Proc,
    default_domain_id,
    discovery_settings,
    ros_environment,
    start_nodes,
    stop_nodes,
)
from servo_axis.run.progress import ProgressLine, ProgressWatcher
from servo_axis.stop_signals import catch_stop_signals, restore_handlers

if TYPE_CHECKING:
    from servo_axis.analysis.summary import AxesSummary, RunSummary

#: The roles whose clean exit means "the run is complete".
PLANT_ROLES = ("plant", "composed")
#: Seconds the watch loop waits per pass (shared by the axes).
POLL_S = 0.05


class RunError(RuntimeError):
    """The run could not complete (a node failed, stalled or refused its configuration)."""


class RunInterruptedError(RunError):
    """SIGINT or SIGTERM stopped the run; the nodes were stopped and the bag closed."""

    def __init__(self, text: str, signum: int) -> None:
        super().__init__(text)
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
        Wall time from the first recorded step to the end.
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


@dataclass
class _AxisRun:
    """The nodes of one axis in a run."""

    axis: str  # "" for a single-axis scenario
    namespace: str
    scenario: dict[str, Any]
    scenario_path: Path
    out_dir: Path
    roles: list[str]
    params_path: Path
    args: list[str]
    procs: list[Proc] = field(default_factory=list)
    watcher: ProgressWatcher | None = None

    @property
    def log_dir(self) -> Path:
        return self.out_dir / "logs"

    @property
    def plant_done(self) -> bool:
        plant = next((p for p in self.procs if p.role in PLANT_ROLES), None)
        return plant is not None and plant.popen.poll() == 0


@dataclass
class _Watch:
    """What the watch loop saw: progress, times, why it stopped."""

    steps: int = -1  # the slowest axis's recorded steps
    t_start: float = field(default_factory=time.monotonic)
    t_first: float | None = None  # the first recorded step
    t_end: float = 0.0
    failure: str | None = None
    signals: list[int] = field(default_factory=list)
    exit_codes: dict[str, int] = field(default_factory=dict)

    @property
    def wall_time_s(self) -> float:
        return self.t_end - (self.t_first or self.t_start)


def run_scenario(
    scenario: str | Path,
    *,
    out_dir: Path | None = None,
    composed: bool = False,
    domain_id: int | None = None,
    namespace: str = "",
    progress: TextIO | None = sys.stdout,
    stall_timeout_s: float = 60.0,
    plots: bool = True,
    extra_args: list[str] | None = None,
    on_started: Callable[[list[Proc]], object] | None = None,
) -> RunResult:
    """Run one scenario end to end and return where it was written.

    ``scenario`` is a scenario file or the name of a shipped scenario
    (``"rptc_detailed"``). A scenario with per-axis sections (``/x/<node>``,
    ``/y/<node>``) runs one set of nodes per axis, each in its own namespace
    with its own ``/<axis>/clock``, all at once; each axis gets a
    subdirectory of the run directory (its own bag, logs, summary) and the
    run's summary holds the per-axis summaries and the contour (XY) figures.
    ``os.environ`` is left as it was.

    Raises
    ------
    ConfigError
        For a scenario that is neither a file nor a shipped scenario, or
        not a valid scenario; for an ``out_dir`` that is not empty.
    RunError
        If a node exits with an error, the run stalls, or a node refuses its
        parameters (its message is in the error).
    RunInterruptedError
        If SIGINT or SIGTERM reached the runner (called from the main
        thread): the nodes are stopped, the bag written so far is closed and
        readable, no summary is made.
    """
    scenario_path = find_scenario(scenario).resolve()
    data = load_scenario(scenario_path)
    common = shared(data)
    steps = run_steps(node_values(data, "plant"))
    run_dir = _new_run_dir(out_dir, common.get("scenario", {}).get("name") or scenario_path.stem)
    runs = prepare_axis_runs(
        data, scenario_path, run_dir, composed=composed, namespace=namespace, extra_args=extra_args
    )
    domain = default_domain_id() if domain_id is None else domain_id
    line = ProgressLine(steps, progress) if progress is not None else None
    watch = _run_nodes(runs, domain, composed, line, stall_timeout_s, on_started, run_dir)
    if watch.signals:
        signame = signal.Signals(watch.signals[0]).name
        bags = ", ".join(str(run.out_dir / "bag") for run in runs)
        raise RunInterruptedError(
            f"interrupted by {signame} at step {max(watch.steps, 0)} of {steps}; "
            f"the nodes were stopped, the bag written so far is in {bags}",
            watch.signals[0],
        )
    if watch.failure is not None:
        raise RunError(watch.failure)
    if line is not None:
        line.show(steps, watch.wall_time_s, final=True)
    summary = summarise_run(
        runs, data, run_dir, wall_time_s=watch.wall_time_s, composed=composed, plots=plots
    )
    return RunResult(run_dir, steps, watch.wall_time_s, watch.exit_codes, summary)


def _new_run_dir(out_dir: Path | None, name: str) -> Path:
    """The run directory (``runs/<name>-<time>`` by default); it must not hold anything yet."""
    if out_dir is None:
        out_dir = Path("runs") / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir = out_dir.resolve()
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ConfigError(f"--out {out_dir}: exists and is not empty")
    return out_dir


def prepare_axis_runs(
    scenario: dict[str, Any],
    scenario_path: Path,
    run_dir: Path,
    *,
    composed: bool = False,
    namespace: str = "",
    extra_args: list[str] | None = None,
) -> list[_AxisRun]:
    """One set of nodes per axis, with its directory, parameter file and ROS arguments.

    Nothing is written before the scenario is known to be runnable as asked.
    """
    axes = axes_of(scenario)
    if axes and (composed or namespace):
        raise ConfigError(
            f"scenario {scenario_path}: a multi-axis scenario runs as separate processes, "
            "each axis in its own namespace (no --composed, no --namespace)"
        )
    for axis in axes:  # every section of every axis, before anything is written or started
        _check_sections(axis_view(scenario, axis, scenario_path.parent), run_dir / axis)
    if not axes:
        _check_sections(scenario, run_dir)
    return [
        _prepare_axis(scenario, scenario_path, run_dir, axis, namespace, extra_args or [])
        for axis in axes or [""]
    ]


def _check_sections(scenario: dict[str, Any], axis_dir: Path) -> None:
    """Check each node's section as the node will (ParameterFileError naming the key)."""
    roles = roles_of(scenario)
    overrides = handshake_overrides(scenario, roles, axis_dir / "bag", axis_dir)
    for role in roles:
        checked_values(role, {**node_params(scenario, role), **overrides.get(role, {})})


def _prepare_axis(
    scenario: dict[str, Any],
    scenario_path: Path,
    run_dir: Path,
    axis: str,
    namespace: str,
    extra_args: list[str],
) -> _AxisRun:
    axis_dir = run_dir / axis if axis else run_dir
    (axis_dir / "logs").mkdir(parents=True, exist_ok=True)
    if axis:
        # Each axis is a single-axis scenario of its own, kept in its directory.
        axis_scenario = axis_view(scenario, axis, scenario_path.parent)
        axis_path = axis_dir / "scenario.yaml"
        axis_path.write_text(dump_params(axis_scenario))
        ns = f"/{axis}"
        args = ["-r", f"__ns:={ns}", "-r", f"/clock:={ns}/clock", *extra_args]
    else:
        axis_scenario, axis_path, ns = scenario, scenario_path, namespace
        args = [*(["-r", f"__ns:={ns}"] if ns else []), *extra_args]
    roles = roles_of(axis_scenario)
    overrides = handshake_overrides(axis_scenario, roles, axis_dir / "bag", scenario_path.parent)
    params_path = write_run_params(axis_scenario, overrides, axis_dir / "params.yaml")
    return _AxisRun(axis, ns, axis_scenario, axis_path, axis_dir, roles, params_path, args)


def _run_nodes(
    runs: list[_AxisRun],
    domain_id: int,
    composed: bool,
    line: ProgressLine | None,
    stall_timeout_s: float,
    on_started: Callable[[list[Proc]], object] | None,
    run_dir: Path,
) -> _Watch:
    """Start every axis's nodes, watch them until the plants are done, stop them all."""
    env = ros_environment(domain_id, runs[0].log_dir)
    settings = discovery_settings(runs[0].log_dir)
    watch = _Watch()
    try:
        for run in runs:
            if "recorder" in run.roles:
                run.watcher = ProgressWatcher(
                    run.namespace or "/", domain_id=domain_id, environ=settings
                )
        watch.t_start = time.monotonic()
        previous_handlers = catch_stop_signals(watch.signals)
        try:
            for run in runs:
                run_env = {**env, "ROS_LOG_DIR": str(run.log_dir)}
                run.procs = start_nodes(
                    run.params_path, run.roles, run.args, run_env, run.log_dir, composed
                )
            if on_started is not None:
                on_started([p for run in runs for p in run.procs])
            _watch(runs, watch, composed, line, stall_timeout_s, run_dir)
        finally:
            watch.t_end = time.monotonic()
            stop_nodes([p for run in runs for p in run.procs])
            watch.exit_codes = {
                f"{run.axis}/{p.role}" if run.axis else p.role: p.popen.returncode
                for run in runs
                for p in run.procs
            }
            restore_handlers(previous_handlers)
    finally:
        for run in runs:
            if run.watcher is not None:
                run.watcher.close()
    return watch


def _watch(
    runs: list[_AxisRun],
    watch: _Watch,
    composed: bool,
    line: ProgressLine | None,
    stall_timeout_s: float,
    run_dir: Path,
) -> None:
    """Follow the progress until the plants are done, a node fails, the run stalls or a signal."""
    last_change = time.monotonic()
    while not watch.signals:
        for run in runs:
            if run.watcher is not None:
                run.watcher.spin(POLL_S / len(runs))
            else:
                time.sleep(POLL_S / len(runs))
        watched = [run.watcher.steps for run in runs if run.watcher is not None]
        slowest = min(watched) if watched else -1
        if slowest != watch.steps:
            watch.steps, last_change = slowest, time.monotonic()
            if slowest >= 0 and watch.t_first is None:
                watch.t_first = time.monotonic()
        if line is not None and watch.t_first is not None:
            line.show(watch.steps, time.monotonic() - watch.t_first)
        watch.failure = _check_processes(runs)
        if watch.failure is not None or all(run.plant_done for run in runs):
            return
        if time.monotonic() - last_change > stall_timeout_s:
            watch.failure = f"no progress for {stall_timeout_s:.0f} s (see {run_dir})"
            return


def _check_processes(runs: list[_AxisRun]) -> str | None:
    """Why the run must stop now (a node failed or quit early), or None."""
    for run in runs:
        where = f"{run.axis}/" if run.axis else ""
        for p in run.procs:
            code = p.popen.poll()
            if code is None or (code == 0 and p.role in PLANT_ROLES):
                continue
            if p.role in PLANT_ROLES:
                return f"{where}{p.role} exited with code {code}:\n{p.tail()}"
            if not run.plant_done:
                return f"{where}{p.role} exited early with code {code}:\n{p.tail()}"
    return None


def summarise_run(
    runs: list[_AxisRun],
    scenario: dict[str, Any],
    run_dir: Path,
    *,
    wall_time_s: float,
    composed: bool,
    plots: bool,
) -> RunSummary | AxesSummary:
    """Write each axis's ``summary.json`` and plots (and the contour of a multi-axis run)."""
    from servo_axis.analysis import plots as figures
    from servo_axis.analysis import summary as summaries

    per_axis: dict[str, RunSummary] = {}
    for run in runs:
        per_axis[run.axis] = summaries.summarise(
            run.out_dir,
            scenario=run.scenario,
            scenario_path=run.scenario_path,
            wall_time_s=wall_time_s,
            mode="composed" if composed else "separate processes",
        )
        if plots:
            figures.plot(run.out_dir)
    if not axes_of(scenario):
        return per_axis[""]
    summary = summaries.summarise_axes(
        run_dir, scenario=scenario, axes=per_axis, wall_time_s=wall_time_s
    )
    if plots:
        figures.plot_contour(run_dir)
    return summary
