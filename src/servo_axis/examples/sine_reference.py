"""A sine reference generator for the servo_axis emulated axis, in plain rclpy.

It plays the `feedforward` role and imports nothing from servo_axis. For each `state`
sample it publishes the `reference` of that sample, stamped like it: position r (motor
angle, rad), velocity r' (rad/s) and effort = the feedforward torque J r'' + D r' (N m)
of a rigid model. The feedback answers state[k] once reference[k] is in.

    python examples/sine_reference.py --ros-args -r __ns:=/x -p amplitude_rad:=5.0 -p frequency_hz:=2.0
    python -m servo_axis.examples.sine_reference --ros-args -r __ns:=/x   # from an installed servo_axis
"""

import math
import signal

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState


class SineReference(Node):
    def __init__(self) -> None:
        super().__init__("my_sine_reference")
        self.amplitude = self.declare_parameter("amplitude_rad", 5.0).value
        self.w = 2 * math.pi * self.declare_parameter("frequency_hz", 2.0).value
        self.inertia = self.declare_parameter("inertia_kgm2", 0.01).value
        self.damping = self.declare_parameter("damping_Nms_per_rad", 0.1).value
        self.pub = self.create_publisher(JointState, "reference", 10)
        self.create_subscription(JointState, "state", self.on_state, 10)

    def on_state(self, state: JointState) -> None:
        t = state.header.stamp.sec + state.header.stamp.nanosec * 1e-9
        a, w = self.amplitude, self.w
        # 1 - cos starts at rest: no step at t = 0.
        position, velocity = a * (1 - math.cos(w * t)), a * w * math.sin(w * t)
        acceleration = a * w * w * math.cos(w * t)
        ref = JointState(header=state.header, name=[state.name[0]])
        ref.position, ref.velocity = [position], [velocity]
        ref.effort = [self.inertia * acceleration + self.damping * velocity]
        self.pub.publish(ref)


def main(args: list[str] | None = None) -> None:
    # Ctrl-C (SIGINT) and SIGTERM only set a flag, which the loop reads every 0.1 s, and
    # the context is shut down once, here. rclpy's own handlers shut it down from a
    # thread of theirs while this one still uses it (RCLError "context is not valid" from
    # the executor or a constructor: seen under load), and their KeyboardInterrupt,
    # raised inside rclpy's conversion of a message, comes out as another error.
    stop: list[int] = []
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda signum, frame: stop.append(signum))
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = SineReference()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop:
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass  # rclpy.shutdown() was called (by a callback, say)
    finally:
        # The node goes before the context, here, not in the interpreter's teardown.
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
