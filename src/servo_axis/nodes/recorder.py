"""Recorder node: every topic of the run into a rosbag2-layout MCAP directory.

Subscribes to ``topics`` (with their ``types``) without deserialising
(``raw=True``) and writes the CDR bytes as they come. Publishes
``recorder/progress`` (Float64MultiArray ``[steps_recorded]``, latched): the
smallest message count over ``counted_topics``, i.e. the number of steps that
are fully on disk. The plant uses it for flow control in lockstep, so the
recorder never loses a message. A first ``[0]`` means "all subscriptions
matched, ready".

Log times are simulation times (:class:`~servo_axis.recording.timeline.SimTimeline`):
a ``JointState`` is logged at its header stamp, a ``Clock`` at its clock, a
per-sample vector that carries its step (``deformation``) at that step's
time, any other message at the simulation time seen so far on ``/clock`` and the
counted topics (junk stamps are bounded; see the timeline's docstring). The
bag's timeline and ``metadata.yaml``'s duration are then the simulated ones,
the same run after run.

With ``max_bag_size_bytes`` or ``max_bag_duration_s`` the bag is split as
``ros2 bag record --max-bag-size/--max-bag-duration`` splits it: one
directory, ``bag_0.mcap``, ``bag_1.mcap``, ... (each finished when the next
begins), all listed in ``metadata.yaml``; every reader of the suite reads it
as one file.

Every :data:`FLUSH_PERIOD_S` of wall time (a steady-clock timer) the chunk in
progress is closed and written to the file, so that a recorder that dies,
even by SIGKILL, loses at most the last 0.5 s of messages; ``python -m
servo_axis bag recover <bag>`` makes such a bag readable again. The bag is
closed (metadata.yaml written) on shutdown, SIGINT or SIGTERM, once what is
still on its way has been written: the runner stops the recorder after the
other nodes, which wait until their last samples are acknowledged, and the
recorder drains its readers until they are quiet
(:func:`~servo_axis.nodes.runtime.finish`).

Run::

    python -m servo_axis.nodes.recorder --ros-args --params-file config/<scenario>.yaml \
        -p recorder:output_dir:=<dir>
"""

from __future__ import annotations

import functools
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.event_handler import SubscriptionEventCallbacks

from servo_axis.core.errors import ConfigError, ParameterFileError, SignalError
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.runtime import LATCHED_READ_QOS, STREAM_QOS, run_main, steady_clock
from servo_axis.params.factories import run_steps
from servo_axis.params.values import RecorderValues
from servo_axis.recording.definitions import message_class as bag_message_class
from servo_axis.recording.definitions import message_definition
from servo_axis.recording.timeline import SimTimeline
from servo_axis.recording.writer import DEFAULT_QOS, LATCHED_QOS_TEXT, BagWriter
from servo_axis.wire import messages as msgs
from servo_axis.wire import topics as topics_table
from servo_axis.wire.cdr import clock_ns_from_cdr
from servo_axis.wire.streams import (
    ARRAY_STREAMS,
    STEP_STREAMS,
    EarlyCommands,
    StampOrigin,
    StreamGate,
    decode_array_stream,
    decode_step_stream,
)

#: The streams a plant that owns its clock stamps (``state_stamps: plant_clock``):
#: its states, and the commands that echo their stamps.
PLANT_CLOCK_STREAMS = ("state", "command")

#: Wall-time period (s) of the flush of the bag: half the 0.5 s a killed
#: recorder may lose, so that a tick delayed by a long callback still keeps
#: the bound.
FLUSH_PERIOD_S = 0.25

# The first field of a definition that starts with a std_msgs/Header.
_HEADER_FIRST = re.compile(r"^\s*(?:std_msgs/)?Header\s+header\b")


def stamp_reader(type_name: str) -> Callable[[bytes], int] | None:
    """The stamp (ns) reader of a message type's CDR payloads; None if unstamped.

    ``rosgraph_msgs/msg/Clock``: its ``clock``; a type whose first field is a
    ``std_msgs/Header`` (``sensor_msgs/msg/JointState``): ``header.stamp``.
    Both are read in place, without deserialising.
    """
    if type_name in ("rosgraph_msgs/msg/Clock", "rosgraph_msgs/Clock"):
        return clock_ns_from_cdr
    first = next(
        (
            line
            for line in message_definition(type_name).splitlines()
            if line.strip() and not line.lstrip().startswith("#")
        ),
        "",
    )
    return msgs.stamp_ns_from_cdr if _HEADER_FIRST.match(first) else None


