"""The node processes of a run: their environment, start, stop and clean-up.

Each node is its own process started with this interpreter (the venv's),
in its own process group, with a private ROS domain, localhost discovery
and a fast discovery profile. rmw_fastrtps adds the shared-memory transport
for localhost discovery whatever the profile says; what a SIGKILLed node
leaves in ``/dev/shm`` is removed by
:func:`~servo_axis.run.fastdds.clean_stale_shm`. On a machine with two or more cores the plant and the
feedback share one core (in lockstep they take turns) and the other nodes
get the rest (``SERVO_AXIS_PIN=0`` turns this off).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from servo_axis import numerics
from servo_axis.params.names import check_domain_id
from servo_axis.run.fastdds import REALTIME_ANNOUNCEMENT_S, clean_stale_shm, realtime_profile

#: Seconds between SIGINT and SIGKILL when the nodes are stopped at a run's
#: end (each stage of :func:`stop_nodes`).
STOP_TIMEOUT_S = 5.0
#: Seconds from SIGINT to SIGKILL of the last process when a signal stopped
#: the run (:func:`stop_nodes` with ``total_s``: a bit under the 5 s in which
#: every process of an interrupted run must be gone).
SIGNAL_STOP_S = 4.5
#: Roles stopped after the others (:func:`stop_nodes`).
STOPPED_LAST = ("recorder",)
#: The roles that take turns on the per-sample path in lockstep.
LOCKSTEP_PAIR = ("plant", "feedback")
#: The roles on the plant's core in realtime (:func:`cpu_set`).
REALTIME_FIRST_CORE = ("plant", "identifier", "learning")


def ros_environment(domain_id: int, log_dir: Path, *, realtime: bool = False) -> dict[str, str]:
    """Environment of the node processes: ``os.environ`` plus the run's ROS settings.

    The numeric paths pinned (:func:`servo_axis.numerics.portable_environment`:
    the same numbers on any x86-64 host, in realtime too, where it costs
    nothing measurable) unless ``SERVO_AXIS_NUMERICS=native``.
    """
    env = numerics.portable_environment(os.environ)
    env.update(discovery_settings(log_dir, realtime=realtime))
    env.update(ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED="1")
    # The nodes' matrices are 3x3 to 8x8: OpenBLAS threads only contend for
    # the cores with the nodes (a 3x3 expm went from 10 to 70-87 us under load).
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def discovery_settings(log_dir: Path, *, realtime: bool = False) -> dict[str, str]:
    """The variables rcl and Fast DDS read when a context and its participant are made.

    Localhost discovery, the profile shipped with the package (100 ms
    discovery announcements, UDP and shared memory with 8 MB segments), and
    the ROS log directory. With ``realtime`` the profile is its copy with
    announcements every second (:func:`~servo_axis.run.fastdds.realtime_profile`,
    written to ``log_dir``).
    """
    profile = Path(str(resources.files("servo_axis") / "data" / "fastdds_localhost.xml"))
    if realtime:
        profile = realtime_profile(profile, log_dir / "fastdds_realtime.xml")
    return {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_LOG_DIR": str(log_dir),
        "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(profile),
    }


def run_header(domain_id: int, namespaces: list[str], settings: Mapping[str, str]) -> list[str]:
    """What a run prints first about its ROS graph: how to reach it from outside.

    Parameters
    ----------
    domain_id : int
        The run's ``ROS_DOMAIN_ID``.
    namespaces : list of str
        The namespace of each axis (``""``: the root).
    settings : mapping
        :func:`discovery_settings` of the run.

    Returns
    -------
    list of str
        The lines: domain and namespaces, discovery and transports, and the
        environment and the command that watch the run (the shipped
        watcher, no ``ros2`` CLI needed).
    """
    shown = [ns or "/" for ns in namespaces]
    first = shown[0].rstrip("/")
    clock = (
        ", each axis its own <ns>/clock" if len(shown) > 1 else "; /clock and /diagnostics absolute"
    )
    range_ = settings["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    profile = settings["FASTRTPS_DEFAULT_PROFILES_FILE"]
    transports = settings["FASTDDS_BUILTIN_TRANSPORTS"]
    realtime = Path(profile).name == "fastdds_realtime.xml"
    announced = f"{REALTIME_ANNOUNCEMENT_S:g} s" if realtime else "100 ms"
    return [
        f"ROS 2: ROS_DOMAIN_ID={domain_id}, namespace{'s' if len(shown) > 1 else ''} "
        f"{', '.join(shown)} (nodes {first}/plant, {first}/feedback, ...{clock})",
        f"discovery: ROS_AUTOMATIC_DISCOVERY_RANGE={range_}, "
        f"FASTRTPS_DEFAULT_PROFILES_FILE={profile} ({announced} announcements, 100 ms "
        "heartbeats), "
        f"transports FASTDDS_BUILTIN_TRANSPORTS={transports}"
        + (
            " + shared memory (rmw_fastrtps adds it under LOCALHOST)"
            if range_ == "LOCALHOST"
            else ""
        ),
        # The watcher ships in the wheel: a PyPI-only user has no ros2 CLI.
        f"watch it: ROS_DOMAIN_ID={domain_id} ROS_AUTOMATIC_DISCOVERY_RANGE={range_} "
        f"python -m servo_axis.examples.watch_run --ros-args -r __ns:={first or '/'}  "
        "(or ros2 topic echo, or run --live for Foxglove: docs/how-to/watch-a-run.md)",
    ]


def default_domain_id() -> int:
    """ROS_DOMAIN_ID from the environment, else one derived from the pid (1..100).

    Raises
    ------
    ConfigError
        For a ROS_DOMAIN_ID that is not an integer 0..232.
    """
    if "ROS_DOMAIN_ID" in os.environ:
        return check_domain_id(os.environ["ROS_DOMAIN_ID"], "ROS_DOMAIN_ID")
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
        """The last ``lines`` lines of the process's output."""
        self.log.flush()
        text = self.log_path.read_text(errors="replace").splitlines()
        return "\n".join(text[-lines:])


