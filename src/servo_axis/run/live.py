"""The live view: a run served to Foxglove or Lichtblick over their WebSocket protocol.

``python -m servo_axis run SCENARIO --live [--live-port N]`` starts this
module as a process of the run (``python -m servo_axis.run.live --port N
--axes JSON``): it serves ``ws://127.0.0.1:N`` with the ``foxglove-sdk``
package (the optional extra ``servo_axis[live]``) and forwards, per axis,

* ``<ns>/state``, ``<ns>/reference``, ``<ns>/command``: the validated
  samples of those topics (the fields of
  :class:`~servo_axis.wire.messages.StateSample`,
  :class:`~servo_axis.wire.messages.ReferenceSample`,
  :class:`~servo_axis.wire.messages.CommandSample`, SI units in their names);
* ``<ns>/tracking_error``: the reference position minus the controlled
  output (:func:`~servo_axis.core.feedback.output.controlled_output` of the
  feedback's ``sensor``: the encoder angle for the semi-closed loop) for
  each step where both are known, in rad of motor angle and, for a linear
  axis, in m of table position (times the lead ``R``);

and ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) when a node
publishes it. Channels are JSON with a JSON schema, named like the ROS topics.
Each message is logged at its simulation time (the header stamp, integer
ns), so the viewer's timeline is the simulated one; ``/diagnostics``, whose
stamps need not be simulation times, at the latest simulation time the
bridge has seen, and the server's time (the ``time`` capability) follows the
simulation too.

It does not change the run. It is not one of the run's roles: no handshake
counts it (:meth:`~servo_axis.nodes.base.ServoNode.consumers_matched` counts
only the table's consumers and the recorder), and it publishes nothing the
nodes read. It subscribes as the nodes do
(:func:`~servo_axis.nodes.base.reader_qos`: reliable, transient-local,
keep-last 2000), so that it gets the first samples from the writers'
history even when it is matched after they were sent (a ``--composed`` run
starts within its discovery time); a keep-last writer never waits for a
reader, it drops its oldest sample instead. The recorded bytes are those of
a run without it (``test/integration/test_live.py``).
Apart from ``state`` (whose stamps are the simulation time) a message is
decoded only while a viewer is subscribed to a channel that needs it, so
the bridge costs little when nobody watches.

Why a process of its own rather than a thread of the runner: the bridge
receives and converts several thousand messages per simulated second in
Python; in the runner it would hold the GIL that the runner's watch loop
(progress, node deaths, SIGINT/SIGTERM) needs, and a fault in the native
WebSocket server would take the runner down with it. As a process it is
pinned off the plant's and the feedback's core like the recorder
(:func:`~servo_axis.run.processes.cpu_set`), started before the nodes (the
runner waits for its server to listen, so the URL it prints is live) and
stopped after them (it forwards what is still arriving), reaped like a node;
its death never stops the run.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servo_axis.core.errors import ConfigError, SignalError

#: Where the live view listens (loopback only) and its default port.
HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: What the process prints once its server listens (the runner waits for it).
READY = "live view serving"
#: The one line shown when the optional extra is missing.
INSTALL_HINT = (
    "--live needs the optional package foxglove-sdk: install it with "
    "`.venv/bin/pip install -e '.[live]'` (or `pip install 'servo_axis[live]'`)"
)
#: Seconds the runner waits for the live view to listen.
READY_TIMEOUT_S = 20.0
#: The server's time is broadcast every this many simulated seconds.
TIME_EVERY_S = 0.01
#: Messages buffered per viewer before the oldest is dropped (the SDK's
#: default, 1024, is a quarter of a simulated second of four 1 kHz channels).
BACKLOG_MESSAGES = 16_384
#: Seconds the live view goes on forwarding after SIGINT/SIGTERM while
#: messages still arrive (the runner's SIGKILL comes 5 s after its SIGINT),
#: and the pause in arrivals that ends it sooner.
DRAIN_S = 3.0
DRAIN_IDLE_S = 0.5
#: Seconds the server is given to send what it has queued before it stops.
FLUSH_S = 0.3
#: Steps a reference or an output waits for its partner before it is dropped.
PAIR_WINDOW_STEPS = 20_000
#: Samples of a realtime stream that may wait for a missing earlier step
#: before the gap is given up (:class:`InOrder`): a realtime stream skips
#: steps (a late command is not answered), and a viewer must not lag for them.
HOLD_SAMPLES = 200
#: The same in lockstep, where every step comes: a step missing at the bridge
#: is the writers' history, still on its way to a reader matched late, for as
#: long as the writers keep it (their depth, ``STREAM_QOS``). A fixed 200
#: was 50 ms of a 4,000-steps/s run: a viewer once got state 0, then 5, and
#: 1,819 of 2,000 states.
HOLD_LOCKSTEP_SAMPLES = 2000


@dataclass(frozen=True)
class LiveAxis:
    """What the live view needs to know of one axis.

    Attributes
    ----------
    namespace : str
        The axis namespace (``""`` for none, ``"/x"``).
    axis : str
        The axis name (JointState names ``<axis>_motor``, ``<axis>_table``).
    control_period_s : float
        ``T_u``, s.
    sensor : str
        The feedback's controlled output: ``encoder`` or ``scale``.
    lead_m_per_rad : float
        ``R``, m/rad.
    linear : bool
        True when the table moves along a line (the error is also given in
        m, ``R (r - y)``); False for a rotary table.
    lockstep : bool
        The run's time mode is lockstep (every step comes: a gap is waited
        for, :data:`HOLD_LOCKSTEP_SAMPLES`); False: realtime.
    """

    namespace: str
    axis: str
    control_period_s: float
    sensor: str
    lead_m_per_rad: float
    linear: bool
    lockstep: bool = True

    def topic(self, name: str) -> str:
        """The resolved ROS name of the axis's topic ``name``."""
        return f"{self.namespace.rstrip('/')}/{name}"


