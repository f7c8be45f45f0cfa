"""Run a scenario end to end: prepare, start, watch, stop, summarise.

``python -m servo_axis run <scenario name or file> [--out DIR] [--composed]``

The runner writes each axis's parameter file (:mod:`servo_axis.run.plan`),
starts the nodes (:mod:`servo_axis.run.processes`), waits for them to
connect through their own handshakes (no fixed sleeps), follows
``recorder/progress`` to show progress (:mod:`servo_axis.run.progress`), and
when the plant has finished it stops the rest with SIGINT, then SIGKILL
after a timeout. It then writes ``summary.json`` and the plots
(:mod:`servo_axis.analysis`).

A node that dies during the run (node-death policy, README):

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

import dataclasses
import re
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from servo_axis.analysis.health import NodeDeath, RunHealth, assess
from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.params.factories import EXTERNAL_ROLES, checked_values, run_steps
from servo_axis.params.names import check_domain_id, check_namespace
from servo_axis.params.registry import term_files
from servo_axis.params.resolve import node_values
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
from servo_axis.run.fastdds import clean_stale_shm, free_participant_id, with_participant_id
from servo_axis.run.live import LiveAxis, check_live, live_axis, module_args, wait_ready
from servo_axis.run.plan import (
    REQUIRED_INPUTS,
    handshake_overrides,
    presence_topic,
    role_topics,
    write_run_params,
)
from servo_axis.run.processes import (
    Proc,
    default_domain_id,
    discovery_settings,
    ros_environment,
    run_header,
    start_node,
    start_nodes,
    start_process,
    stop_nodes,
)
from servo_axis.run.progress import ProgressLine, ProgressWatcher
from servo_axis.stop_signals import catch_stop_signals, restore_handlers
from servo_axis.wire.node_report import NodeHealth, read_health

if TYPE_CHECKING:
    from servo_axis.analysis.summary import AxesSummary, RunSummary

#: The roles whose clean exit means "the run is complete".
PLANT_ROLES = ("plant", "composed")
#: Roles the runner starts again when they die (the axis runs on meanwhile).
RESTARTED_ROLES = ("learning", "identifier")
#: Roles whose death the axis survives without a restart (the feedback trips).
RUN_ON_ROLES = ("feedforward",)
#: Restarts per role and axis by default.
RESPAWN_LIMIT = 3
#: Exit code of a node that refused its configuration (never restarted).
NODE_BAD_CONFIG = 2
#: Seconds a run waits for its outside nodes before the first step, by default.
EXTERNAL_TIMEOUT_S = 120.0
#: Seconds the watch loop waits per pass (shared by the axes).
POLL_S = 0.05


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
    external: tuple[str, ...] = ()
    steps: int = 0
    procs: list[Proc] = field(default_factory=list)
    watcher: ProgressWatcher | None = None
    env: dict[str, str] = field(default_factory=dict)
    deaths: list[NodeDeath] = field(default_factory=list)
    restarts: dict[str, int] = field(default_factory=dict)
    seen_dead: set[int] = field(default_factory=set)  # pids already handled

    @property
    def realtime(self) -> bool:
        """The axis runs in realtime (the plant's ``mode``)."""
        return bool(node_values(self.scenario, "plant")["mode"] == "realtime")

    @property
    def log_dir(self) -> Path:
        return self.out_dir / "logs"

    @property
    def started_roles(self) -> list[str]:
        """The roles the runner starts (those an outside node plays left out)."""
        return [r for r in self.roles if r not in self.external]

    @property
    def plant_done(self) -> bool:
        if "plant" in self.external:
            # An outside plant: done once the recorder has every step.
            return self.watcher is not None and self.watcher.steps >= self.steps
        plant = next((p for p in self.procs if p.role in PLANT_ROLES), None)
        return plant is not None and plant.popen.poll() == 0

    @property
    def recorder_died(self) -> bool:
        rec = [p for p in self.procs if p.role == "recorder"]
        return bool(rec) and rec[-1].popen.returncode not in (0, None)

    def where(self, role: str) -> str:
        return f"{self.axis}/{role}" if self.axis else role


@dataclass
class _Watch:
    """What the watch loop saw: progress, times, why it stopped."""

    steps: int = -1  # the slowest axis's recorded steps
    t_start: float = field(default_factory=time.monotonic)
    t_start_epoch: float = field(default_factory=time.time)  # for the shared-memory clean-up
    t_first: float | None = None  # the first recorded step
    t_end: float = 0.0
    failure: str | None = None
    interrupted: str | None = None  # why, when a signal stopped the run
    signals: list[int] = field(default_factory=list)
    exit_codes: dict[str, int] = field(default_factory=dict)
    participant_ids: set[int] = field(default_factory=set)  # given to restarted nodes

    @property
    def wall_time_s(self) -> float:
        return self.t_end - (self.t_first or self.t_start)


@dataclass
class _Live:
    """The live view of a run (:mod:`servo_axis.run.live`): its port, axes, where it says so."""

    port: int
    axes: list[LiveAxis]
    out: TextIO | None
    proc: Proc | None = None


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
    respawn_limit: int = RESPAWN_LIMIT,
    external: tuple[str, ...] = (),
    external_timeout_s: float = EXTERNAL_TIMEOUT_S,
    live_port: int | None = None,
    floor: dict[int, dict[str, Any]] | None = None,
) -> RunResult:
    """Run one scenario end to end and return where it was written.

    ``scenario`` is a scenario file or the name of a shipped scenario
    (``"rptc_detailed"``). A scenario with per-axis sections (``/x/<node>``,
    ``/y/<node>``) runs one set of nodes per axis, each in its own namespace
    with its own ``/<axis>/clock``, all at once; each axis gets a
    subdirectory of the run directory (its own bag, logs, summary) and the
    run's summary holds the per-axis summaries and the contour (XY) figures.
    ``os.environ`` is left as it was.

    ``external`` names roles that nodes from outside the suite play (with
    the scenario's ``external_roles``): the runner starts every other node,
    says which topics the outside node must serve, and waits for it (at most
    ``external_timeout_s`` before the first step); the rest of the run is as
    usual.

    Raises
    ------
    ConfigError
        For a scenario that is neither a file nor a shipped scenario, or
        not a valid scenario; for an ``out_dir`` that is not empty or cannot
        be created, a ``namespace`` ROS would reject, a ``domain_id`` outside
        0..232 (also from ROS_DOMAIN_ID) or a negative ``respawn_limit``:
        before anything is written or started.
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

    With ``live_port``, the run is also served to Foxglove / Lichtblick on
    ``ws://127.0.0.1:<live_port>`` while it runs (:mod:`servo_axis.run.live`;
    a :class:`ConfigError` before anything is written if the optional
    package is missing or the port is taken); the run itself is the same.
    """
    # The options first: nothing is written or started for a bad one.
    namespace = check_namespace(namespace) if namespace else ""
    domain = default_domain_id() if domain_id is None else check_domain_id(domain_id)
    if respawn_limit < 0:
        raise ConfigError(f"--respawn-limit {respawn_limit}: expected an integer >= 0")
    scenario_path = find_scenario(scenario).resolve()
    data = load_scenario(scenario_path)
    common = shared(data)
    steps = run_steps(node_values(data, "plant"))
    if live_port is not None:
        check_live(live_port)
    run_dir = _new_run_dir(out_dir, common.get("scenario", {}).get("name") or scenario_path.stem)
    outside = external_roles_of(data, external)
    runs = prepare_axis_runs(
        data,
        scenario_path,
        run_dir,
        composed=composed,
        namespace=namespace,
        extra_args=extra_args,
        external=outside,
    )
    if progress is not None:
        name = common.get("scenario", {}).get("name") or scenario_path.stem
        print(f"servo_axis run {name}: {steps} steps, run directory {run_dir}", file=progress)
        namespaces = [run.namespace for run in runs]
        header = run_header(domain, namespaces, discovery_settings(runs[0].log_dir))
        print("\n".join(header), file=progress, flush=True)
    line = ProgressLine(steps, progress) if progress is not None else None
    if progress is not None:
        for run in runs:
            for role in run.external:
                progress.write(describe_external(run, role))
        progress.flush()
    live = (
        None
        if live_port is None
        else _Live(live_port, [live_axis(run.scenario, run.namespace) for run in runs], progress)
    )
    watch = _run_nodes(
        runs,
        domain,
        composed,
        line,
        stall_timeout_s,
        on_started,
        run_dir,
        respawn_limit,
        external_timeout_s,
        progress,
        live,
    )
    recovered = _recover_bags(runs)
    if watch.signals:
        signame = signal.Signals(watch.signals[0]).name
        bags = ", ".join(str(run.out_dir / "bag") for run in runs if (run.out_dir / "bag").is_dir())
        kept = f"the bag written so far is in {bags}" if bags else "no bag had been started yet"
        watch.interrupted = (
            f"interrupted by {signame} at step {max(watch.steps, 0)} of {steps}; "
            f"the nodes were stopped, {kept}"
        )
        summary = _summary_of_the_recorded_part(runs, data, run_dir, watch, composed, recovered)
        note = f"\nsummary of what was recorded: {run_dir / 'summary.json'}" if summary else ""
        raise RunInterruptedError(watch.interrupted + note, watch.signals[0], summary)
    if watch.failure is not None:
        summary = _summary_of_the_recorded_part(runs, data, run_dir, watch, composed, recovered)
        note = f"\nsummary of what was recorded: {run_dir / 'summary.json'}" if summary else ""
        raise RunError(watch.failure + note, summary)
    summary = summarise_run(
        runs,
        data,
        run_dir,
        watch,
        composed=composed,
        plots=plots,
        recovered=recovered,
        floor=floor,
    )
    if line is not None:
        line.show(steps, summary.wall_time_s, final=True)
    return RunResult(run_dir, steps, summary.wall_time_s, watch.exit_codes, summary)


