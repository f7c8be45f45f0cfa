"""The two processes of the realtime floor: a bare rclpy plant and controller.

``python -m servo_axis floor`` (:mod:`servo_axis.run.floor`) starts this
module twice, ``--role controller`` and ``--role plant``, each a process of
its own. Nothing of the suite runs in them but this: what they miss is the
least any pair of rclpy nodes on this host, with this middleware, misses.

The controller echoes each ``sensor_msgs/JointState`` it takes on
``floor/state`` back on ``floor/command``. The plant publishes state ``k``
at the absolute deadline ``d_k = start + k T`` of the monotonic clock
(sleeping until :data:`~servo_axis.nodes.realtime.SPIN_NS` before it, then
spinning to it, as the plant node's clock does) and waits for its echo
until ``d_{k+1}``: an echo later than the next tick is a deadline miss, the
rule of the plant node (:func:`servo_axis.core.deadlines.misses_of`). It
writes its result, one JSON object, to ``--result``.

Both end by themselves: the plant after its ticks (or when no controller
appeared within :data:`DISCOVERY_TIMEOUT_S`), the controller after
``--seconds``, either on SIGINT or SIGTERM, and either when the process
that started it is gone. rclpy is imported in :func:`main` only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core import deadlines
from servo_axis.nodes.realtime import (
    SPIN_FIFO_NS,
    SPIN_NS,
    favour_middleware_threads,
    fifo_this_thread,
)
from servo_axis.stop_signals import catch_stop_signals

#: Seconds the plant waits for the controller to appear (exit 3 after).
DISCOVERY_TIMEOUT_S = 20.0
#: Exchanges before the measured ticks, each waited for up to :data:`WARM_UP_WAIT_S`:
#: discovery and the reliable channel settle before the first deadline counts.
WARM_UP = 300
WARM_UP_WAIT_S = 0.05
#: Exit code of a plant that found no controller.
EXIT_NO_CONTROLLER = 3
#: The topics of the pair (relative: under the processes' namespace, none).
STATE_TOPIC, COMMAND_TOPIC = "floor/state", "floor/command"


def _qos() -> Any:
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST
    )


def _executor(kind: str) -> Any:
    if kind == "events":
        from rclpy.experimental import EventsExecutor

        return EventsExecutor()
    from rclpy.executors import SingleThreadedExecutor

    return SingleThreadedExecutor()


def _percentiles(values_us: np.ndarray, qs: tuple[float, ...]) -> dict[str, float | None]:
    """``{"p50": ..., ...}`` of ``values_us`` (us, 0.1 us), None for none; with ``max``."""
    out: dict[str, float | None] = {}
    for q in qs:
        out[f"p{q:g}"] = round(float(np.percentile(values_us, q)), 1) if values_us.size else None
    out["max"] = round(float(values_us.max()), 1) if values_us.size else None
    return out


def scheduling(priority: int) -> dict[str, object]:
    """The calling thread under ``SCHED_FIFO`` at ``priority`` (0: none), the middleware's
    receive threads just below it, as a realtime node's (``thread_priority``,
    ``realtime.middleware_priority``: :class:`~servo_axis.nodes.realtime.RealtimeScheduling`)."""
    got = fifo_this_thread(priority)
    if got["policy"] == "fifo":
        receive = max(0, priority - 1)
        got["middleware_priority"] = receive
        got["middleware_threads"] = favour_middleware_threads(receive_priority=receive)
    return got


def controller(executor: str, seconds: float, priority: int, stop: list[int], parent: int) -> int:
    """Echo every state until ``seconds`` passed, a stop signal came or the parent is gone."""
    import rclpy
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    node = Node("floor_controller")
    pub = node.create_publisher(JointState, COMMAND_TOPIC, _qos())

    def echo(msg: JointState) -> None:
        out = JointState()
        out.header = msg.header
        out.position = [0.5 * msg.position[0]]
        pub.publish(out)

    node.create_subscription(JointState, STATE_TOPIC, echo, _qos())
    ex = _executor(executor)
    ex.add_node(node)
    scheduling(priority)
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and not stop and os.getppid() == parent and rclpy.ok():
            ex.spin_once(timeout_sec=0.1)
    finally:
        ex.shutdown()
        node.destroy_node()
    return 0


def plant(
    period_ns: int, ticks: int, executor: str, priority: int, stop: list[int]
) -> dict[str, Any] | None:
    """The measured ticks (:mod:`servo_axis.run.floor_pair`); None if no controller appeared.

    The realtime priority is taken after discovery and the warm-up, as a
    node takes it at its first per-sample input.
    """
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    node = Node("floor_plant")
    pub = node.create_publisher(JointState, STATE_TOPIC, _qos())
    arrived: dict[int, int] = {}
    node.create_subscription(
        JointState,
        COMMAND_TOPIC,
        lambda m: arrived.__setitem__(int(m.header.stamp.nanosec), time.monotonic_ns()),
        _qos(),
    )
    ex = _executor(executor)
    ex.add_node(node)
    try:
        deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
        while pub.get_subscription_count() == 0 or node.count_publishers(COMMAND_TOPIC) == 0:
            if time.monotonic() > deadline or stop:
                return None
            ex.spin_once(timeout_sec=0.05)
        for i in range(WARM_UP):
            tag = 999_999_999 - i  # never a measured tick's
            m = JointState()
            m.header.stamp.nanosec = tag
            m.position = [1.0]
            pub.publish(m)
            until = time.monotonic() + WARM_UP_WAIT_S
            while tag not in arrived and time.monotonic() < until:
                ex.spin_once(timeout_sec=0.001)
        arrived.clear()
        sched = scheduling(priority)
        spin_ns = SPIN_FIFO_NS if sched["policy"] == "fifo" else SPIN_NS
        start = time.monotonic_ns() + 50_000_000
        late_ns = np.full(ticks, np.nan)  # tick: sent after its deadline
        echo_ns = np.full(ticks, np.nan)  # echo after the tick's deadline (NaN: never by the next)
        trip_ns = np.full(ticks, np.nan)  # echo after the send
        done = 0
        for k in range(ticks):
            if stop:
                break
            tick = deadlines.deadline_ns(start, period_ns, k)
            pause = deadlines.sleep_s(time.monotonic_ns(), tick, spin_ns)
            if pause > 0:
                time.sleep(pause)
            while time.monotonic_ns() < tick:
                pass
            sent = time.monotonic_ns()
            late_ns[k] = sent - tick
            m = JointState()
            m.header.stamp.nanosec = k
            m.position = [float(k)]
            pub.publish(m)
            due = tick + period_ns
            while k not in arrived:
                left = due - time.monotonic_ns()
                if left <= 0:
                    break
                ex.spin_once(timeout_sec=min(left * 1e-9, 0.0005))
            if k in arrived and arrived[k] <= due:
                echo_ns[k] = arrived[k] - tick
                trip_ns[k] = arrived[k] - sent
            done = k + 1
    finally:
        ex.shutdown()
        node.destroy_node()
    misses = deadlines.misses_of(echo_ns[:done], period_ns)
    trips = trip_ns[:done][~np.isnan(trip_ns[:done])] * 1e-3
    return {
        "period_us": round(period_ns / 1000),
        "ticks": done,
        "executor": executor,
        "misses": misses,
        "miss_pct": round(100 * misses / done, 3) if done else None,
        "tick_late_us": _percentiles(late_ns[:done] * 1e-3, (50, 99)),
        "round_trip_us": _percentiles(trips, (50, 99, 99.9)),
        "scheduling": sched,
    }


def main(argv: list[str] | None = None) -> int:
    """One process of the pair (the arguments are :mod:`servo_axis.run.floor`'s to give)."""
    p = argparse.ArgumentParser(prog="python -m servo_axis.run.floor_pair")
    p.add_argument("--role", choices=("plant", "controller"), required=True)
    p.add_argument("--executor", choices=("single", "events"), default="events")
    p.add_argument("--period-ns", type=int, default=1_000_000)
    p.add_argument("--ticks", type=int, default=1000)
    p.add_argument("--priority", type=int, default=0)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--result", type=Path)
    p.add_argument("--parent", type=int, default=os.getppid())
    a = p.parse_args(argv)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop: list[int] = []
    catch_stop_signals(stop)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    try:
        if a.role == "controller":
            return controller(a.executor, a.seconds, a.priority, stop, a.parent)
        result = plant(a.period_ns, a.ticks, a.executor, a.priority, stop)
        if result is None:
            print("floor: the controller process did not appear", file=sys.stderr)
            return EXIT_NO_CONTROLLER
        if a.result is not None:
            a.result.write_text(json.dumps(result) + "\n")
        return 128 + stop[0] if stop else 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