def message_class(type_name: str) -> Any:
    """Python class of ``pkg/msg/Type``; ParameterFileError if there is none."""
    try:
        return bag_message_class(type_name)
    except ConfigError as err:
        raise ParameterFileError(f"parameter 'types': {err}") from err


class RecorderNode(ServoNode):
    """Recorder; see the module docstring."""

    #: At its process's end it writes what is still arriving (runtime.finish).
    drain_on_stop = True

    values: RecorderValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        values = self.values
        # One type per topic, the latched and counted ones among them, one period
        # per scheduled topic: checked with the values (factories.check_recorder_topics).
        topics, types = values.topics, values.types
        if not values.output_dir:
            raise ParameterFileError(
                "parameter 'output_dir': required (the bag directory to create)"
            )
        classes = [message_class(t) for t in types]
        self._steps = run_steps(values)
        try:
            self.writer = BagWriter(
                Path(values.output_dir),
                compression=values.compression,
                max_file_size_bytes=values.max_bag_size_bytes,
                max_file_duration_ns=round(values.max_bag_duration_s * 1e9),
            )
        except (OSError, ValueError) as err:
            raise ParameterFileError(f"parameter 'output_dir': {err}") from err

        self._finals = {
            self.resolve_topic_name(topic): every
            for topic, every in zip(values.final_topics, values.final_every_steps, strict=False)
            if topic
        }
        self._progress_pub = self.publisher("recorder/progress")
        self._counts: dict[str, int] = {}
        # Messages of the publisher that plays each topic's role (a stranger's
        # are written to the bag on a channel of their own, never counted).
        self._own_counts: dict[str, int] = {}
        self._counted: list[str] = []
        # Only the next step of a counted stream counts as recorded (a
        # stranger's message ahead or behind is written to the bag but never
        # acknowledged, so it cannot move the plant's flow control).
        self._gates: dict[str, tuple[str, StreamGate]] = {}
        self._gone: set[str] = set()
        # Streams whose writer's lease lapsed with none alive: the step then.
        # Not counted meanwhile; gone for good (a fallback) only if no writer
        # is alive again by the end of the run (see _publisher_gone).
        self._lapsed: dict[str, int] = {}
        #: Lapses after which a writer of the stream was alive again.
        self.lapses_recovered = 0
        self._period_ns = msgs.period_ns(values.control_period_s)
        self._axis = values.axis
        # A plant that owns its clock (realtime): state and command are
        # stamped by it; their steps count from the first state's stamp.
        self._origin = (
            StampOrigin(self._period_ns)
            if values.state_stamps == "plant_clock" and values.mode != "lockstep"
            else None
        )
        # Commands taken before their state (the two callbacks' order is the
        # executor's): kept until the state comes.
        self._early = EarlyCommands(self._origin) if self._origin is not None else None
        self._subs: dict[str, Any] = {}
        self._leaseless: set[str] = set()
        self._topics = list(topics)
        self._topic_names: dict[str, str] = {self.resolve_topic_name(t): t for t in topics}
        self.timeline = SimTimeline()
        for topic, type_name, cls in zip(topics, types, classes, strict=True):
            self._record(topic, type_name, cls)
        self.recorded = -1
        self.messages_taken = 0
        self._ready_timer = self.create_timer(0.01, self._check_ready, clock=steady_clock())
        self._flush_timer = self.create_timer(
            FLUSH_PERIOD_S, self.writer.flush, clock=steady_clock()
        )
        self.create_timer(0.5, self._check_gone, clock=steady_clock())
        self._closed = False

    def _record(self, topic: str, type_name: str, cls: Any) -> None:
        """Record ``topic`` (``type_name``, message class ``cls``): its bag topic, its
        count (and gate, if counted), its subscription once it is published."""
        values = self.values
        name = self.resolve_topic_name(topic)
        latched = topic in values.latched_topics
        self.writer.add_topic(
            name, type_name, qos_text=LATCHED_QOS_TEXT if latched else DEFAULT_QOS
        )
        self._counts[name] = 0
        self._own_counts[name] = 0
        if topic in values.counted_topics:
            self._counted.append(name)
            if topic not in STEP_STREAMS:
                raise ParameterFileError(
                    f"parameter 'counted_topics': {topic!r} is not a per-sample stream "
                    f"(one of {sorted(STEP_STREAMS)})"
                )
            lockstep = values.mode == "lockstep"
            window = 1 if lockstep else 100
            if self._origin is not None and topic in PLANT_CLOCK_STREAMS:
                window = self._steps  # its timer may skip; the origin refuses junk ahead
            # Realtime: a jump the wall clock makes plausible is taken (a
            # recorder that fell behind goes on; StreamGate).
            period_ns = None if lockstep else self._period_ns
            self._gates[name] = (
                topic,
                StreamGate(window=window, first=0, limit=self._steps, period_ns=period_ns),
            )
        qos = LATCHED_READ_QOS if latched else STREAM_QOS
        stamp = stamp_reader(type_name)
        if topic in ARRAY_STREAMS:
            # A vector of one step carries the step: logged at its time.
            stamp = self._array_step_ns(topic)
        # The loop's own streams move the timeline; the reference runs ahead.
        clock = stamp is clock_ns_from_cdr or topic in ("state", "command")
        events = (
            SubscriptionEventCallbacks(liveliness=self._liveliness(name))
            if name in self._gates
            else None
        )
        # Made once the topic has a publisher, with the profile that matches
        # it (an outside node's default QoS too: Inputs.when_published).
        if self._origin is not None and topic in PLANT_CLOCK_STREAMS and stamp is not None:
            stamp = self._from_origin(topic, stamp)
        callback = self._callback(name, stamp, clock=clock)
        self.inputs.when_published(
            topic, qos, functools.partial(self._subscribe_raw, topic, cls, callback, events)
        )

    def _callback(self, name: str, stamp: Callable[[bytes], int] | None, *, clock: bool) -> Any:
        writer = self.writer
        counts = self._counts
        own = self._own_counts
        log_time = self.timeline.log_time
        counted = name in self._counted
        final = name in self._finals
        topic_of = self._topic_names

        def on_message(data: bytes, from_producer: bool, who: str) -> None:
            stamp_ns = None
            if stamp is not None and from_producer:
                try:
                    stamp_ns = stamp(data)
                except SignalError:
                    pass  # a payload whose stamp cannot be read: logged at the present
            # A stranger's message is logged at the present: its stamp moves
            # no clock of the bag.
            t = log_time(stamp_ns, clock=clock and from_producer)
            writer.write(
                name,
                data,
                log_time_ns=t,
                publish_time_ns=t,
                stranger=None if from_producer else who,
            )
            counts[name] += 1
            self.messages_taken += 1
            if not from_producer:
                # Written, never counted: a stranger's well-formed message
                # with the next stamp must not take the producer's place
                # (measured: a stranger's state stamped 0 counted before the
                # plant's own, the plant refused the acknowledgement of a step
                # it had not sent, and the run never started).
                self.report.stranger_message(topic_of[name], who)
                return
            own[name] += 1
            if final:
                self._update_progress()
            if counted:
                # Only a sample its subscribers would take counts: a NaN or
                # short message stamped with the next step must not take the
                # real one's place, and nothing ahead or behind may move the
                # gate.
                topic, gate = self._gates[name]
                try:
                    if self._origin is not None and topic in PLANT_CLOCK_STREAMS:
                        self._count_plant_clock(topic, data)
                        return
                    gate.accept(self._step_of(topic, data))
                except SignalError as err:
                    self.report.reject(topic, f"{topic} recorded but not counted: {err}")
                    return
                self._update_progress()

        return on_message

    def _count_plant_clock(self, topic: str, data: bytes) -> None:
        """Count a sample of a stream stamped by the plant's clock (``state``, ``command``).

        A command whose state has not been taken yet is kept until it is
        (:class:`~servo_axis.wire.streams.EarlyCommands`): the recorder
        takes the two streams from two subscriptions, in the order its
        executor runs them, and one that fell behind takes commands before
        their states (measured: 999 of 1,000 commands refused, and no
        progress, with the recorder on a third of a core).
        """
        origin, early = self._origin, self._early
        assert origin is not None and early is not None
        stamp_ns = msgs.joint_codec(topic, axis=self._axis, period_ns_=1).decode(data).step
        if topic == "command":
            step = early.step(stamp_ns)
            if step is not None:
                self._take_plant_clock("command", step)
                self._update_progress()
            return
        step = origin.state_step(stamp_ns, time.monotonic_ns())
        self._take_plant_clock("state", step)
        matched, refused = early.state_taken(stamp_ns, step)
        for _ in range(refused):
            self.report.reject(
                "command", "command recorded but not counted: its state was never taken"
            )
        for command_step in matched:
            try:
                self._take_plant_clock("command", command_step)
            except SignalError as err:
                self.report.reject("command", f"command recorded but not counted: {err}")
        self._update_progress()

    def _take_plant_clock(self, topic: str, step: int) -> None:
        """Step ``step`` of plant-clock stream ``topic`` through its gate.

        The first sample at or past the run's last step ends the stream; a
        plant that owns its clock (a driver) goes on publishing after it.
        """
        gate = self._gates[self.resolve_topic_name(topic)][1]
        if step >= self._steps - 1 and gate.last == self._steps - 1:
            return
        gate.accept(min(step, self._steps - 1))

    def _from_origin(self, topic: str, stamp: Callable[[bytes], int]) -> Callable[[bytes], int]:
        """The log stamp of a stream stamped by the plant's clock: since the first state's."""
        origin = self._origin
        assert origin is not None

        def since_origin(data: bytes) -> int:
            ns = stamp(data)
            if origin.origin_ns is None:
                raise SignalError("no state yet")  # the first: logged at the present (0)
            return ns - origin.origin_ns

        return since_origin

    def _step_of(self, topic: str, data: bytes) -> int:
        """The step of a counted stream's sample, after the subscribers' checks."""
        return decode_step_stream(topic, data, axis=self._axis, period_ns=self._period_ns)[0]

    def _subscribe_raw(
        self, topic: str, cls: Any, callback: Any, events: Any, profile: Any
    ) -> None:
        # Every message, sorted by its publisher (Inputs.identified): the
        # producer's counted, a stranger's only written.
        self._subs[topic] = self.inputs.identified(topic, cls, callback, profile, events=events)
        if profile.liveliness_lease_duration.nanoseconds == 0:
            # Its publisher offers no lease: the graph says when it is gone.
            self._leaseless.add(topic)

    def _required(self, topic: str) -> bool:
        """Whether ``topic`` must have a publisher before the recorder reports ready.

        Every topic of a node the run started (they publish from the start);
        of an outside node's topics, the per-sample streams the flow control
        counts (an outside feedback need not publish ``fault`` before it trips).
        """
        entry = topics_table.BY_NAME.get(topic)
        if entry is None or not self.graph.is_outside(entry.producer):
            return True
        return topic in self.values.counted_topics or topic in self.values.final_topics

    def _array_step_ns(self, topic: str) -> Callable[[bytes], int]:
        period_ns = self._period_ns

        def step_ns(data: bytes) -> int:
            return decode_array_stream(topic, data)[0] * period_ns

        return step_ns

    def _check_ready(self) -> None:
        if self.values.wait_for_publishers and not all(
            self.inputs.matched(t, self._subs.get(t)) if t in self._subs else False
            for t in self._topics
            if self._required(t)
        ):
            return
        self._ready_timer.cancel()
        self.recorded = 0
        self._update_progress(force=True)

    def _update_progress(self, force: bool = False) -> None:
        if self.recorded < 0:
            return
        counted = [n for n in self._counted if n not in self._gone] or self._counted
        done = min(self._recorded_steps(n) for n in counted) if counted else 0
        for name, every in self._finals.items():
            # A step counts only once the plant's scheduled messages up to it
            # are written too: they are not on the flow control otherwise,
            # and the last of them could die with the plant's process
            # (measured with a stranger subscribed on the domain).
            done = min(done, self._own_counts[name] * every)
        if done == self.recorded and not force:
            return
        self.recorded = done
        if force or done % self.values.ack_every_steps == 0 or done >= self._steps:
            self._progress_pub.publish(msgs.labelled_array(msgs.PROGRESS_LABELS, [done]))

    def _liveliness(self, name: str) -> Any:
        def on_liveliness(info: Any) -> None:
            # Gone when a writer's lease lapses (not_alive_count_change > 0)
            # and none is alive; not when the last alive one exits cleanly
            # while a killed one's lapsed writer is still listed (a restarted
            # node at the end of the run: the recorder is stopped last).
            # Nor when the writer is in this process (a composed run): its
            # lease lapses a second after its last message, during a long
            # start-up too (measured: publisher_gone at step 0 with 2.1 s of
            # start-up), while it lives.
            lapsed = info.alive_count == 0 and info.not_alive_count_change > 0
            if lapsed and not self.graph.published_in_process(name):
                self._publisher_gone(name, lapsed=True)
            elif info.alive_count > 0:
                self._gone.discard(name)
                if self._lapsed.pop(name, None) is not None:
                    self.lapses_recovered += 1
                    self.get_logger().info(f"a writer of {name} is alive again; counted again")

        return on_liveliness

    def _check_gone(self) -> None:
        """A counted stream's publisher that offers no lease is gone when it left the graph.

        A publisher with a lease is followed by its liveliness, which a clean
        exit at the end of the run does not lapse; only the lease-less ones
        (an outside node's default profile) are looked at here.
        """
        running = 0 <= self.recorded < self._steps  # not after the end: the plant exits
        for topic in self._leaseless:
            name = self.resolve_topic_name(topic)
            if name in self._gates and running and self._subs[topic].get_publisher_count() == 0:
                self._publisher_gone(name)

    def _publisher_gone(self, name: str, *, lapsed: bool = False) -> None:
        """The producer of ``name`` is gone (``lapsed``: its last alive writer's lease lapsed).

        Either way its stream stops being counted (what it published is on
        disk), so the rest of the run is recorded. A producer gone after its
        stream's last step is the end of the run, however its writer goes:
        under load its lease can lapse while it waits for acknowledgements
        and exits (the recorder is stopped last), which is no loss.

        A lapse is reported (a fallback) only if no writer of the stream is
        alive again by the end of the run (:meth:`close`; a killed
        producer's never is): a lease is renewed by the middleware's own
        thread, which a host busy enough can hold back past the lease (1 s)
        while the producer lives (seen in a lockstep run of test_determinism
        with a CPU hog and a second test's runs beside it: ``reference`` at
        step 200, every message recorded, the bag identical to the other
        runs').
        """
        if name in self._gone or self._recorded_steps(name) >= self._steps:
            return
        self._gone.add(name)
        step = self._recorded_steps(name)
        if lapsed:
            self._lapsed[name] = step
            self.get_logger().warning(
                f"the writer of {name} let its liveliness lapse at step {step}: "
                "not counted until it is alive again"
            )
        else:
            self._report_gone(name, step)
        self._update_progress()

    def _report_gone(self, name: str, step: int, why: str = "") -> None:
        self.report.fallback(
            "publisher_gone",
            step,
            f"the publisher of {name} is gone{why}; its stream is no longer counted",
        )

    def _recorded_steps(self, name: str) -> int:
        """Steps of counted stream ``name`` written in order (the next expected step)."""
        last = self._gates[name][1].last
        return 0 if last is None else last + 1

    def diagnostic_stamp_ns(self) -> int:
        """The simulation time the recorder has seen (it does not run on ``/clock``)."""
        return self.timeline.now_ns

    def diagnostic_values(self) -> list[tuple[str, Any]]:
        return [
            ("steps_recorded", self.recorded),
            ("messages_written", sum(self._counts.values())),
            ("publishers_gone", ", ".join(sorted(self._gone)) or "none"),
            ("liveliness_lapses_recovered", self.lapses_recovered),
        ]

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written per topic."""
        return dict(self._counts)

    def close(self) -> None:
        """Report the streams whose writers lapsed and never came back; finish the bag (idempotent)."""
        if not self._closed:
            self._closed = True
            # What is still held for a publisher the graph did not name: written now.
            self.inputs.release_all()
            for name, step in sorted(self._lapsed.items()):
                if name in self._gone:
                    why = f" (its liveliness lapsed at step {step}; no writer was alive again)"
                    self._report_gone(name, step, why)
            self._lapsed.clear()
            self.writer.close()
        super().close()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.recorder``."""
    return run_main("recorder", [RecorderNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
