"""What every node process shares: QoS profiles and message types, the executor, the main() wrapper."""

from __future__ import annotations

import gc
import os
import sys
import time
from collections.abc import Callable, Sequence

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration, Infinite
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import ServoAxisError
from servo_axis.stop_signals import catch_stop_signals, hard_deadline, restore_handlers
from servo_axis.wire import topics

#: Seconds after which a publisher whose process stopped asserting its
#: liveliness (it died, or hangs) counts as gone for its subscribers: the
#: only way a lockstep node gives up waiting for it (Fast DDS asserts
#: AUTOMATIC liveliness from its own thread, so a busy Python callback does
#: not lapse it; measured: a SIGKILLed publisher is seen gone after 0.3-1 s).
LIVELINESS_LEASE_S = 1.0


def _reliable(depth: int, durability: DurabilityPolicy) -> QoSProfile:
    """Reliable keep-last with AUTOMATIC liveliness (lease :data:`LIVELINESS_LEASE_S`)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=durability,
        liveliness=LivelinessPolicy.AUTOMATIC,
        liveliness_lease_duration=Duration(seconds=LIVELINESS_LEASE_S),
    )


#: Per-sample streams: reliable, deep enough for the preview window and the
#: recorder's flow-control lag. Transient-local because a publisher that
#: counts a reader as matched does not mean that the reader has matched it
#: yet: a volatile reader that completes its side of discovery late drops
#: what was sent before, while a transient-local reader asks the writer's
#: history (``depth`` samples) for it.
STREAM_QOS = _reliable(2000, DurabilityPolicy.TRANSIENT_LOCAL)

#: A reader that joins a running stream on purpose (a restarted learning
#: unit) and wants only what comes from now on, not the writer's history.
LATE_JOIN_QOS = _reliable(STREAM_QOS.depth, DurabilityPolicy.VOLATILE)

#: Latched state (faults, recorder progress): a late subscriber gets the last one.
LATCHED_QOS = _reliable(1, DurabilityPolicy.TRANSIENT_LOCAL)

#: What a reader of a latched topic asks for: the writer's last message
#: when it joins, and then a deep queue. A depth-1 reader keeps only the
#: newest sample of all writers together, so a stranger publishing on the
#: topic replaced the recorder's one `steps_recorded: 0` before the plant
#: took it, and the plant never started (measured: every run with a junk
#: publisher already on the domain).
LATCHED_READ_QOS = _reliable(STREAM_QOS.depth, DurabilityPolicy.TRANSIENT_LOCAL)

#: What a publisher of the table offers, by the table's QoS name.
QOS: dict[str, QoSProfile] = {"stream": STREAM_QOS, "latched": LATCHED_QOS}
#: What the subscriptions ask for (a deep queue on latched topics too).
READER_QOS: dict[str, QoSProfile] = {"stream": STREAM_QOS, "latched": LATCHED_READ_QOS}
#: The message class of each type of the table.
MESSAGE_CLASSES: dict[str, type] = {
    topics.JOINT_STATE: JointState,
    topics.FLOAT64_MULTI_ARRAY: Float64MultiArray,
    topics.CLOCK: ClockMsg,
}


def topic_qos(name: str) -> QoSProfile:
    """The QoS profile of a topic of the table (its publisher's)."""
    return QOS[topics.topic(name).qos]


def reader_qos(name: str) -> QoSProfile:
    """The QoS profile a subscription to a topic of the table asks for."""
    return READER_QOS[topics.topic(name).qos]


#: Seconds of lease above which an offered liveliness lease counts as none
#: (rmw reports "infinite" as about 9.2e9 s).
_NO_LEASE_S = 1e9


def _lease_s(profile: QoSProfile) -> float:
    lease = profile.liveliness_lease_duration
    if lease.nanoseconds >= Infinite.nanoseconds:
        return float("inf")
    seconds = lease.nanoseconds / 1e9
    return float("inf") if seconds <= 0.0 or seconds >= _NO_LEASE_S else seconds


def matching_reader_qos(wanted: QoSProfile, offered: Sequence[QoSProfile]) -> QoSProfile | None:
    """The profile a reader asks for so that it matches the publishers that ``offered``.

    A subscription of the suite asks for what its own publishers offer
    (``wanted``: reliable, transient-local, liveliness lease 1 s) when at
    least one publisher on the topic offers it, and otherwise for what the
    publishers there do offer, down to rclpy's and rclcpp's defaults
    (reliable, volatile, no lease) or ``qos_profile_sensor_data`` (best
    effort): request-offered matching in DDS lets a reader ask for at most
    what a writer offers. So between the suite's own nodes nothing is weaker
    than before (history for a reader that completes discovery late, the
    1 s lease by which a dead peer is seen), and an outside node with
    default QoS is matched all the same.

    Parameters
    ----------
    wanted : QoSProfile
        The strongest profile the reader would take (the topic table's).
    offered : sequence of QoSProfile
        The profiles of the publishers on the topic (from the ROS graph).

    Returns
    -------
    QoSProfile or None
        None while there is no publisher to match (ask again later).
    """
    if not offered:
        return None
    reliable = wanted.reliability == ReliabilityPolicy.RELIABLE and any(
        p.reliability == ReliabilityPolicy.RELIABLE for p in offered
    )
    reliability = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
    durable = wanted.durability == DurabilityPolicy.TRANSIENT_LOCAL and any(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL and p.reliability == reliability
        for p in offered
    )
    durability = DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE
    # The reader's lease must be at least each matched writer's: the longest
    # one offered by the publishers this reader will match.
    matched = [
        p
        for p in offered
        if (p.reliability == ReliabilityPolicy.RELIABLE or not reliable)
        and (p.durability == DurabilityPolicy.TRANSIENT_LOCAL or not durable)
    ]
    lease = max((_lease_s(p) for p in matched), default=float("inf"))
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=wanted.depth,
        reliability=reliability,
        durability=durability,
        liveliness=LivelinessPolicy.AUTOMATIC,
    )
    if lease != float("inf"):
        profile.liveliness_lease_duration = Duration(nanoseconds=round(lease * 1e9))
    return profile


