"""The live view from the runner's side: checked before a run, started before its nodes, stopped after.

The live process is :mod:`servo_axis.run.live`. The runner checks before
anything is written that it can serve (:func:`check_live`), starts it before
the nodes (:class:`LiveView`), waits until its server listens
(:func:`wait_ready`) so that the URL it prints is live, and stops it after
the nodes, so that it forwards what they sent last. Its death never stops
the run. No handshake waits for it.
"""

from __future__ import annotations

import dataclasses
import json
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from servo_axis.core.errors import ConfigError
from servo_axis.params.run_plan import AxisPlan
from servo_axis.run.live_channels import (
    DRAIN_MAX_S,
    HOST,
    INSTALL_HINT,
    READY,
    TERMINAL,
    LiveAxis,
)
from servo_axis.run.processes import Proc, start_process, stop_nodes

#: Seconds the runner waits for the live view to listen.
READY_TIMEOUT_S = 20.0
#: Seconds the live view is given to stop: it drains for up to DRAIN_MAX_S.
STOP_TIMEOUT_S = DRAIN_MAX_S + 10.0
#: How often the runner looks for the live view's lines for the terminal.
RELAY_EVERY_S = 0.25


def live_axis(plan: AxisPlan) -> LiveAxis:
    """The :class:`LiveAxis` of one axis of a run."""
    return LiveAxis(
        namespace=plan.namespace,
        axis=plan.joint_axis,
        control_period_s=plan.control_period_s,
        sensor=plan.sensor,
        lead_m_per_rad=plan.lead_m_per_rad,
        linear=plan.linear,
        lockstep=not plan.realtime,
        steps=plan.steps,
    )


def check_live(port: int) -> None:
    """Raise :class:`ConfigError` (one line) if the live view cannot be served on ``port``.

    The optional package must be there, and ``port`` a free TCP port of
    the loopback interface.
    """
    try:
        import foxglove
    except ImportError:
        raise ConfigError(INSTALL_HINT) from None
    if not hasattr(foxglove, "start_server"):  # another package of that name
        raise ConfigError(INSTALL_HINT)
    if not 1 <= port <= 65535:
        raise ConfigError(f"--live-port {port}: expected a TCP port 1..65535")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        # As the server binds: a connection of a previous run still in
        # TIME_WAIT does not make the port busy, a listener does.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((HOST, port))
        except OSError as err:
            raise ConfigError(
                f"--live-port {port}: cannot listen on {HOST}:{port} ({err.strerror})"
            ) from None


def module_args(port: int, axes: list[LiveAxis]) -> list[str]:
    """The command line of the live process after ``python -m servo_axis.run.live``."""
    return ["--port", str(port), "--axes", json.dumps([dataclasses.asdict(a) for a in axes])]


def wait_ready(
    log_path: Path,
    alive: Callable[[], bool],
    *,
    stopped: Callable[[], bool] = lambda: False,
    timeout_s: float = READY_TIMEOUT_S,
) -> str:
    """Wait until the live process says it serves; its URL ("" if ``stopped()`` first).

    Raises
    ------
    ConfigError
        With the process's last line if it exits or does not listen within
        ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        text = log_path.read_text(errors="replace") if log_path.exists() else ""
        for line in text.splitlines():
            if line.startswith(READY):
                return line.removeprefix(READY).split()[0]
        if stopped():
            return ""
        if not alive() or time.monotonic() > deadline:
            last = text.strip().splitlines()[-1:] or ["no output"]
            why = "exited" if not alive() else f"did not listen within {timeout_s:.0f} s"
            raise ConfigError(f"--live: the live view {why}: {last[0]} (log: {log_path})")
        time.sleep(0.02)


@dataclass
class LiveView:
    """The live view of a run: its port and axes, where it says its URL, its process once started."""

    port: int
    axes: list[LiveAxis]
    out: TextIO | None
    proc: Proc | None = None
    relay: LogRelay | None = None

    def start(self, env: dict[str, str], log_dir: Path, stopped: Callable[[], bool]) -> None:
        """Start the live process and wait until it listens (or ``stopped()``); print its URL."""
        self.proc = start_process(
            "live",
            ["-m", "servo_axis.run.live", *module_args(self.port, self.axes)],
            {**env, "ROS_LOG_DIR": str(log_dir)},
            log_dir / "live.log",
        )
        proc = self.proc
        address = wait_ready(proc.log_path, lambda: proc.popen.poll() is None, stopped=stopped)
        if address and self.out is not None:
            print(
                f"live view: {address}  (Foxglove / Lichtblick: open a connection, "
                "Foxglove WebSocket, this URL)",
                file=self.out,
                flush=True,
            )
        # What the user must know at once (a viewer refused, what was not
        # forwarded) goes from its log to the terminal.
        self.relay = LogRelay(proc.log_path, sys.stderr)
        self.relay.start()

    def stop(self) -> None:
        """Stop the live process, if it was started; say so if it had failed (the run goes on)."""
        if self.proc is None:
            return
        code = stop_nodes([self.proc], STOP_TIMEOUT_S)["live"]
        if self.relay is not None:
            self.relay.stop()
        if code != 0:
            print(
                f"live view exited with code {code} (see {self.proc.log_path}); "
                "the run is not affected",
                file=sys.stderr,
            )


class LogRelay:
    """A thread that copies the live view's lines for the terminal (:data:`TERMINAL`) to ``out``.

    The live process writes to its log; a viewer that could not connect, or
    the steps a viewer did not get, must reach the user's terminal while the
    run goes on (and at its end), not only that log.
    """

    def __init__(self, log_path: Path, out: TextIO) -> None:
        self._path = log_path
        self._out = out
        self._offset = 0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="live-relay", daemon=True)

    def start(self) -> None:
        """Start copying."""
        self._thread.start()

    def stop(self) -> None:
        """Copy what is left (the process has ended) and stop."""
        self._done.set()
        self._thread.join(timeout=5.0)
        self.copy()

    def copy(self) -> None:
        """Copy the lines for the terminal written since the last call."""
        try:
            with self._path.open("rb") as f:
                f.seek(self._offset)
                data = f.read()
        except OSError:
            return
        end = data.rfind(b"\n") + 1  # whole lines only
        self._offset += end
        for line in data[:end].decode(errors="replace").splitlines():
            if line.startswith(TERMINAL):
                print(line, file=self._out, flush=True)

    def _run(self) -> None:
        while not self._done.wait(RELAY_EVERY_S):
            self.copy()
