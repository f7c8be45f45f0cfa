"""The runner's progress watcher shows only valid ``recorder/progress`` values, never crashes."""

from __future__ import annotations

import math
import time

import pytest

from servo_axis.run.progress import ProgressFilter
from servo_axis.wire.cdr import PROGRESS_LABELS

LABEL = [",".join(PROGRESS_LABELS)]


def test_filter_takes_whole_non_decreasing_values_within_the_run() -> None:
    f = ProgressFilter(total=100)
    assert f.offer(LABEL, [1], [0.0]) and f.steps == 0
    assert f.offer(LABEL, [1], [50.0]) and f.steps == 50
    assert f.offer(LABEL, [1], [50.0]) and f.steps == 50  # the same again: fine
    junk = [
        (LABEL, [1], [math.nan]),
        (LABEL, [1], [math.inf]),
        (LABEL, [1], [-math.inf]),
        (LABEL, [1], []),  # empty
        (LABEL, [2], [60.0, 70.0]),  # long
        ([], [], [60.0]),  # no layout
        (["steps"], [1], [60.0]),  # wrong label
        (LABEL, [1], [49.0]),  # past
        (LABEL, [1], [-1.0]),
        (LABEL, [1], [60.5]),  # not whole
        (LABEL, [1], [101.0]),  # beyond the run
        (LABEL, [1], [1e9]),
        (LABEL, [1], [1e308 * 10]),
    ]
    for labels, sizes, data in junk:
        assert not f.offer(labels, sizes, data), data
        assert f.steps == 50
    assert f.rejected == len(junk)
    assert f.last_reason == "data[0]: expected a finite number, got inf"
    assert f.offer(LABEL, [1], [100.0]) and f.steps == 100
    assert ProgressFilter().offer(LABEL, [1], [1e9])  # no bound given


@pytest.mark.ros
def test_watcher_ignores_a_strangers_junk(ros_env: int) -> None:
    """NaN, inf, empty, wrong labels, past and beyond-the-run values on the watched topic;
    and a stranger's well-formed value (a node not called ``recorder``), which is counted
    and never shown."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension

    from servo_axis.nodes.runtime import LATCHED_QOS
    from servo_axis.run.progress import ProgressWatcher
    from servo_axis.wire import messages as msgs

    watcher = ProgressWatcher("/x", domain_id=ros_env, steps=1000)
    context = rclpy.context.Context()
    rclpy.init(args=[], context=context, domain_id=ros_env)
    try:
        node = rclpy.create_node("recorder", namespace="/x", context=context)
        pub = node.create_publisher(Float64MultiArray, "recorder/progress", LATCHED_QOS)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)

        def raw(label: str, data: list[float]) -> Float64MultiArray:
            msg = Float64MultiArray()
            msg.layout.dim = [MultiArrayDimension(label=label, size=len(data), stride=1)]
            msg.data = data
            return msg

        def send_until(msg: Float64MultiArray, done: object, timeout_s: float = 10.0) -> None:
            end = time.monotonic() + timeout_s
            pub.publish(msg)
            while time.monotonic() < end and not done():  # type: ignore[operator]
                executor.spin_once(timeout_sec=0.0)
                watcher.spin(0.02)

        send_until(msgs.labelled_array(PROGRESS_LABELS, [200]), lambda: watcher.steps == 200)
        assert watcher.steps == 200
        junk = [
            raw("steps_recorded", [math.nan]),
            raw("steps_recorded", [math.inf]),
            raw("steps_recorded", []),
            raw("", [500.0]),
            raw("steps_recorded", [100.0]),  # past
            raw("steps_recorded", [1200.0]),  # beyond the run
            raw("steps_recorded", [1e9]),
            raw("steps_recorded", [300.5]),
        ]
        for i, msg in enumerate(junk, start=1):
            send_until(msg, lambda i=i: watcher.rejected >= i)
        assert watcher.rejected == len(junk)
        assert watcher.steps == 200
        # A stranger with a valid value: not the recorder, so never shown.
        stranger = rclpy.create_node("not_the_recorder", namespace="/x", context=context)
        executor.add_node(stranger)
        other = stranger.create_publisher(Float64MultiArray, "recorder/progress", LATCHED_QOS)
        end = time.monotonic() + 10.0
        while time.monotonic() < end and watcher.strangers == 0:
            other.publish(msgs.labelled_array(PROGRESS_LABELS, [500]))
            executor.spin_once(timeout_sec=0.0)
            watcher.spin(0.05)
        assert watcher.strangers >= 1 and watcher.steps == 200 and watcher.rejected == len(junk)
        send_until(msgs.labelled_array(PROGRESS_LABELS, [1000]), lambda: watcher.steps == 1000)
        assert watcher.steps == 1000
    finally:
        watcher.close()
        rclpy.try_shutdown(context=context)