#: Seconds after SIGINT or SIGTERM after which a node process ends whatever
#: it is doing (``os._exit``): its spin loop normally ends within a callback,
#: and its end (acknowledgements, a recorder's drain and its bag's close)
#: takes at most a few seconds; the runner stops an interrupted run's
#: processes sooner (``SIGNAL_STOP_S``).
STOP_DEADLINE_S = 8.0

#: Exit code of a node that refused its configuration.
EXIT_BAD_CONFIG = 2

#: Seconds a node process gives, once its spin loop ends, for what it
#: published to be acknowledged by every reliable reader, before its writers
#: are destroyed: a sample a reader lost (a full shared-memory port) is
#: repaired only while its writer exists, and a reliable reader holds back
#: everything after the gap (suspected where a live viewer got 1,863 of 2,000
#: states). A reader that stopped reading (SIGSTOP) costs this much.
ACK_TIMEOUT_S = 1.0
#: A node that drains at its end (``drain_on_stop``: the recorder) goes on
#: taking what was sent until this many seconds pass without a message, and
#: at most :data:`DRAIN_MAX_S` (an outside node may publish for ever).
DRAIN_IDLE_S = 0.1
DRAIN_MAX_S = 1.0


def steady_clock() -> Clock:
    """Wall (steady) clock for watchdogs, whatever ``use_sim_time`` says."""
    return Clock(clock_type=ClockType.STEADY_TIME)


