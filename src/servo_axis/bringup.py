"""Bring a scenario up, run it, record it, shut it down.

``python -m servo_axis run <scenario.yaml> [--out DIR] [--composed]``

Each node is its own process started with this interpreter (the venv's),
in its own process group, with a private ROS domain, localhost discovery,
UDP transport (no ``/dev/shm`` files left behind even on SIGKILL) and a fast
discovery profile. The runner waits for the nodes to connect through their
own handshakes (no fixed sleeps), follows ``recorder/progress`` to show
progress, and when the plant has finished it stops the rest with SIGINT,
then SIGKILL after a timeout. It then writes ``summary.json`` and the plots.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, TextIO

import yaml

from servo_axis.core.errors import ConfigError
from servo_axis.stop_signals import catch_stop_signals, restore_handlers

ROLES = ("plant", "feedback", "feedforward", "learning", "recorder")
SHARED_SECTION = "/**"
STOP_TIMEOUT_S = 5.0


class RunError(RuntimeError):
    """The run could not complete (a node failed, stalled or refused its configuration)."""


class RunInterruptedError(RunError):
    """SIGINT or SIGTERM stopped the run; the nodes were stopped and the bag closed."""

    def __init__(self, text: str, signum: int) -> None:
        super().__init__(text)
        self.signum = signum


def load_scenario(path: Path) -> dict[str, Any]:
    """Read a scenario (a ROS parameter file) and check its top-level layout."""
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f"scenario {path}: cannot read it: {err}") from err
    if not isinstance(data, dict):
        raise ConfigError(f"scenario {path}: expected a mapping of node sections")
    for key, value in data.items():
        if key != SHARED_SECTION and key not in ROLES and _axis_section(key) is None:
            raise ConfigError(
                f"scenario {path}: unknown section '{key}'; expected '/**', one of {list(ROLES)} "
                "or '/<axis>/<node>'"
            )
        if not isinstance(value, dict) or set(value) != {"ros__parameters"}:
            raise ConfigError(f"scenario {path}: section '{key}' must hold only 'ros__parameters'")
    if "plant" not in data:
        raise ConfigError(f"scenario {path}: a 'plant' section is required")
    return data


def _axis_section(key: str) -> tuple[str, str] | None:
    """``(axis, role)`` of a per-axis section key ``/<axis>/<role>``, else None."""
    parts = key.split("/")
    if len(parts) == 3 and parts[0] == "" and parts[1].isidentifier() and parts[2] in ROLES:
        return parts[1], parts[2]
    return None


def axes_of(scenario: dict[str, Any]) -> list[str]:
    """Axes of a multi-axis scenario (from its ``/<axis>/<node>`` sections), sorted; [] if none."""
    return sorted({a[0] for key in scenario if (a := _axis_section(key)) is not None})


def axis_view(scenario: dict[str, Any], axis: str, scenario_dir: Path) -> dict[str, Any]:
    """The single-axis scenario of one axis of a multi-axis scenario.

    Each ``/<axis>/<node>`` section is merged into the node's common section
    (nested keys merge, the axis wins), ``axis`` is set to the axis name and
    a relative friction-table path is made absolute, so that the result runs
    and is reported like any single-axis scenario.
    """

    def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
        out = dict(base)
        for k, v in over.items():
            out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
        return out

    view: dict[str, Any] = {}
    common = shared(scenario)
    common["axis"] = axis
    about = dict(common.get("scenario", {}))
    about["name"] = f"{about.get('name', 'scenario')}/{axis}"
    common["scenario"] = about
    view[SHARED_SECTION] = {"ros__parameters": common}
    for role in ROLES:
        own = scenario.get(f"/{axis}/{role}", {}).get("ros__parameters", {})
        if role in scenario or own:
            base = scenario.get(role, {}).get("ros__parameters", {})
            view[role] = {"ros__parameters": merge(base, own)}
    ff = view.get("feedforward", {}).get("ros__parameters", {})
    if ff.get("friction_table", {}).get("file"):
        table = resolve_table(ff["friction_table"]["file"], scenario_dir)
        ff["friction_table"] = {**ff["friction_table"], "file": table}
    return view


def resolve_table(path_text: str, scenario_dir: Path) -> str:
    """A friction-table path of a scenario: relative ones are relative to the scenario's directory."""
    if path_text and not Path(path_text).is_absolute():
        return str(scenario_dir / path_text)
    return path_text


