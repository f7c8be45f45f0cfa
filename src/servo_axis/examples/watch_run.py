"""Watch a run without the ros2 CLI: its state, its diagnostics and a parameter's descriptor.

Plain rclpy, nothing imported from servo_axis. Start it in the run's domain, with the
run's localhost discovery and its namespace (the run's header prints all three):

    ROS_DOMAIN_ID=42 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
        python examples/watch_run.py --ros-args -r __ns:=/x
    python -m servo_axis.examples.watch_run --ros-args -r __ns:=/x   # from an installed servo_axis

Ctrl-C ends it quietly at any point, also while it still waits for the run's plant.
"""

import signal

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.srv import DescribeParameters
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

LEVELS = {b"\x00": "OK", b"\x01": "WARN", b"\x02": "ERROR", b"\x03": "STALE"}


def show_status(msg: DiagnosticArray) -> None:
    for status in msg.status:
        print(status.name, LEVELS.get(status.level, status.level), status.message, flush=True)


def main() -> None:
    # Ctrl-C sets a flag the loops below look at every 0.1 s. rclpy's own handler
    # raises KeyboardInterrupt wherever the main thread is, also inside rclpy's
    # conversion of a message, which then fails with a RuntimeError instead.
    stop: list[int] = []
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, lambda number, frame: stop.append(number))
    node = rclpy.create_node("watcher")
    try:
        node.create_subscription(
            JointState, "state", lambda m: print("state", list(m.position), flush=True), 10
        )
        node.create_subscription(DiagnosticArray, "/diagnostics", show_status, 10)
        name = node.resolve_service_name("plant/describe_parameters")
        describe = node.create_client(DescribeParameters, name)
        while not stop and not describe.wait_for_service(timeout_sec=1.0):
            print(f"waiting for {name} ...", flush=True)
        # Keys of the shared /** block, which every plant model declares: rclpy answers a
        # request that names one undeclared parameter with no descriptor at all.
        request = DescribeParameters.Request(names=["duration_s", "control_period_s"])
        future = describe.call_async(request)
        while not stop and not future.done():
            rclpy.spin_once(node, timeout_sec=0.1)
        for d in future.result().descriptors if future.done() else []:
            span = list(d.floating_point_range)
            print(d.name, "|", d.description, "|", span, "| read-only:", d.read_only, flush=True)
        while not stop:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