def live_axis(scenario: dict[str, Any], namespace: str) -> LiveAxis:
    """The :class:`LiveAxis` of a single-axis scenario run in ``namespace``."""
    from servo_axis.analysis.summary import error_unit
    from servo_axis.params.resolve import node_values

    plant = node_values(scenario, "plant")
    feedback = node_values(scenario, "feedback")
    return LiveAxis(
        namespace=namespace,
        axis=plant["axis"],
        control_period_s=plant["control_period_s"],
        sensor=feedback["sensor"],
        lead_m_per_rad=feedback["lead_m_per_rad"],
        linear=error_unit(plant) == "m",
        lockstep=plant["mode"] == "lockstep",
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


def url(port: int) -> str:
    """The WebSocket URL of the live view on ``port``."""
    return f"ws://{HOST}:{port}"


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


class ErrorPairs:
    """Pairs reference positions and controlled outputs of the same step.

    Each stream comes in order of step; a pair is complete when the second
    of its two values arrives. Values older than :data:`PAIR_WINDOW_STEPS`
    behind the newest step seen are dropped, so that a value whose partner
    never comes does not stay forever.
    """

    def __init__(self, window: int = PAIR_WINDOW_STEPS) -> None:
        self._window = window
        self._refs: dict[int, float] = {}
        self._outputs: dict[int, float] = {}
        self._newest = -1

    def reference(self, step: int, position_rad: float) -> tuple[float, float] | None:
        """Offer ``r[step]``; ``(r, y)`` if ``y[step]`` was there."""
        return self._offer(step, position_rad, self._refs, self._outputs, first=False)

    def output(self, step: int, output_rad: float) -> tuple[float, float] | None:
        """Offer ``y[step]``; ``(r, y)`` if ``r[step]`` was there."""
        return self._offer(step, output_rad, self._outputs, self._refs, first=True)

    def _offer(
        self,
        step: int,
        value: float,
        mine: dict[int, float],
        other: dict[int, float],
        *,
        first: bool,
    ) -> tuple[float, float] | None:
        if step > self._newest:
            self._newest = step
            if len(mine) + len(other) > 2 * self._window:
                old = self._newest - self._window
                for table in (mine, other):
                    for k in [k for k in table if k < old]:
                        del table[k]
        partner = other.pop(step, None)
        if partner is None:
            mine[step] = value
            return None
        return (partner, value) if first else (value, partner)


def sample_schema(cls: type, title: str) -> dict[str, Any]:
    """JSON schema of a sample dataclass (its fields) plus ``timestamp`` (sec, nsec)."""
    kinds = {"int": "integer", "float": "number", "bool": "boolean"}
    properties: dict[str, Any] = {"timestamp": TIME_SCHEMA}
    for f in dataclasses.fields(cls):
        properties[f.name] = {"type": kinds.get(str(f.type), "number")}
    return {"title": title, "type": "object", "properties": properties}


TIME_SCHEMA: dict[str, Any] = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0}},
}