def _summary_of_the_recorded_part(
    runs: list[_AxisRun],
    data: dict[str, Any],
    run_dir: Path,
    watch: _Watch,
    composed: bool,
    recovered: set[str],
) -> RunSummary | AxesSummary | None:
    """``summary.json`` of a failed or interrupted run (no plots); None if the bag does not allow one."""
    try:
        return summarise_run(
            runs, data, run_dir, watch, composed=composed, plots=False, recovered=recovered
        )
    except Exception as err:  # the bag may be too short to summarise
        print(f"no summary of the recorded part: {err}", file=sys.stderr)
        return None


def _recover_bags(runs: list[_AxisRun]) -> set[str]:
    """Recover the bag of each axis whose recorder died; the axes recovered."""
    recovered = set()
    for run in runs:
        if run.recorder_died and (run.out_dir / "bag").is_dir():
            from servo_axis.recording.recover import recover_bag

            report = recover_bag(run.out_dir / "bag")
            if report.recovered:
                recovered.add(run.axis)
    return recovered


def _new_run_dir(out_dir: Path | None, name: str) -> Path:
    """The run directory (``runs/<name>-<time>`` by default); it must not hold anything yet."""
    if out_dir is None:
        out_dir = Path("runs") / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir = out_dir.resolve()
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(f"--out {out_dir}: exists and is not a directory")
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ConfigError(f"--out {out_dir}: exists and is not empty")
    return out_dir


