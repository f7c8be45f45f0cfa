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
its death never stops the run (the runner's side: :mod:`servo_axis.run.live_view`;
the channels' pieces without ROS: :mod:`servo_axis.run.live_channels`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import sys
import time
from collections.abc import Callable
from typing import Any

from servo_axis.core.errors import SignalError
from servo_axis.core.feedback.output import controlled_output
from servo_axis.run.live_channels import (
    DEFAULT_PORT,
    DIAGNOSTICS_SCHEMA,
    DRAIN_MAX_S,
    HOLD_LOCKSTEP_SAMPLES,
    HOLD_SAMPLES,
    HOST,
    INSTALL_HINT,
    READY,
    TERMINAL,
    ErrorPairs,
    IncreasingSteps,
    InOrder,
    LiveAxis,
    diagnostics_json,
    error_schema,
    sample_schema,
    stamp_json,
    url,
)

#: The server's time is broadcast every this many simulated seconds.
TIME_EVERY_S = 0.01
#: Messages buffered per viewer before the oldest is dropped (the SDK's
#: default, 1024, is a quarter of a simulated second of four 1 kHz channels).
BACKLOG_MESSAGES = 16_384
#: After SIGINT/SIGTERM the live view forwards until every axis's last state
#: (step ``steps - 1``) is forwarded, for at most DRAIN_MAX_S (the runner
#: waits that long for it), or until nothing arrives for DRAIN_IDLE_S (a run
#: stopped early). A fixed 3 s once cut two viewers of a loaded run at step
#: 1,982 of 3,000, and nothing said so.
DRAIN_IDLE_S = 2.0
#: Seconds the server is given to send what it has queued before it stops.
FLUSH_S = 0.3


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
        self.flushes: list[Callable[[], None]] = []
        self.sim_ns = 0
        self.channels: dict[str, Any] = {}
        self.streams: list[_AxisStreams] = []

        def channel(topic: str, schema: dict[str, Any]) -> Any:
            ch = foxglove.Channel(
                topic,
                schema=foxglove.Schema(
                    name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
            )
            self.channels[topic] = ch
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

    def complete(self) -> bool:
        """Every axis's last step (``steps - 1``) has come on each of its streams (False: steps
        not known)."""
        return all(s.complete() for s in self.streams)

    def report(self) -> list[str]:
        """Per axis, the state steps not forwarded (lines for the terminal, none if all were)."""
        lines = []
        for s in self.streams:
            steps = s.axis.steps
            if steps <= 0 or s.forwarded_states == steps:
                continue
            lines.append(
                f"{TERMINAL}{s.axis.topic('state')}: forwarded {s.forwarded_states} of {steps} "
                f"steps, up to step {s.last_state} (not forwarded: "
                f"{steps - s.forwarded_states}; the run ended before its last step, or the "
                "view fell behind by more than its queue of "
                f"{HOLD_LOCKSTEP_SAMPLES} samples)"
            )
        return lines

    @property
    def topics(self) -> list[str]:
        """The channels' topics."""
        return list(self.channels)

    def flush(self) -> None:
        """Forward what still waits for a missing step (the run has ended)."""
        for flush in self.flushes:
            flush()

    def subscribe(self, node: Any) -> None:
        """Subscribe ``node`` to every topic the channels need."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        for axis in self.axes:
            streams = _AxisStreams(self, axis)
            streams.subscribe(node)
            self.streams.append(streams)
        try:
            from diagnostic_msgs.msg import DiagnosticArray
        except ImportError:  # not installed: the channel stays empty
            return
        diagnostics = self.channels["/diagnostics"]

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


class _AxisStreams:
    """``state``, ``reference`` and ``command`` of one axis, and its tracking error, into the channels."""

    def __init__(self, bridge: LiveBridge, axis: LiveAxis) -> None:
        from servo_axis.wire import messages as msgs

        self.bridge = bridge
        self.axis = axis
        self.period = msgs.period_ns(axis.control_period_s)
        self.every = max(1, round(TIME_EVERY_S / axis.control_period_s))
        self.pairs = ErrorPairs()
        self.error_ch = bridge.channels[axis.topic("tracking_error")]
        self.error_gate = IncreasingSteps()
        self.last_state = -1
        self.forwarded_states = 0
        # The last step that came on each stream, forwarded or not.
        self.last_seen = {"state": -1, "reference": -1, "command": -1}

    def complete(self) -> bool:
        """The run's last step has come on each of the axis's streams."""
        last = self.axis.steps - 1
        return last >= 0 and all(step >= last for step in self.last_seen.values())

    def subscribe(self, node: Any) -> None:
        """Subscribe ``node`` to the axis's three streams."""
        from servo_axis.wire import messages as msgs

        kw = {"axis": self.axis.axis, "period_ns_": self.period}
        # The state is decoded even when nobody watches it: its stamps are
        # the simulation time of the server's clock and of /diagnostics.
        self._stream(
            node, "state", lambda m: msgs.state_from_msg(m, **kw), self._on_state, always=True
        )
        self._stream(
            node, "reference", lambda m: msgs.reference_from_msg(m, **kw), self._on_reference
        )
        self._stream(node, "command", lambda m: msgs.command_from_msg(m, **kw), None)

    def _emit_error(self, step: int, pair: tuple[float, float] | None) -> None:
        if pair is None or not self.error_gate.take(step):
            return
        r, y = pair
        ns = step * self.period
        out: dict[str, Any] = {
            "timestamp": stamp_json(ns),
            "step": step,
            "reference_rad": r,
            "output_rad": y,
            "error_rad": r - y,
        }
        if self.axis.linear:
            out["error_m"] = self.axis.lead_m_per_rad * (r - y)
        self.error_ch.log(out, log_time=ns)

    def _on_state(self, sample: Any) -> None:
        self.last_state = max(self.last_state, sample.step)
        self.forwarded_states += 1
        bridge = self.bridge
        ns = sample.step * self.period
        if ns > bridge.sim_ns:
            bridge.sim_ns = ns
            if sample.step % self.every == 0 and bridge.server is not None:
                bridge.server.broadcast_time(ns)
        y = controlled_output(
            self.axis.sensor,
            encoder_rad=sample.encoder_rad,
            scale_m=sample.scale_m,
            lead_m_per_rad=self.axis.lead_m_per_rad,
        )
        self._emit_error(sample.step, self.pairs.output(sample.step, y))

    def _on_reference(self, sample: Any) -> None:
        self._emit_error(sample.step, self.pairs.reference(sample.step, sample.position_rad))

    def _stream(
        self,
        node: Any,
        name: str,
        decode: Callable[[Any], Any],
        after: Callable[[Any], None] | None,
        always: bool = False,
    ) -> None:
        """Subscribe to ``name``: its samples in step order to its channel, then to ``after``."""
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState

        from servo_axis.nodes.base import reader_qos
        from servo_axis.wire import messages as msgs

        bridge, period, error_ch = self.bridge, self.period, self.error_ch
        ch = bridge.channels[self.axis.topic(name)]
        order = InOrder(hold=HOLD_LOCKSTEP_SAMPLES if self.axis.lockstep else HOLD_SAMPLES)

        def forward(samples: list[Any]) -> None:
            for sample in samples:
                if ch.has_sinks():
                    ns = sample.step * period
                    ch.log({"timestamp": stamp_json(ns), **dataclasses.asdict(sample)}, log_time=ns)
                if after is not None:
                    after(sample)

        last_seen = self.last_seen

        def on_data(data: bytes) -> None:
            bridge.last_message_s = time.monotonic()
            needed = always or ch.has_sinks() or (after is not None and error_ch.has_sinks())
            if not needed:
                # Unwatched, it moves on all the same: a viewer that
                # subscribes later does not wait for the steps skipped.
                with contextlib.suppress(SignalError):  # junk: not forwarded anyway
                    step = msgs.stamp_ns_from_cdr(data) // period
                    order.skip(step)
                    last_seen[name] = max(last_seen[name], step)
                return
            try:
                sample = decode(deserialize_message(data, JointState))
            except SignalError:
                bridge.rejected += 1
                return
            last_seen[name] = max(last_seen[name], sample.step)
            forward(order.put(sample.step, sample))

        bridge.flushes.append(lambda: forward(order.flush()))
        node.create_subscription(
            JointState, self.axis.topic(name), on_data, reader_qos(name), raw=True
        )


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
    _say_refused_viewers(foxglove)
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


#: Why foxglove-sdk 0.30 fails a WebSocket handshake, in practice: the
#: subprotocol. It logs only "handshake failed" (and answers HTTP 400).
REFUSED_WHY = (
    "this server speaks the subprotocol foxglove.sdk.v1 (foxglove-sdk 0.30); a client that "
    "offers only the older foxglove.websocket.v1 is refused with HTTP 400: use a current "
    "Foxglove or Lichtblick, or offer both subprotocols"
)


class _RefusedViewers(logging.Handler):
    """The SDK's log records of a viewer it dropped, as a line for the user's terminal."""

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if "handshake failed" in text:
            print(f"{TERMINAL}a viewer could not connect ({text}): {REFUSED_WHY}", flush=True)
        elif record.levelno >= logging.WARNING:
            print(f"{TERMINAL}{record.name}: {text}", flush=True)


def _say_refused_viewers(foxglove: Any) -> None:
    """Route the SDK's warnings and errors (a viewer refused) to the terminal's lines."""
    logger = logging.getLogger("foxglove")
    logger.addHandler(_RefusedViewers(level=logging.WARNING))
    logger.setLevel(logging.WARNING)
    logger.propagate = False  # not also on the root logger's stderr
    with contextlib.suppress(Exception):  # an SDK without it: its log stays its own
        foxglove.set_log_level("WARNING")


def _spin(bridge: LiveBridge, ready: str) -> int:
    """Subscribe, say ``ready``, forward until SIGINT/SIGTERM, then what still arrives.

    The runner starts the nodes once ``ready`` is printed: the subscriptions
    exist by then, so they are discovered while the nodes start. Forwarding
    goes on after the signal until the run's last state is forwarded (see
    :data:`DRAIN_IDLE_S`); the steps not forwarded are then said.
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
        end = time.monotonic() + DRAIN_MAX_S
        while (
            not bridge.complete()
            and time.monotonic() < end
            and time.monotonic() - bridge.last_message_s < DRAIN_IDLE_S
        ):
            executor.spin_once(timeout_sec=0.05)
        bridge.flush()
        for line in bridge.report():
            print(line, flush=True)
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