ERROR_FIELDS = ("step", "reference_rad", "output_rad", "error_rad")

DIAGNOSTICS_SCHEMA: dict[str, Any] = {
    "title": "diagnostic_msgs/msg/DiagnosticArray",
    "type": "object",
    "properties": {
        "header": {
            "type": "object",
            "properties": {"stamp": TIME_SCHEMA, "frame_id": {"type": "string"}},
        },
        "status": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "level": {"type": "integer"},
                    "name": {"type": "string"},
                    "message": {"type": "string"},
                    "hardware_id": {"type": "string"},
                    "values": {
                        "type": "array",
                        "items": {
                            "type": "object",
                            "properties": {
                                "key": {"type": "string"},
                                "value": {"type": "string"},
                            },
                        },
                    },
                },
            },
        },
    },
}


def error_schema(axis: LiveAxis) -> dict[str, Any]:
    """JSON schema of ``<ns>/tracking_error``."""
    properties: dict[str, Any] = {"timestamp": TIME_SCHEMA, "step": {"type": "integer"}}
    for name in ERROR_FIELDS[1:]:
        properties[name] = {"type": "number"}
    if axis.linear:
        properties["error_m"] = {"type": "number"}
    return {"title": "servo_axis tracking error r - y", "type": "object", "properties": properties}


def stamp_json(ns: int) -> dict[str, int]:
    """``{"sec", "nsec"}`` of a time in ns."""
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


class _Gate:
    """Forwards a channel's samples in increasing step only (a stranger's repeat is dropped)."""

    def __init__(self) -> None:
        self.last = -1

    def take(self, step: int) -> bool:
        if step <= self.last:
            return False
        self.last = step
        return True


class InOrder:
    """Hands a stream's samples on in increasing step, each step once.

    The bridge's reader can be matched with a writer after its first
    samples: it then gets the writer's history (transient-local) after some
    newer samples, and an increasing-only gate dropped the older ones (a
    viewer once got state 0, then 5: 15 of 2,000 states missing). The first
    sample starts the stream (a bridge may join one under way); a sample
    that comes ahead of a missing step waits for it, while at most ``hold``
    samples wait; past that the gap is given up (a realtime stream may skip
    steps). A step at or before the last one handed on is dropped (a
    stranger's repeat).

    Parameters
    ----------
    hold : int
        Samples that may wait for a missing step, >= 0.
    """

    def __init__(self, hold: int = HOLD_SAMPLES) -> None:
        self.hold = hold
        self.last = -1
        self._waiting: dict[int, Any] = {}

    def put(self, step: int, item: Any) -> list[Any]:
        """The items to hand on now, in step order, once ``item`` of ``step`` came."""
        if self.last < 0 and not self._waiting:
            self.last = step - 1  # the first sample starts the stream
        if step <= self.last or step in self._waiting:
            return []
        self._waiting[step] = item
        out = []
        while self._waiting and (self.last + 1 in self._waiting or len(self._waiting) > self.hold):
            step = self.last + 1 if self.last + 1 in self._waiting else min(self._waiting)
            out.append(self._waiting.pop(step))
            self.last = step
        return out

    def skip(self, step: int) -> None:
        """``step`` went by unused: the stream goes on after it."""
        self.last = max(self.last, step)
        for old in [k for k in self._waiting if k <= step]:
            del self._waiting[old]

    def flush(self) -> list[Any]:
        """Everything still waiting, in step order (the stream has ended)."""
        out = [self._waiting[k] for k in sorted(self._waiting)]
        if self._waiting:
            self.last = max(self._waiting)
        self._waiting.clear()
        return out