def make_executor(context: rclpy.context.Context | None = None) -> rclpy.executors.Executor:
    """EventsExecutor (fast), or SingleThreadedExecutor if ``SERVO_AXIS_EXECUTOR=single``.

    On ``context`` (None: the default one).
    """
    if os.environ.get("SERVO_AXIS_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor(context=context)
    from rclpy.experimental import EventsExecutor

    return EventsExecutor(context=context)


#: Seconds between two looks at ``done()`` (and at a stop a signal asked for)
#: while the executor runs callbacks.
DONE_POLL_S = 0.05


def spin_nodes(nodes: Sequence[Node], done: Callable[[], bool]) -> None:
    """Spin ``nodes`` on one executor until ``done()`` or shutdown.

    Time-bounded spins in a loop rather than ``spin``: EventsExecutor.spin()
    was seen to ignore SIGTERM in a standalone process (ROS_NOTES).
    """
    executor = make_executor()
    for node in nodes:
        executor.add_node(node)
    try:
        # Many callbacks per call into the executor, not one: a spin_once per
        # callback cost a composed run a third of its steps per second
        # (measure_frf_ball_screw: 1,321 -> 1,965 steps/s, the same payloads).
        # ``done()`` and a signal are seen within DONE_POLL_S.
        never = Future()  # the loop ends on done(), not on a future
        while rclpy.ok() and not done():
            try:
                executor.spin_until_future_complete(never, timeout_sec=DONE_POLL_S)
            except RuntimeError:
                # A signal shut the context down while the EventsExecutor was
                # handing a message to Python; that is a normal stop.
                if rclpy.ok():
                    raise
        if rclpy.ok():
            finish(executor, nodes)
    finally:
        executor.shutdown()


def finish(
    executor: rclpy.executors.Executor,
    nodes: Sequence[Node],
    *,
    ack_timeout_s: float = ACK_TIMEOUT_S,
    idle_s: float = DRAIN_IDLE_S,
    max_s: float = DRAIN_MAX_S,
) -> None:
    """End a node process's spin: what it published is acknowledged, a recorder drains.

    First every publisher of ``nodes`` waits until each reliable reader has
    acknowledged what it sent (:func:`wait_for_acks`; a topic that was not is
    logged). Then the nodes that set ``drain_on_stop`` (the recorder) spin
    alone, taking what is already on its way to them, until ``idle_s`` pass
    without their ``messages_taken`` moving (at most ``max_s``): the runner
    stops them after the other nodes
    (:func:`~servo_axis.run.processes.stop_nodes`), so what those sent last
    is written, in a composed process too.
    """
    deadline = time.monotonic() + ack_timeout_s
    for node in nodes:
        late = wait_for_acks([node], max(0.0, deadline - time.monotonic()))
        if late:
            node.get_logger().warning(
                f"not acknowledged by every reader within {ack_timeout_s:g} s: "
                f"{', '.join(late)} (a reader that stopped reading misses the last samples)"
            )
    drainers = [n for n in nodes if getattr(n, "drain_on_stop", False)]
    if not drainers:
        return
    for node in nodes:
        if node not in drainers:
            executor.remove_node(node)

    def taken() -> int:
        return sum(int(getattr(n, "messages_taken", 0)) for n in drainers)

    start = last_change = time.monotonic()
    seen = taken()
    while drainers[0].context.ok():
        now = time.monotonic()
        if now - last_change >= idle_s or now - start >= max_s:
            break
        executor.spin_once(timeout_sec=idle_s / 4)
        if taken() != seen:
            seen, last_change = taken(), time.monotonic()


def wait_for_acks(nodes: Sequence[Node], timeout_s: float) -> list[str]:
    """Wait until every reliable reader acknowledged what ``nodes`` published.

    Returns the topics of the publishers not acknowledged within
    ``timeout_s`` seconds, all publishers together.
    """
    deadline = time.monotonic() + timeout_s
    late = []
    for node in nodes:
        for publisher in list(node.publishers):
            left_ns = max(0, int((deadline - time.monotonic()) * 1e9))
            if not publisher.wait_for_all_acked(Duration(nanoseconds=left_ns)):
                late.append(publisher.topic_name)
    return late


def run_main(
    name: str,
    factories: Sequence[Callable[[], Node]],
    args: list[str] | None = None,
    done: Callable[[Sequence[Node]], bool] | None = None,
) -> int:
    """Standard main of a node process: init, build, spin, shut down.

    A node whose parameters are bad raises a :class:`ServoAxisError` in its
    constructor, before it creates any publisher; that is reported on stderr
    and the process exits with :data:`EXIT_BAD_CONFIG`. So does a parameter
    file that is missing or not YAML (checked before rcl reads it), and
    anything else rcl refuses in the ROS arguments (its ``RCLError``) or in
    the parameters while the node is made: one line on stderr, no traceback.

    SIGINT and SIGTERM end the spin loop between callbacks, and the context
    is shut down only after it: rclpy's own handler shuts the context down at
    once, so a callback under way (a stop in the middle of a run) would fail
    to publish and log a traceback.
    """
    from rclpy.exceptions import NameValidationException, ParameterException
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    from servo_axis.numerics import scipy_import

    scipy_import.install()  # ~0.1 s less start-up of a node that imports scipy
    refused = _init(args)
    if refused is not None:
        return _refuse(name, refused)
    stop_requested: list[int] = []
    previous = catch_stop_signals(stop_requested, hard_deadline(STOP_DEADLINE_S))
    nodes: list[Node] = []
    code = 0
    try:
        for factory in factories:
            try:
                nodes.append(factory())
            except (_rclpy.RCLError, ParameterException, NameValidationException) as err:
                return _refuse(name, err)
            if stop_requested:
                return code
        # Start-up made every long-lived object (modules, models, messages):
        # out of the collector's sight, so a full collection during the run
        # scans only what the run allocates (no multi-ms pause mid-run).
        gc.collect()
        gc.freeze()
        _spin_profiled(
            name, nodes, lambda: bool(stop_requested) or (done is not None and done(nodes))
        )
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ServoAxisError as err:
        print(f"{name}: {err}", file=sys.stderr, flush=True)
        code = EXIT_BAD_CONFIG
    finally:
        for node in reversed(nodes):
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
        restore_handlers(previous)
    return code


def _refuse(name: str, problem: object) -> int:
    """One line on stderr for what the node refused; :data:`EXIT_BAD_CONFIG`."""
    import re

    # rcl's messages carry C source locations (", at /project/src/...:271").
    text = re.sub(r",? at \S+:\d+", "", " ".join(str(problem).split()))
    print(f"{name}: {text}", file=sys.stderr, flush=True)
    return EXIT_BAD_CONFIG


def _init(args: list[str] | None) -> str | ServoAxisError | None:
    """rclpy initialised with ``args`` (the parameter files checked first); what it refused, or None.

    rcl logs its own line on stderr before it raises: stderr is held while it
    reads the arguments, and what it wrote is passed on only if it succeeded.
    """
    import tempfile

    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    from servo_axis.params.scenario import check_params_files

    try:
        check_params_files(sys.argv if args is None else args)
    except ServoAxisError as err:
        return err
    refused: Exception | None = None
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except _rclpy.RCLError as err:
            refused = err
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        if refused is not None:
            return f"bad ROS arguments or parameter file: {refused}"
        held.seek(0)
        os.write(2, held.read())
    return None


def _spin_profiled(name: str, nodes: Sequence[Node], done: Callable[[], bool]) -> None:
    """:func:`spin_nodes`, under cProfile into ``$SERVO_AXIS_PROFILE`` if set
    (``scripts/benchmark.py --budget``: where a step's time goes)."""
    profile_dir = os.environ.get("SERVO_AXIS_PROFILE")
    profiler = None
    if profile_dir:
        import cProfile

        profiler = cProfile.Profile()
        profiler.enable()
    try:
        spin_nodes(nodes, done)
    finally:
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(os.path.join(profile_dir or ".", f"{name}.{os.getpid()}.prof"))
