"""How a node process ends (``nodes.runtime.finish``): acknowledged, then drained.

A producer's last samples must reach a recorder that is stopped after it:
the producer waits until every reliable reader has acknowledged them, and a
node that drains (``drain_on_stop``) takes what is on its way before its
process ends. A reader in another process that stopped reading bounds the
wait instead of blocking it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from rclpy.context import Context
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from host_load import RunQueueWait, said
from servo_axis.nodes.runtime import STREAM_QOS, finish, make_executor, wait_for_acks

pytestmark = pytest.mark.ros

TOPIC = "/finish_probe"


class Sink(Node):
    """A node that drains at its end, counting what it takes."""

    drain_on_stop = True

    def __init__(self, context: Context) -> None:
        super().__init__("sink", context=context)
        self.messages_taken = 0
        self.steps: list[int] = []
        self.create_subscription(Float64MultiArray, TOPIC, self._take, STREAM_QOS)

    def _take(self, msg: Float64MultiArray) -> None:
        self.messages_taken += 1
        self.steps.append(int(msg.data[0]))


def wait_matched(publisher, count: int, timeout_s: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while publisher.get_subscription_count() < count:
        assert time.monotonic() < deadline, f"{count} subscriber(s) never matched"
        time.sleep(0.01)


@contextmanager
def published_unspun(context: Context, reader: Node, count: int) -> Iterator[tuple[Any, Node, Any]]:
    """A producer beside ``reader`` on one executor, ``count`` samples sent, nothing spun.

    Yields ``(executor, producer, publisher)``; the nodes are destroyed after.
    """
    producer = Node("producer", context=context)
    executor = make_executor(context)
    executor.add_node(producer)
    executor.add_node(reader)
    try:
        pub = producer.create_publisher(Float64MultiArray, TOPIC, STREAM_QOS)
        wait_matched(pub, 1)
        for step in range(count):
            pub.publish(Float64MultiArray(data=[float(step)]))
        yield executor, producer, pub
    finally:
        executor.shutdown()
        reader.destroy_node()
        producer.destroy_node()


@pytest.mark.realtime
def test_finish_writes_what_was_sent_before_the_stop_and_nothing_is_spun_twice(
    context: Context,
) -> None:
    sink = Sink(context)
    with published_unspun(context, sink, 500) as (executor, producer, pub):
        # Nothing was spun: the samples wait in the sink's reader.
        assert sink.messages_taken == 0
        started = time.monotonic()
        finish(executor, [producer, sink], idle_s=0.1, max_s=30.0)
        took = time.monotonic() - started
        assert sink.steps == list(range(500))
        assert pub.wait_for_all_acked(_duration(0.0))
        # It ends once idle_s passed without a message, not at max_s (an
        # ordering, not a speed: 500 samples take what the host needs).
        assert took < 30.0, took


def test_finish_without_a_draining_node_only_waits_for_the_acknowledgements(
    context: Context,
) -> None:
    reader = Node("reader", context=context)
    taken: list[int] = []
    reader.create_subscription(Float64MultiArray, TOPIC, lambda m: taken.append(1), STREAM_QOS)
    with published_unspun(context, reader, 50) as (executor, producer, pub):
        finish(executor, [producer, reader], idle_s=0.1, max_s=5.0)
        # Acknowledged (in the reader's history) but not taken: no node drains.
        assert pub.wait_for_all_acked(_duration(0.0))
        assert taken == []


# A reliable reader in a process of its own, which is then stopped (SIGSTOP).
READER = f"""
import sys, rclpy
from std_msgs.msg import Float64MultiArray
from servo_axis.nodes.runtime import STREAM_QOS
rclpy.init()
node = rclpy.create_node("stopped_reader")
node.create_subscription(Float64MultiArray, "{TOPIC}", lambda m: None, STREAM_QOS)
print("ready", flush=True)
rclpy.spin(node)
"""


@pytest.mark.realtime
def test_a_reader_that_stopped_reading_bounds_the_wait_and_is_named(context: Context) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-c", READER], stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    producer = Node("producer", context=context)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
        pub = producer.create_publisher(Float64MultiArray, TOPIC, STREAM_QOS)
        wait_matched(pub, 1)
        # Matched on our side does not mean the reader matched us: wait for
        # its first acknowledgement before it is stopped.
        pub.publish(Float64MultiArray(data=[0.0]))
        assert wait_for_acks([producer], 10.0) == []
        os.kill(proc.pid, signal.SIGSTOP)
        for step in range(1, 200):
            pub.publish(Float64MultiArray(data=[float(step)] * 100))
        started = time.monotonic()
        host = RunQueueWait()
        late = wait_for_acks([producer], 0.5)
        took, wait = time.monotonic() - started, host.seconds()
        assert late == [TOPIC]
        # The wait is bounded by its timeout (+ what a busy host withheld).
        assert 0.45 <= took < 2.0 + wait, said(took, 2.0, wait)
        os.kill(proc.pid, signal.SIGCONT)
        # Once it reads again, what it missed is repaired and acknowledged.
        assert wait_for_acks([producer], 10.0) == []
    finally:
        os.kill(proc.pid, signal.SIGCONT)
        proc.send_signal(signal.SIGINT)  # a clean exit removes its shared memory
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        producer.destroy_node()


def _duration(seconds: float):  # type: ignore[no-untyped-def]
    from rclpy.duration import Duration

    return Duration(nanoseconds=int(seconds * 1e9))