@dataclass(frozen=True)
class Launch:
    """How the node processes of one axis are started.

    Attributes
    ----------
    params_path : Path
        The run's parameter file (``--params-file``).
    args : tuple of str
        ROS arguments after it (the namespace remaps, ``-p`` overrides).
    env : mapping
        The processes' environment (:func:`ros_environment`).
    log_dir : Path
        Where each process logs (``<log_dir>/<role>.log``).
    realtime : bool
        The run's time mode is realtime (the cores are shared out
        differently, :func:`cpu_set`).
    """

    params_path: Path
    args: tuple[str, ...]
    env: Mapping[str, str]
    log_dir: Path
    realtime: bool = False


def start_nodes(launch: Launch, roles: list[str], composed: bool = False) -> list[Proc]:
    """Start the node processes of ``roles`` (or one composed process), each logging to its own file."""
    if composed:
        return [start_node(launch, "composed", roles=roles)]
    return [start_node(launch, role) for role in roles]


def start_node(
    launch: Launch, role: str, *, roles: list[str] | None = None, log_name: str | None = None
) -> Proc:
    """Start one node process (``role`` = ``composed``: the nodes of ``roles`` in one).

    Its output goes to ``<launch.log_dir>/<log_name or role>.log``.
    """
    cmd = (
        ["-m", "servo_axis.nodes.composed", *(roles or [])]
        if role == "composed"
        else ["-m", f"servo_axis.nodes.{role}"]
    )
    args = [*cmd, "--ros-args", "--params-file", str(launch.params_path), *launch.args]
    log_path = launch.log_dir / f"{log_name or role}.log"
    return start_process(role, args, dict(launch.env), log_path, realtime=launch.realtime)


def pids_of(run_dir: Path, role: str) -> list[int]:
    """Processes of ``role`` started for the run in ``run_dir`` (their command line names its params file)."""
    out = subprocess.run(
        ["pgrep", "-f", f"servo_axis.nodes.{role} .*{run_dir}/params.yaml"],
        capture_output=True,
        text=True,
        check=False,
    )
    return [int(p) for p in out.stdout.split()]


def start_process(
    role: str,
    args: list[str],
    env: dict[str, str],
    log_path: Path,
    *,
    realtime: bool = False,
    pinned: bool = True,
) -> Proc:
    """Start ``python args...`` (this interpreter) as a process of the run, logging to ``log_path``.

    In its own process group, pinned like ``role`` (:func:`cpu_set`; not
    with ``pinned`` false), and ended by the kernel when the runner dies
    (:func:`_in_child`).
    """
    log = log_path.open("wb")
    pin = pinned and os.environ.get("SERVO_AXIS_PIN", "1") == "1"
    cpus = cpu_set(role, realtime=realtime) if pin else None
    runner = os.getpid()
    popen = subprocess.Popen(
        [sys.executable, *args],
        preexec_fn=lambda: _in_child(runner, cpus),
        stdout=log,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env=env,
        start_new_session=True,
    )
    return Proc(role, popen, log_path, log)