class LiveBridge:
    """The channels of the live view and the rclpy subscriptions that feed them.

    Parameters
    ----------
    foxglove : module
        The ``foxglove`` package (imported by the caller: optional).
    axes : list of LiveAxis
        The axes of the run.

    Attributes
    ----------
    server : foxglove.WebSocketServer or None
        The server whose time follows the simulation (set once it is
        started: the channels are made first, so that a viewer that connects
        at once finds them all; one advertised while a viewer was
        connecting was refused as "Unknown channel ID" in foxglove-sdk 0.30).
    """

    def __init__(self, foxglove: Any, axes: list[LiveAxis]) -> None:
        from servo_axis.wire import messages as msgs

        self.server: Any = None
        self.last_message_s = time.monotonic()
        self.axes = axes
        self.rejected = 0
        self._flushes: list[Callable[[], None]] = []
        self.sim_ns = 0
        self._channels: dict[str, Any] = {}

        def channel(topic: str, schema: dict[str, Any]) -> Any:
            ch = foxglove.Channel(
                topic,
                schema=foxglove.Schema(
                    name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
            )
            self._channels[topic] = ch
            return ch

        for axis in axes:
            label = f"servo_axis {axis.topic('')}"
            channel(axis.topic("state"), sample_schema(msgs.StateSample, f"{label}state"))
            channel(
                axis.topic("reference"), sample_schema(msgs.ReferenceSample, f"{label}reference")
            )
            channel(axis.topic("command"), sample_schema(msgs.CommandSample, f"{label}command"))
            channel(axis.topic("tracking_error"), error_schema(axis))
        channel("/diagnostics", DIAGNOSTICS_SCHEMA)

    @property
    def topics(self) -> list[str]:
        """The channels' topics."""
        return list(self._channels)

    def flush(self) -> None:
        """Forward what still waits for a missing step (the run has ended)."""
        for flush in self._flushes:
            flush()

    def subscribe(self, node: Any) -> None:
        """Subscribe ``node`` to every topic the channels need."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        for axis in self.axes:
            self._subscribe_axis(node, axis)
        try:
            from diagnostic_msgs.msg import DiagnosticArray
        except ImportError:  # not installed: the channel stays empty
            return
        diagnostics = self._channels["/diagnostics"]

        def on_diagnostics(msg: Any) -> None:
            if diagnostics.has_sinks():
                diagnostics.log(diagnostics_json(msg), log_time=self.sim_ns)

        # Best effort reads from reliable and best-effort publishers alike.
        node.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            on_diagnostics,
            QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT),
        )

    def _subscribe_axis(self, node: Any, axis: LiveAxis) -> None:
        """``state``, ``reference`` and ``command`` of one axis, and its tracking error."""
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState

        from servo_axis.core.feedback.output import controlled_output
        from servo_axis.nodes.base import reader_qos
        from servo_axis.wire import messages as msgs

        period = msgs.period_ns(axis.control_period_s)
        every = max(1, round(TIME_EVERY_S / axis.control_period_s))
        pairs = ErrorPairs()
        error_ch = self._channels[axis.topic("tracking_error")]
        error_gate = _Gate()

        def emit_error(step: int, pair: tuple[float, float] | None) -> None:
            if pair is None or not error_gate.take(step):
                return
            r, y = pair
            ns = step * period
            out: dict[str, Any] = {
                "timestamp": stamp_json(ns),
                "step": step,
                "reference_rad": r,
                "output_rad": y,
                "error_rad": r - y,
            }
            if axis.linear:
                out["error_m"] = axis.lead_m_per_rad * (r - y)
            error_ch.log(out, log_time=ns)

        def stream(
            name: str,
            decode: Callable[[Any], Any],
            after: Callable[[Any], None] | None,
            always: bool = False,
        ) -> None:
            ch = self._channels[axis.topic(name)]
            order = InOrder(hold=HOLD_LOCKSTEP_SAMPLES if axis.lockstep else HOLD_SAMPLES)

            def forward(samples: list[Any]) -> None:
                for sample in samples:
                    if ch.has_sinks():
                        ns = sample.step * period
                        ch.log(
                            {"timestamp": stamp_json(ns), **dataclasses.asdict(sample)}, log_time=ns
                        )
                    if after is not None:
                        after(sample)

            def on_data(data: bytes) -> None:
                self.last_message_s = time.monotonic()
                needed = always or ch.has_sinks() or (after is not None and error_ch.has_sinks())
                if not needed:
                    # Unwatched, it moves on all the same: a viewer that
                    # subscribes later does not wait for the steps skipped.
                    with contextlib.suppress(SignalError):  # junk: not forwarded anyway
                        order.skip(msgs.stamp_ns_from_cdr(data) // period)
                    return
                try:
                    sample = decode(deserialize_message(data, JointState))
                except SignalError:
                    self.rejected += 1
                    return
                forward(order.put(sample.step, sample))

            self._flushes.append(lambda: forward(order.flush()))

            node.create_subscription(
                JointState, axis.topic(name), on_data, reader_qos(name), raw=True
            )

        def on_state(sample: Any) -> None:
            ns = sample.step * period
            if ns > self.sim_ns:
                self.sim_ns = ns
                if sample.step % every == 0 and self.server is not None:
                    self.server.broadcast_time(ns)
            y = controlled_output(
                axis.sensor,
                encoder_rad=sample.encoder_rad,
                scale_m=sample.scale_m,
                lead_m_per_rad=axis.lead_m_per_rad,
            )
            emit_error(sample.step, pairs.output(sample.step, y))

        def on_reference(sample: Any) -> None:
            emit_error(sample.step, pairs.reference(sample.step, sample.position_rad))

        kw = {"axis": axis.axis, "period_ns_": period}
        # The state is decoded even when nobody watches it: its stamps are
        # the simulation time of the server's clock and of /diagnostics.
        stream("state", lambda m: msgs.state_from_msg(m, **kw), on_state, always=True)
        stream("reference", lambda m: msgs.reference_from_msg(m, **kw), on_reference)
        stream("command", lambda m: msgs.command_from_msg(m, **kw), None)


def diagnostics_json(msg: Any) -> dict[str, Any]:
    """A ``diagnostic_msgs/DiagnosticArray`` as plain JSON."""
    stamp = msg.header.stamp
    return {
        "header": {
            "stamp": {"sec": stamp.sec, "nsec": stamp.nanosec},
            "frame_id": msg.header.frame_id,
        },
        "status": [
            {
                "level": s.level[0] if isinstance(s.level, bytes | bytearray) else int(s.level),
                "name": s.name,
                "message": s.message,
                "hardware_id": s.hardware_id,
                "values": [{"key": v.key, "value": v.value} for v in s.values],
            }
            for s in msg.status
        ],
    }


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.run.live``."""
    parser = argparse.ArgumentParser(
        prog="python -m servo_axis.run.live",
        description="serve a running servo_axis run to Foxglove / Lichtblick (started by the runner)",
    )
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help="TCP port on 127.0.0.1")
    parser.add_argument("--axes", required=True, help="JSON list of the axes (LiveAxis fields)")
    args = parser.parse_args(argv)
    try:
        import foxglove
    except ImportError:
        print(f"live: {INSTALL_HINT}", file=sys.stderr, flush=True)
        return 2
    axes = [LiveAxis(**a) for a in json.loads(args.axes)]
    bridge = LiveBridge(foxglove, axes)
    try:
        server = foxglove.start_server(
            name="servo_axis",
            host=HOST,
            port=args.port,
            capabilities=[foxglove.Capability.Time],
            message_backlog_size=BACKLOG_MESSAGES,
        )
    except Exception as err:  # the SDK raises its own error types
        print(f"live: cannot serve on {HOST}:{args.port}: {err}", file=sys.stderr, flush=True)
        return 2
    bridge.server = server
    try:
        return _spin(bridge, f"{READY} {url(server.port)} channels {', '.join(bridge.topics)}")
    finally:
        time.sleep(FLUSH_S)
        server.stop()