def shared(scenario: dict[str, Any]) -> dict[str, Any]:
    """The ``/**`` parameters of a scenario."""
    return dict(scenario.get(SHARED_SECTION, {}).get("ros__parameters", {}))


def node_params(scenario: dict[str, Any], role: str) -> dict[str, Any]:
    """The section of one node, flattened to dotted keys, on top of the shared ones."""

    def flat(prefix: str, d: dict[str, Any], out: dict[str, Any]) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                flat(f"{prefix}{k}.", v, out)
            else:
                out[f"{prefix}{k}"] = v

    out: dict[str, Any] = {}
    flat("", shared(scenario), out)
    flat("", scenario.get(role, {}).get("ros__parameters", {}), out)
    return out


def roles_of(scenario: dict[str, Any]) -> list[str]:
    """Nodes a scenario starts: those with a section, in start order."""
    return [
        r for r in ("recorder", "learning", "feedforward", "feedback", "plant") if r in scenario
    ]


def handshake_overrides(
    scenario: dict[str, Any], roles: list[str], bag_dir: Path, scenario_dir: Path
) -> dict[str, dict[str, Any]]:
    """Per-node parameters the bringup adds: whom to wait for, where to record."""
    state_subs = ("feedback" in roles) + ("learning" in roles)
    status_subs = int("feedforward" in roles)
    clock_subs = ("feedback" in roles) + ("feedforward" in roles) + ("learning" in roles)
    ref_subs = int("feedback" in roles)
    out: dict[str, dict[str, Any]] = {"plant": {}}
    if "learning" in roles:
        ff = node_params(scenario, "feedforward")
        learning = {k: v for k, v in ff.items() if k.startswith("reference.")}
        # The learning unit needs the original target and the cycle of the
        # feedforward generator: one source, copied here.
        learning["cycle_s"] = ff.get("learning.cycle_s", 0.5)
        if "memory.file" not in node_params(scenario, "learning"):
            learning["memory.file"] = str(bag_dir.parent / "learning_memory.json")
        out["learning"] = learning
    if "recorder" in roles:
        rec = node_params(scenario, "recorder")
        default_topics = ["state", "command", "reference", "/clock", "fault", "plant/status"]
        topics = rec.get("topics", default_topics)
        if "learning" in roles and "topics" not in rec:
            topics = [*default_topics, "learning/correction", "learning/cycle_stats"]
            out["recorder"] = {
                "topics": topics,
                "types": ["sensor_msgs/msg/JointState"] * 3
                + ["rosgraph_msgs/msg/Clock"]
                + ["std_msgs/msg/Float64MultiArray"] * 2
                + ["sensor_msgs/msg/JointState", "std_msgs/msg/Float64MultiArray"],
            }
        state_subs += "state" in topics
        status_subs += "plant/status" in topics
        clock_subs += "/clock" in topics
        ref_subs += "reference" in topics
        out.setdefault("recorder", {})["output_dir"] = str(bag_dir)
        out["plant"]["flow_control"] = True
    out["plant"].update(
        wait_for_state_subscribers=state_subs,
        wait_for_clock_subscribers=clock_subs,
        wait_for_status_subscribers=status_subs,
    )
    if "feedforward" in roles:
        out["feedforward"] = {"wait_for_reference_subscribers": ref_subs}
        table = node_params(scenario, "feedforward").get("friction_table.file", "")
        if table:
            out["feedforward"]["friction_table.file"] = resolve_table(table, scenario_dir)
    return out