#: ``prctl`` option: the signal a process gets when its parent dies.
PR_SET_PDEATHSIG = 1


def _in_child(runner: int, cpus: set[int] | None) -> None:
    """In a node's process before it runs: its cores, and its end when the runner dies.

    ``PR_SET_PDEATHSIG`` SIGKILLs the node when the thread that started it
    ends (the runner starts its nodes from its main thread); a runner that
    died between the fork and here is caught by its pid (a node left
    running would hold a core at a realtime priority, issue 30).
    """
    if cpus:
        os.sched_setaffinity(0, cpus)
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
    if os.getppid() != runner:
        os._exit(1)


def cpu_set(
    role: str, *, realtime: bool = False, cpus: Sequence[int] | None = None
) -> set[int] | None:
    """The cores a node is pinned to; None (no pinning) on a single core.

    ``cpus``: the cores to share out (None: those this process may use).

    Lockstep: the plant and the feedback take turns, so one core is enough
    for both, and the recorder, the feedforward generator and the others get
    the rest (measured on 2 cores, ``dlpid_tilt_lpf2``: 1.22-1.32x real time
    pinned so, 0.80-1.00x unpinned). Realtime: the first core is the
    plant's, shared only with the nodes that read the per-sample streams at
    their own pace and answer nothing within a period (the identifier, the
    learning unit: the plant's wake-up at each deadline preempts them);
    the feedback, the feedforward generator (which must stay a preview
    window ahead) and the recorder get the rest. With the pair on one core
    the plant's wait for its next deadline and the feedback's answer took
    turns on it; with the plant alone, the other core was overloaded at
    0.4 ms and the identifier fell behind. Figures: docs/benchmarks.md
    ("realtime: the identifier and the learning unit beside the plant").
    """
    cores = sorted(os.sched_getaffinity(0) if cpus is None else cpus)
    if len(cores) < 2:
        return None
    first = role in REALTIME_FIRST_CORE if realtime else role in LOCKSTEP_PAIR
    return {cores[0]} if first else set(cores[1:])


def stop_nodes(
    procs: list[Proc],
    timeout_s: float = STOP_TIMEOUT_S,
    *,
    last: tuple[str, ...] = STOPPED_LAST,
    total_s: float | None = None,
) -> dict[str, int]:
    """SIGINT every live process group, SIGKILL what is left after ``timeout_s``; reap all.

    With ``total_s`` (a run a signal stopped) every process is gone within
    it: the others get 60 % of it, the last ones the rest (at least a
    second). The roles in ``last`` (the recorder) are stopped once the
    others have exited: each node waits at its end until its last samples are
    acknowledged, and the recorder then writes what is still on its way
    (:func:`~servo_axis.nodes.runtime.finish`), so that nothing a node sent
    before it stopped is missing from the bag.

    Returns the exit code of each role (negative: killed by that signal).
    After a SIGKILL the shared-memory files of the killed participants are
    removed (:func:`clean_stale_shm`).
    """
    t0 = time.monotonic()
    first = timeout_s if total_s is None else 0.6 * total_s
    _interrupt([p for p in procs if p.role not in last], first)
    rest = timeout_s if total_s is None else max(1.0, total_s - (time.monotonic() - t0))
    _interrupt([p for p in procs if p.role in last], rest)
    for p in procs:
        _signal_group(p.popen, signal.SIGKILL)  # stray children of the group, if any
        p.log.close()
    if procs and any(p.popen.returncode == -signal.SIGKILL for p in procs):
        clean_stale_shm(since=min(p.started_at for p in procs))
    return {p.role: p.popen.returncode for p in procs}


def _interrupt(procs: list[Proc], timeout_s: float) -> None:
    """SIGINT ``procs`` and wait for them, SIGKILL those still there after ``timeout_s``."""
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


def _signal_group(popen: subprocess.Popen[bytes], sig: int) -> None:
    try:
        os.killpg(popen.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass
