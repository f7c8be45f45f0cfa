"""The realtime floor of this host: the deadline misses of a bare pair of rclpy processes.

``python -m servo_axis floor [--period-us P ...] [--ticks N] [--json]``
measures, at each period, what a plant and a controller that do nothing but
exchange one ``JointState`` per tick miss (:mod:`servo_axis.run.floor_pair`):
the least any node pair on this machine, with this middleware, can miss. A
realtime run's misses mean something only next to it, taken in the same
session (a shared host drifts from hour to hour): ``run --floor FILE``
puts the floor at the run's period in its summary, ``FILE`` being what
``floor --json`` prints (one JSON object a line, by period).

Each measurement gets its own ROS domain, localhost discovery with the
realtime runs' discovery profile and a temporary ROS log directory, removed
after; its two processes are reaped (SIGINT, then SIGKILL, then the shared
memory a killed participant left), on Ctrl-C too. Nothing here imports rclpy.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import tempfile
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servo_axis.core.errors import ConfigError
from servo_axis.run.processes import Proc, ros_environment, start_process, stop_nodes
from servo_axis.stop_signals import STOP_SIGNALS, restore_handlers

#: The periods measured by default, us (the suite's realtime scenarios run at 1 ms to 400 us).
DEFAULT_PERIODS_US = (1000, 500, 400)
#: Ticks per period by default.
DEFAULT_TICKS = 10_000
#: Seconds a measurement may take beyond its ticks (start-up, discovery, warm-up).
MARGIN_S = 40.0
#: The fields ``run --floor`` reads of each result (``servo_axis.cli.run_command``).
REQUIRED_FIELDS = ("period_us", "miss_pct", "round_trip_us")


class FloorError(ConfigError):
    """A floor that could not be measured (a process failed, no controller appeared)."""


class FloorInterruptedError(Exception):
    """SIGINT or SIGTERM while the floor was measured (both processes are gone by then)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass(frozen=True)
class FloorOptions:
    """How the floor is measured.

    Attributes
    ----------
    ticks : int
        Ticks per period, >= 1.
    executor : str
        ``events`` (rclpy's EventsExecutor, as the suite's nodes) or
        ``single`` (SingleThreadedExecutor).
    priority : int
        ``SCHED_FIFO`` priority of both processes' executor threads, 1-99
        (their middleware receive threads one below), as a realtime run's
        plant and feedback with ``thread_priority`` at it; 0: the default
        scheduler.
    domain_id : int
        The ROS domain of the pair.
    """

    ticks: int = DEFAULT_TICKS
    executor: str = "events"
    priority: int = 0
    domain_id: int = 0


def measure(period_us: float, options: FloorOptions) -> dict[str, Any]:
    """The floor at one period: the plant's JSON result (``misses``, ``round_trip_us``, ...).

    Raises
    ------
    FloorError
        When a process of the pair failed or the controller never appeared
        (the message has the plant's last log lines).
    FloorInterruptedError
        On SIGINT or SIGTERM (:func:`measure_all`), once both processes are gone.
    """
    period_ns = round(period_us * 1000)
    seconds = options.ticks * period_ns * 1e-9 + MARGIN_S
    work = Path(tempfile.mkdtemp(prefix="servo_axis_floor_"))
    procs: list[Proc] = []
    try:
        env = ros_environment(options.domain_id, work, realtime=True)
        common = ["-m", "servo_axis.run.floor_pair", "--executor", options.executor]
        common += ["--priority", str(options.priority)]
        start = _starter(env, work)
        procs.append(start("controller", [*common, "--seconds", f"{seconds:g}"]))
        result = work / "result.json"
        timing = ["--period-ns", str(period_ns), "--ticks", str(options.ticks)]
        plant = start("plant", [*common, *timing, "--result", str(result)])
        procs.append(plant)
        try:
            code = plant.popen.wait(timeout=seconds)
        except subprocess.TimeoutExpired:
            code = None
        if code != 0 or not result.is_file():
            why = "did not end" if code is None else f"exit {code}"
            raise FloorError(
                f"floor at {period_us:g} us: the plant process failed ({why}): "
                + " | ".join(plant.tail(3).splitlines())
            )
        return dict(json.loads(result.read_text()))
    finally:
        stop_nodes(procs)
        shutil.rmtree(work, ignore_errors=True)


def _starter(env: dict[str, str], work: Path) -> Callable[[str, list[str]], Proc]:
    def start(role: str, args: list[str]) -> Proc:
        return start_process(
            role, [*args[:2], "--role", role, *args[2:]], env, work / f"{role}.log", pinned=False
        )

    return start


def measure_all(
    periods_us: Sequence[float],
    options: FloorOptions,
    on_result: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """:func:`measure` at each period in turn (``on_result`` called with each as it comes).

    Raises
    ------
    FloorInterruptedError
        On SIGINT or SIGTERM (in the main thread), once the pair is reaped
        and its temporary directory removed.
    """

    def interrupt(signum: int, _frame: object) -> None:
        raise FloorInterruptedError(signum)

    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        previous = {sig: signal.signal(sig, interrupt) for sig in STOP_SIGNALS}
    results = []
    try:
        for period in periods_us:
            r = measure(period, options)
            results.append(r)
            if on_result is not None:
                on_result(r)
    finally:
        restore_handlers(previous)
    return results


def table_header() -> str:
    """The header of :func:`table_row`'s table."""
    return (
        f"{'period':>8} {'executor':>8} {'misses':>16} {'tick late p99':>14} "
        f"{'round trip p50/p99/max (us)':>30}"
    )


def table_row(r: dict[str, Any]) -> str:
    """One result as a line of the table ``floor`` prints without ``--json``."""
    rt = r["round_trip_us"]
    return (
        f"{r['period_us']:>6}us {r['executor']:>8} {r['misses']:>6} ({r['miss_pct']:.2f} %)"
        f" {r['tick_late_us']['p99']:>12}us {rt['p50']:>10}/{rt['p99']}/{rt['max']}"
    )


def read_floor(path: str | Path) -> dict[int, dict[str, Any]]:
    """``floor --json`` results of a file, by period in us (what ``run --floor`` reads).

    Raises
    ------
    ConfigError
        ``--floor <path>: ...`` for a file that cannot be read, a line that
        is not a JSON object with :data:`REQUIRED_FIELDS`, or no line at all.
    """
    try:
        text = Path(path).read_text()
    except OSError as err:
        raise ConfigError(f"--floor {path}: cannot read it: {err.strerror}") from None
    out: dict[int, dict[str, Any]] = {}
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            missing = [f for f in REQUIRED_FIELDS if f not in row]
            if missing:
                raise ValueError(f"no {', '.join(missing)}")
            out[int(row["period_us"])] = row
        except (ValueError, TypeError) as err:
            raise ConfigError(
                f"--floor {path}: line {number} is not a result of "
                f"`python -m servo_axis floor --json` ({err})"
            ) from None
    if not out:
        raise ConfigError(f"--floor {path}: no result (`python -m servo_axis floor --json` output)")
    return out