class _QuotingDumper(yaml.SafeDumper):
    """Quotes every string: rcl's parameter parser reads a bare ``y``, ``on``
    or ``1e3`` as a bool or a number, PyYAML writes them bare."""


_QuotingDumper.add_representer(
    str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value, style='"')
)


def dump_params(data: dict[str, Any]) -> str:
    """A ROS parameter file's text, every string quoted."""
    return yaml.dump(data, Dumper=_QuotingDumper, sort_keys=False)


def write_run_params(
    scenario: dict[str, Any], overrides: dict[str, dict[str, Any]], path: Path
) -> Path:
    """The parameter file the nodes of a run get: the scenario plus the overrides.

    Node sections are keyed ``/**/<node>`` so that they apply under any
    namespace; the file is kept in the run directory as the exact record of
    what ran.
    """
    out: dict[str, Any] = {SHARED_SECTION: {"ros__parameters": shared(scenario)}}
    for role in ROLES:
        if role not in scenario and role not in overrides:
            continue
        params = dict(scenario.get(role, {}).get("ros__parameters", {}))
        params.update(overrides.get(role, {}))
        out[f"/**/{role}"] = {"ros__parameters": params}
    path.write_text(dump_params(out))
    return path


def ros_environment(domain_id: int, log_dir: Path) -> dict[str, str]:
    """Environment of the node processes."""
    env = dict(os.environ)
    profile = resources.files("servo_axis") / "data" / "fastdds_localhost.xml"
    env.update(
        ROS_DOMAIN_ID=str(domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(log_dir),
        FASTDDS_BUILTIN_TRANSPORTS="UDPv4",
        FASTRTPS_DEFAULT_PROFILES_FILE=str(profile),
        PYTHONUNBUFFERED="1",
    )
    return env


def default_domain_id() -> int:
    """ROS_DOMAIN_ID from the environment, else one derived from the pid (1..100)."""
    if "ROS_DOMAIN_ID" in os.environ:
        return int(os.environ["ROS_DOMAIN_ID"])
    return os.getpid() % 100 + 1


@dataclass
class Proc:
    """A node process and its log."""

    role: str
    popen: subprocess.Popen[bytes]
    log_path: Path
    log: Any = field(repr=False)
    started_at: float = field(default_factory=time.time)

    def tail(self, lines: int = 15) -> str:
        self.log.flush()
        text = self.log_path.read_text(errors="replace").splitlines()
        return "\n".join(text[-lines:])


def start_nodes(
    params_path: Path,
    roles: list[str],
    extra_args: list[str],
    env: dict[str, str],
    log_dir: Path,
    composed: bool,
) -> list[Proc]:
    """Start the node processes (or one composed process)."""
    base = ["--ros-args", "--params-file", str(params_path), *extra_args]
    jobs = (
        [("composed", ["-m", "servo_axis.nodes.composed", *roles])]
        if composed
        else [(r, ["-m", f"servo_axis.nodes.{r}"]) for r in roles]
    )
    procs: list[Proc] = []
    for role, cmd in jobs:
        log_path = log_dir / f"{role}.log"
        log = log_path.open("wb")
        cpus = _cpu_set(role) if os.environ.get("SERVO_AXIS_PIN", "1") == "1" else None
        popen = subprocess.Popen(
            [sys.executable, *cmd, *base],
            preexec_fn=(lambda c=cpus: os.sched_setaffinity(0, c)) if cpus else None,
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,
        )
        procs.append(Proc(role, popen, log_path, log))
    return procs


def _cpu_set(role: str) -> set[int] | None:
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        return None
    # plant and feedback take turns (lockstep): one core is enough for both;
    # the recorder and the feedforward generator get the rest.
    return {cpus[0]} if role in ("plant", "feedback") else set(cpus[1:])


def stop_nodes(procs: list[Proc], timeout_s: float = STOP_TIMEOUT_S) -> dict[str, int]:
    """SIGINT every live process group, SIGKILL what is left after ``timeout_s``; reap all."""
    for p in procs:
        if p.popen.poll() is None:
            _signal_group(p.popen, signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    for p in procs:
        try:
            p.popen.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            _signal_group(p.popen, signal.SIGKILL)
            p.popen.wait()
    for p in procs:
        _signal_group(p.popen, signal.SIGKILL)  # stray children of the group, if any
        p.log.close()
    if procs and any(p.popen.returncode == -signal.SIGKILL for p in procs):
        clean_stale_shm(since=min(p.started_at for p in procs))
    return {p.role: p.popen.returncode for p in procs}


def _lock_held(path: Path) -> bool:
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing releases a lock we took
    return False


def clean_stale_shm(*, since: float, shm_dir: Path = Path("/dev/shm")) -> list[str]:
    """Remove Fast DDS shared-memory files a SIGKILLed node left behind.

    With localhost discovery rmw_fastrtps uses shared memory; a clean exit
    removes its files, SIGKILL does not. A segment is stale when nobody holds
    the lock on its ``_el`` file (live owners hold it; the kernel releases it
    when the owner dies) or, for a port segment, when it has no ``_el`` at
    all. Only files touched since ``since`` (epoch seconds: the start of the
    run) are considered, so other users' files are left alone.
    """
    removed = []
    # A lock file whose segment is gone counts too: Fast DDS may remove a
    # dead owner's port segment when another participant reopens the port,
    # and leave the lock file behind.
    names = {p.name.removesuffix("_el") for p in shm_dir.glob("fastrtps_*")}
    for name in sorted(names):
        seg, lock = shm_dir / name, shm_dir / f"{name}_el"
        try:
            touched = max(p.stat().st_mtime for p in (seg, lock) if p.exists())
        except (OSError, ValueError):
            continue
        if touched < since or (lock.exists() and _lock_held(lock)):
            continue
        for path in (seg, lock, shm_dir / f"sem.{name}_mutex"):
            path.unlink(missing_ok=True)
        removed.append(name)
    return removed


def _signal_group(popen: subprocess.Popen[bytes], sig: int) -> None:
    try:
        os.killpg(popen.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


class ProgressWatcher:
    """Follows ``recorder/progress`` from the runner (an rclpy node of its own)."""

    def __init__(self, namespace: str) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import Float64MultiArray

        from servo_axis.nodes.common import LATCHED_QOS

        self._rclpy = rclpy
        self._context = rclpy.context.Context()
        # The runner handles SIGINT/SIGTERM itself (it must stop the nodes).
        rclpy.init(args=[], context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(
            "servo_axis_run",
            namespace=namespace,
            context=self._context,
            enable_rosout=False,
            start_parameter_services=False,
        )
        self.steps = -1
        self.node.create_subscription(Float64MultiArray, "recorder/progress", self._on, LATCHED_QOS)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)

    def _on(self, msg: Any) -> None:
        if msg.data:
            self.steps = max(self.steps, int(msg.data[0]))

    def spin(self, seconds: float) -> None:
        self._executor.spin_once(timeout_sec=seconds)

    def close(self) -> None:
        self._executor.shutdown()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self._context)


class ProgressLine:
    """One progress line, rewritten in place on a terminal."""

    def __init__(self, total: int, out: TextIO) -> None:
        self.total = total
        self.out = out
        self.tty = out.isatty()
        self._last = 0.0

    def show(self, steps: int, elapsed_s: float, final: bool = False) -> None:
        now = time.monotonic()
        if not final and now - self._last < (0.25 if self.tty else 5.0):
            return
        self._last = now
        frac = max(steps, 0) / self.total
        bar = "#" * int(30 * frac)
        rate = max(steps, 0) / elapsed_s if elapsed_s > 0 else 0.0
        text = f"[{bar:<30}] {max(steps, 0)}/{self.total} steps  {rate:,.0f} steps/s"
        if self.tty:
            self.out.write("\r" + text + ("\n" if final else ""))
        else:
            self.out.write(text + "\n")
        self.out.flush()


@dataclass
class RunResult:
    """Outcome of :func:`run_scenario`."""

    run_dir: Path
    steps: int
    wall_time_s: float
    exit_codes: dict[str, int]
    summary: dict[str, Any]


def run_scenario(
    scenario_path: Path,
    *,
    out_dir: Path | None = None,
    composed: bool = False,
    domain_id: int | None = None,
    namespace: str = "",
    progress: TextIO | None = sys.stdout,
    stall_timeout_s: float = 60.0,
    plots: bool = True,
    extra_args: list[str] | None = None,
    on_started: Any = None,
) -> RunResult:
    """Run one scenario end to end and return where it was written.

    A scenario with per-axis sections (``/x/<node>``, ``/y/<node>``) runs
    one set of nodes per axis, each in its own namespace with its own
    ``/<axis>/clock``, all at once; each axis gets a subdirectory of the run
    directory (its own bag, logs, summary) and the run's summary holds the
    per-axis summaries and the contour (XY) figures.

    Raises
    ------
    ConfigError
        For a scenario file that is not a valid scenario.
    RunError
        If a node exits with an error, the run stalls, or a node refuses its
        parameters (its message is in the error).
    RunInterruptedError
        If SIGINT or SIGTERM reached the runner (called from the main
        thread): the nodes are stopped, the bag written so far is closed and
        readable, no summary is made.
    """
    from servo_axis import report

    scenario_path = scenario_path.resolve()
    scenario = load_scenario(scenario_path)
    common = shared(scenario)
    period = float(common.get("control_period_s", 1e-3))
    steps = round(float(common.get("duration_s", 2.0)) / period)
    name = common.get("scenario", {}).get("name") or scenario_path.stem
    if out_dir is None:
        out_dir = Path("runs") / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir = out_dir.resolve()
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ConfigError(f"--out {out_dir}: exists and is not empty")
    names = axes_of(scenario)
    if names and (composed or namespace):
        raise ConfigError(
            f"scenario {scenario_path}: a multi-axis scenario runs as separate processes, "
            "each axis in its own namespace (no --composed, no --namespace)"
        )
    runs: list[_AxisRun] = []
    for axis in names or [""]:
        axis_dir = out_dir / axis if axis else out_dir
        (axis_dir / "logs").mkdir(parents=True, exist_ok=True)
        if axis:
            axis_scenario = axis_view(scenario, axis, scenario_path.parent)
            axis_path = axis_dir / "scenario.yaml"
            axis_path.write_text(dump_params(axis_scenario))
            ns = f"/{axis}"
            args = ["-r", f"__ns:={ns}", "-r", f"/clock:={ns}/clock", *(extra_args or [])]
        else:
            axis_scenario, axis_path, ns = scenario, scenario_path, namespace
            args = [*(["-r", f"__ns:={ns}"] if ns else []), *(extra_args or [])]
        roles = roles_of(axis_scenario)
        params_path = write_run_params(
            axis_scenario,
            handshake_overrides(axis_scenario, roles, axis_dir / "bag", scenario_path.parent),
            axis_dir / "params.yaml",
        )
        runs.append(
            _AxisRun(axis, ns, axis_scenario, axis_path, axis_dir, roles, params_path, args)
        )
    domain = default_domain_id() if domain_id is None else domain_id
    env = ros_environment(domain, runs[0].out_dir / "logs")
    os.environ.update(
        {
            k: env[k]
            for k in (
                "ROS_DOMAIN_ID",
                "ROS_AUTOMATIC_DISCOVERY_RANGE",
                "FASTDDS_BUILTIN_TRANSPORTS",
                "FASTRTPS_DEFAULT_PROFILES_FILE",
            )
        }
    )
    os.environ.setdefault("ROS_LOG_DIR", str(runs[0].out_dir / "logs"))

    line = ProgressLine(steps, progress) if progress is not None else None
    for run in runs:
        if "recorder" in run.roles:
            run.watcher = ProgressWatcher(run.namespace or "/")
    t_start = time.monotonic()
    t_first: float | None = None
    failure: str | None = None
    stop_signals: list[int] = []
    previous_handlers = catch_stop_signals(stop_signals)
    last_progress = -1
    try:
        for run in runs:
            log_dir = run.out_dir / "logs"
            run_env = {**env, "ROS_LOG_DIR": str(log_dir)}
            run.procs = start_nodes(
                run.params_path, run.roles, run.args, run_env, log_dir, composed
            )
        if on_started is not None:
            on_started([p for run in runs for p in run.procs])
        last_change = time.monotonic()
        while not stop_signals:
            for run in runs:
                if run.watcher is not None:
                    run.watcher.spin(0.05 / len(runs))
                else:
                    time.sleep(0.05 / len(runs))
            watched = [run.watcher.steps for run in runs if run.watcher is not None]
            slowest = min(watched) if watched else -1
            if slowest != last_progress:
                last_progress, last_change = slowest, time.monotonic()
                if slowest >= 0 and t_first is None:
                    t_first = time.monotonic()
            if line is not None and t_first is not None:
                line.show(last_progress, time.monotonic() - t_first)
            failure = _check_processes(runs, composed)
            if failure is not None or all(run.plant_done for run in runs):
                break
            if time.monotonic() - last_change > stall_timeout_s:
                failure = f"no progress for {stall_timeout_s:.0f} s (see {out_dir})"
                break
    finally:
        t_end = time.monotonic()
        stop_nodes([p for run in runs for p in run.procs])
        codes = {
            f"{run.axis}/{p.role}" if run.axis else p.role: p.popen.returncode
            for run in runs
            for p in run.procs
        }
        for run in runs:
            if run.watcher is not None:
                run.watcher.close()
        restore_handlers(previous_handlers)
    if stop_signals:
        signame = signal.Signals(stop_signals[0]).name
        bags = ", ".join(str(run.out_dir / "bag") for run in runs)
        raise RunInterruptedError(
            f"interrupted by {signame} at step {max(last_progress, 0)} of {steps}; "
            f"the nodes were stopped, the bag written so far is in {bags}",
            stop_signals[0],
        )
    if line is not None and failure is None:
        line.show(steps, t_end - (t_first or t_start), final=True)
    if failure is not None:
        raise RunError(failure)
    wall = t_end - (t_first or t_start)
    summaries = {}
    for run in runs:
        summaries[run.axis] = report.summarise(
            run.out_dir,
            scenario=run.scenario,
            scenario_path=run.scenario_path,
            wall_time_s=wall,
            mode="composed" if composed else "separate processes",
        )
        if plots:
            report.plot(run.out_dir)
    if not names:
        return RunResult(out_dir, steps, wall, codes, summaries[""])
    summary = report.summarise_axes(out_dir, scenario=scenario, axes=summaries, wall_time_s=wall)
    if plots:
        report.plot_contour(out_dir)
    return RunResult(out_dir, steps, wall, codes, summary)


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
    def plant_done(self) -> bool:
        plant = next((p for p in self.procs if p.role in ("plant", "composed")), None)
        return plant is not None and plant.popen.poll() == 0


def _check_processes(runs: list[_AxisRun], composed: bool) -> str | None:
    """Why the run must stop now (a node failed or quit early), or None."""
    for run in runs:
        where = f"{run.axis}/" if run.axis else ""
        for p in run.procs:
            code = p.popen.poll()
            if code is None or (code == 0 and p.role in ("plant", "composed")):
                continue
            if p.role in ("plant", "composed"):
                return f"{where}{p.role} exited with code {code}:\n{p.tail()}"
            if not run.plant_done:
                return f"{where}{p.role} exited early with code {code}:\n{p.tail()}"
    return None