def _spin(bridge: LiveBridge, ready: str) -> int:
    """Subscribe, say ``ready``, forward until SIGINT/SIGTERM, then what still arrives.

    The runner starts the nodes once ``ready`` is printed: the subscriptions
    exist by then, so they are discovered while the nodes start. Forwarding
    goes on for at most :data:`DRAIN_S` after the signal.
    """
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from servo_axis.nodes.runtime import make_executor
    from servo_axis.stop_signals import catch_stop_signals, restore_handlers

    stop: list[int] = []
    previous = catch_stop_signals(stop)
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("servo_axis_live", enable_rosout=False, start_parameter_services=False)
    executor = make_executor()
    executor.add_node(node)
    try:
        bridge.subscribe(node)
        print(ready, flush=True)
        while not stop:
            executor.spin_once(timeout_sec=0.1)
        # The runner stops the live view after the nodes: what they sent
        # last may still be queued here (the bridge can lag behind a fast run).
        end = time.monotonic() + DRAIN_S
        while time.monotonic() < end and time.monotonic() - bridge.last_message_s < DRAIN_IDLE_S:
            executor.spin_once(timeout_sec=DRAIN_IDLE_S / 4)
        bridge.flush()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        restore_handlers(previous)
    if bridge.rejected:
        print(f"live: {bridge.rejected} messages failed validation (not forwarded)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