def _create_run_dir(run_dir: Path) -> None:
    """Create the run directory, or :class:`ConfigError` naming ``--out`` and the OS's reason."""
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"--out {run_dir}: cannot create it: {err}") from None


def prepare_axis_runs(
    scenario: dict[str, Any],
    scenario_path: Path,
    run_dir: Path,
    *,
    composed: bool = False,
    namespace: str = "",
    extra_args: list[str] | None = None,
    external: tuple[str, ...] = (),
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
    if external and composed:
        raise ConfigError("--external: a run with outside nodes runs as separate processes")
    for axis in axes:  # every section of every axis, before anything is written or started
        view = axis_view(scenario, axis, scenario_path.parent)
        _check_sections(view, run_dir / axis, scenario_path.parent, external)
    if not axes:
        _check_sections(scenario, run_dir, scenario_path.parent, external)
        single_axis_namespace(scenario, namespace)
    _create_run_dir(run_dir)
    return [
        _prepare_axis(scenario, scenario_path, run_dir, axis, namespace, extra_args or [], external)
        for axis in axes or [""]
    ]


def external_roles_of(
    scenario: dict[str, Any], given: tuple[str, ...] | list[str]
) -> tuple[str, ...]:
    """The roles outside nodes play: ``given`` (``--external``) and the scenario's ``external_roles``.

    Raises
    ------
    ConfigError
        For a role that is not one an outside node can play.
    """
    listed = [r for r in shared(scenario).get("external_roles", []) if r]
    roles = tuple(dict.fromkeys([*given, *listed]))
    for role in roles:
        if role not in EXTERNAL_ROLES:
            raise ConfigError(f"--external {role}: expected one of {', '.join(EXTERNAL_ROLES)}")
    return roles


def describe_external(run: _AxisRun, role: str) -> str:
    """What the outside node of ``role`` must serve: topics, types, QoS (printed by the run)."""
    publishes, subscribes = role_topics(run.scenario, run.roles, role)
    ns = run.namespace.rstrip("/") if run.namespace not in ("", "/") else ""

    def full(name: str) -> str:
        return name if name.startswith("/") else f"{ns}/{name}"

    lines = [f"outside {run.where(role)}: any node name, default QoS accepted (docs/interfaces.md)"]
    must = presence_topic(run.scenario, role)
    lines += [
        f"  publishes   {full(t.name):32} {t.type_name:30} "
        f"{'' if t.name == must else '(optional) '}{t.meaning}"
        for t in publishes
    ]
    lines += [
        f"  subscribes  {full(t.name):32} {t.type_name:30} "
        f"{'' if t.name in REQUIRED_INPUTS[role] else '(optional) '}{t.meaning}"
        for t in subscribes
    ]
    return "\n".join(lines) + "\n"


def single_axis_namespace(scenario: dict[str, Any], namespace: str = "") -> str:
    """The namespace of a single-axis run: ``namespace`` if given, else ``/<axis>``.

    ``"/"`` is the root (returned as ``""``: the nodes start without a
    namespace remap). The default is the scenario's shared key ``axis``
    (``/x``): the nodes are ``/x/plant``, ``/x/feedback``, ... and the
    topics ``/x/state``, ``/x/command``, ...; ``/clock`` and
    ``/diagnostics`` stay absolute.

    Raises
    ------
    ParameterFileError
        For an ``axis`` that cannot name a ROS namespace.
    """
    if namespace:
        return "" if namespace == "/" else namespace
    axis = node_values(scenario, "plant")["axis"]
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", axis):
        raise ParameterFileError(
            f"parameter 'axis': {axis!r} cannot name the run's ROS namespace /<axis> (a "
            "letter, then letters, digits or _); rename it or give --namespace"
        )
    return f"/{axis}"


def _check_sections(
    scenario: dict[str, Any], axis_dir: Path, scenario_dir: Path, external: tuple[str, ...] = ()
) -> None:
    """Check each node's section as the node will (ParameterFileError naming the key)."""
    roles = roles_of(scenario)
    for role in external:
        if role not in roles:
            raise ConfigError(
                f"--external {role}: the scenario has no {role} section (its roles: "
                f"{', '.join(roles)})"
            )
    overrides = handshake_overrides(scenario, roles, axis_dir / "bag", scenario_dir, external)
    for role in roles:
        values = checked_values(role, {**node_params(scenario, role), **overrides.get(role, {})})
        for key in term_files() if role == "feedforward" else ():
            table = values[key] if values.get(f"{key.rpartition('.')[0]}.enabled", True) else None
            if table and not Path(table).is_file():
                raise ParameterFileError(f"parameter '{key}': no such file {table}")


def _prepare_axis(
    scenario: dict[str, Any],
    scenario_path: Path,
    run_dir: Path,
    axis: str,
    namespace: str,
    extra_args: list[str],
    external: tuple[str, ...] = (),
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
        axis_scenario, axis_path = scenario, scenario_path
        ns = single_axis_namespace(scenario, namespace)
        args = [*(["-r", f"__ns:={ns}"] if ns else []), *extra_args]
    roles = roles_of(axis_scenario)
    overrides = handshake_overrides(
        axis_scenario, roles, axis_dir / "bag", scenario_path.parent, external
    )
    params_path = write_run_params(axis_scenario, overrides, axis_dir / "params.yaml")
    steps = run_steps(node_values(axis_scenario, "plant"))
    return _AxisRun(
        axis, ns, axis_scenario, axis_path, axis_dir, roles, params_path, args, external, steps
    )


def _run_nodes(
    runs: list[_AxisRun],
    domain_id: int,
    composed: bool,
    line: ProgressLine | None,
    stall_timeout_s: float,
    on_started: Callable[[list[Proc]], object] | None,
    run_dir: Path,
    respawn_limit: int,
    external_timeout_s: float = 0.0,
    progress: TextIO | None = None,
    live: _Live | None = None,
) -> _Watch:
    """Start every axis's nodes, watch them until the plants are done, stop them all.

    With ``live``, the live view is started first (the runner waits until it
    listens and prints its URL) and stopped after the nodes.
    """
    env = ros_environment(domain_id, runs[0].log_dir)
    settings = discovery_settings(runs[0].log_dir)
    watch = _Watch()
    started = time.time()  # epoch, for the shared-memory clean-up
    try:
        for run in runs:
            if "recorder" in run.roles or run.external:
                run.watcher = ProgressWatcher(
                    run.namespace or "/",
                    domain_id=domain_id,
                    environ=settings,
                    steps=run_steps(node_values(run.scenario, "plant")),
                )
        watch.t_start = time.monotonic()
        watch.t_start_epoch = started
        previous_handlers = catch_stop_signals(watch.signals)
        try:
            if live is not None:
                _start_live(live, env, runs[0].log_dir if len(runs) == 1 else run_dir, watch)
            for run in runs:
                run.env = {**env, "ROS_LOG_DIR": str(run.log_dir)}
                run.procs = start_nodes(
                    run.params_path,
                    run.started_roles,
                    run.args,
                    run.env,
                    run.log_dir,
                    composed,
                    realtime=run.realtime,
                )
            if on_started is not None:
                on_started([p for run in runs for p in run.procs])
            outside = _Outside(runs, external_timeout_s, progress)
            _watch(runs, watch, line, stall_timeout_s, run_dir, respawn_limit, outside)
        finally:
            watch.t_end = time.monotonic()
            stop_nodes([p for run in runs for p in run.procs])
            watch.exit_codes = {
                run.where(p.role): p.popen.returncode for run in runs for p in run.procs
            }
            restore_handlers(previous_handlers)
    finally:
        if live is not None and live.proc is not None:
            code = stop_nodes([live.proc])["live"]
            if code != 0:  # the run went on without it
                print(
                    f"live view exited with code {code} (see {live.proc.log_path}); "
                    "the run is not affected",
                    file=sys.stderr,
                )
        for run in runs:
            if run.watcher is not None:
                run.watcher.close()
        procs = [p for run in runs for p in run.procs]
        if live is not None and live.proc is not None:
            procs.append(live.proc)
        if any((p.popen.returncode or 0) < 0 for p in procs):
            # Again once the watchers are closed: a killed participant never
            # lets go of the port segments it opened (the watchers' own
            # included), so their last user's clean exit leaves them behind.
            clean_stale_shm(since=started)
    return watch


class _Outside:
    """The wait for the nodes of the roles outside nodes play, before the first step."""

    def __init__(self, runs: list[_AxisRun], timeout_s: float, out: TextIO | None) -> None:
        self.missing = [(run, role) for run in runs for role in run.external]
        self.timeout_s = timeout_s
        self.out = out
        self.t0 = time.monotonic()
        self.told = 0.0

    def _present(self, run: _AxisRun, role: str) -> bool:
        assert run.watcher is not None
        publishers, _ = run.watcher.endpoints(presence_topic(run.scenario, role))
        return publishers > 0

    def arrived(self) -> bool:
        """Whether every outside node is there (its main output has a publisher)."""
        self.missing = [(run, role) for run, role in self.missing if not self._present(run, role)]
        if self.missing and self.out is not None and time.monotonic() - self.told >= 5.0:
            self.told = time.monotonic()
            waited = self.told - self.t0
            for run, role in self.missing:
                topic = presence_topic(run.scenario, role)
                self.out.write(
                    f"waiting for the outside {run.where(role)} ({waited:.0f} s of "
                    f"{self.timeout_s:.0f} s): no publisher on {topic} yet\n"
                )
            self.out.flush()
        return not self.missing

    def failure(self) -> str | None:
        """Why the run stops (the timeout passed), or None."""
        if time.monotonic() - self.t0 <= self.timeout_s:
            return None
        names = ", ".join(
            f"{run.where(role)} (no publisher on {presence_topic(run.scenario, role)})"
            for run, role in self.missing
        )
        return (
            f"the outside node did not come within --external-timeout {self.timeout_s:g} s: {names}"
        )


def _start_live(live: _Live, env: dict[str, str], log_dir: Path, watch: _Watch) -> None:
    """Start the live view and wait until it listens; print its URL."""
    live.proc = start_process(
        "live",
        ["-m", "servo_axis.run.live", *module_args(live.port, live.axes)],
        {**env, "ROS_LOG_DIR": str(log_dir)},
        log_dir / "live.log",
    )
    proc = live.proc
    address = wait_ready(
        proc.log_path, lambda: proc.popen.poll() is None, stopped=lambda: bool(watch.signals)
    )
    if address and live.out is not None:
        print(
            f"live view: {address}  (Foxglove / Lichtblick: open a connection, "
            "Foxglove WebSocket, this URL)",
            file=live.out,
            flush=True,
        )


def _watch(
    runs: list[_AxisRun],
    watch: _Watch,
    line: ProgressLine | None,
    stall_timeout_s: float,
    run_dir: Path,
    respawn_limit: int,
    outside: _Outside | None = None,
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
        watch.failure = _check_processes(runs, watch, respawn_limit)
        if watch.failure is not None or all(run.plant_done for run in runs):
            return
        if outside is not None and not outside.arrived():
            # The wait for an outside node has its own timeout, not the stall's.
            watch.failure = outside.failure()
            if watch.failure is not None:
                return
            last_change = time.monotonic()
            continue
        if time.monotonic() - last_change > stall_timeout_s:
            watch.failure = f"no progress for {stall_timeout_s:.0f} s (see {run_dir})"
            return


def _check_processes(runs: list[_AxisRun], watch: _Watch, respawn_limit: int) -> str | None:
    """Apply the node-death policy; why the run must stop now, or None."""
    for run in runs:
        for p in list(run.procs):
            code = p.popen.poll()
            if code is None or p.popen.pid in run.seen_dead:
                continue
            if p.role in PLANT_ROLES and code == 0:
                continue
            if run.plant_done:
                continue  # the run is over; the rest are being stopped
            run.seen_dead.add(p.popen.pid)
            after = time.monotonic() - watch.t_start
            restarts = run.restarts.get(p.role, 0)
            if p.role in RESTARTED_ROLES and code != NODE_BAD_CONFIG and restarts < respawn_limit:
                run.restarts[p.role] = restarts + 1
                clean_stale_shm(since=watch.t_start_epoch, dead_owners_only=True)
                log_name = f"{p.role}.restart{restarts + 1}"
                # Not the dead one's participant id: the others still write
                # to its receive segment. Past the 20 ids (a node that keeps
                # dying under a large --respawn-limit), Fast DDS's choice.
                env = run.env
                try:
                    pid = free_participant_id(
                        int(run.env["ROS_DOMAIN_ID"]), taken=watch.participant_ids
                    )
                    env = with_participant_id(env, pid, run.log_dir / f"{log_name}.fastdds.xml")
                    watch.participant_ids.add(pid)
                except RuntimeError:
                    pass
                new = start_node(
                    run.params_path,
                    p.role,
                    [*run.args, "-p", "late_join:=true"],
                    env,
                    run.log_dir,
                    log_name=log_name,
                    realtime=run.realtime,
                )
                run.procs.append(new)
                action, again = "restarted", time.monotonic() - watch.t_start - after
            elif p.role in RUN_ON_ROLES and code != NODE_BAD_CONFIG:
                action, again = "ran on", None
            else:
                action, again = "stopped the run", None
            run.deaths.append(
                NodeDeath(run.where(p.role), code, round(after, 3), watch.steps, action, again)
            )
            if action == "stopped the run":
                what = "exited with code" if p.role in PLANT_ROLES else "exited early with code"
                return f"{run.where(p.role)} {what} {code}:\n{p.tail()}"
    return None


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


def summarise_run(
    runs: list[_AxisRun],
    scenario: dict[str, Any],
    run_dir: Path,
    watch: _Watch,
    *,
    composed: bool,
    plots: bool,
    recovered: set[str] | None = None,
    floor: dict[int, dict[str, Any]] | None = None,
) -> RunSummary | AxesSummary:
    """Write each axis's ``summary.json`` (with its health) and plots, and the contour of a multi-axis run.

    A realtime run's summary holds the plant's report on its clock
    (``realtime``), with the host's floor at its period from ``floor``
    (``rt_floor.py --json`` results by period in us) if given.
    """
    from servo_axis.analysis import plots as figures
    from servo_axis.analysis import summary as summaries

    recovered = recovered or set()
    per_axis: dict[str, RunSummary] = {}
    all_deaths: list[NodeDeath] = []
    all_reports = {}
    spans: list[tuple[float, float]] = []
    for run in runs:
        reports = read_health(run.log_dir)
        span = stepping_span(reports.get("plant"), watch.t_start, watch.t_end)
        summary = summaries.summarise(
            run.out_dir,
            scenario=run.scenario,
            scenario_path=run.scenario_path,
            wall_time_s=watch.wall_time_s if span is None else span[1] - span[0],
            mode="composed" if composed else "separate processes",
        )
        if span is not None:
            spans.append(span)
            summary = dataclasses.replace(
                summary, startup_s=span[0] - watch.t_start, finish_s=watch.t_end - span[1]
            )
        health = assess(
            failure=watch.failure,
            interrupted=watch.interrupted,
            deaths=run.deaths,
            reports=reports,
            faults=len(summary.faults),
            bag_recovered=run.axis in recovered,
            realtime=summary.time_mode == "realtime",
        )
        summary = dataclasses.replace(summary, health=health)
        plant = reports.get("plant")
        if plant is not None and plant.realtime:
            # The plant's clock, with the feedback's and the generator's counts.
            figures = {k: v for h in reports.values() for k, v in h.realtime.items()}
            rt = summaries.Realtime.from_dict({**figures, **plant.realtime})
            at = (floor or {}).get(round(rt.period_ns / 1000))
            summary = dataclasses.replace(summary, realtime=dataclasses.replace(rt, floor=at))
        (run.out_dir / summaries.SUMMARY_FILE).write_text(summary.to_json())
        per_axis[run.axis] = summary
        all_deaths += run.deaths
        all_reports.update({run.where(role): h for role, h in reports.items()})
        if plots:
            figures.plot(run.out_dir)
    if not axes_of(scenario):
        return per_axis[""]
    health = assess(
        failure=watch.failure,
        interrupted=watch.interrupted,
        deaths=all_deaths,
        reports=all_reports,
        faults=sum(len(s.faults) for s in per_axis.values()),
        bag_recovered=bool(recovered),
        realtime=any(s.time_mode == "realtime" for s in per_axis.values()),
    )
    stepped = max(b for _, b in spans) - min(a for a, _ in spans) if spans else None
    axes_summary = summaries.summarise_axes(
        run_dir,
        scenario=scenario,
        axes=per_axis,
        wall_time_s=watch.wall_time_s if stepped is None or len(spans) < len(runs) else stepped,
        health=health,
    )
    if plots:
        figures.plot_contour(run_dir)
    return axes_summary
