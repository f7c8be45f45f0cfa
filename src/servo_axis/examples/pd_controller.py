"""A PD position controller for the servo_axis emulated axis, in plain rclpy.

It plays the `feedback` role and imports nothing from servo_axis: each `state` sample is
answered with one `command` stamped like it (lockstep waits for exactly that), effort =
motor torque (N m) = feedforward torque + Kp (r - y) + Kd (r' - y'), with r, r' and the
feedforward torque from `reference` and y, y' from `state`.

    python examples/pd_controller.py --ros-args -r __ns:=/x -p bandwidth_hz:=20.0 -p inertia_kgm2:=0.01
    python -m servo_axis.examples.pd_controller --ros-args -r __ns:=/x   # from an installed servo_axis
"""

import math
import signal

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState


class PdController(Node):
    def __init__(self) -> None:
        super().__init__("my_pd_controller")
        w = 2 * math.pi * self.declare_parameter("bandwidth_hz", 20.0).value
        inertia = self.declare_parameter("inertia_kgm2", 0.01).value
        self.kp, self.kd = inertia * w * w, 2 * 0.7 * inertia * w  # poles at w, damping 0.7
        self.states: dict[tuple[int, int], JointState] = {}
        self.references: dict[tuple[int, int], JointState] = {}
        self.pub = self.create_publisher(JointState, "command", 10)
        self.create_subscription(JointState, "state", lambda m: self.take(self.states, m), 10)
        # The reference comes ahead of the samples, in bursts: a deep queue keeps them all.
        self.create_subscription(
            JointState, "reference", lambda m: self.take(self.references, m), 1000
        )

    def take(self, store: dict[tuple[int, int], JointState], msg: JointState) -> None:
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        store[key] = msg
        if key not in self.states or key not in self.references:
            return  # answer state[k] once both it and reference[k] are in
        state, ref = self.states.pop(key), self.references.pop(key)
        error = ref.position[0] - state.position[0]  # encoder angle (rad)
        rate = ref.velocity[0] - state.velocity[0]
        command = JointState(header=state.header, name=[state.name[0]])
        command.effort = [ref.effort[0] + self.kp * error + self.kd * rate]
        self.pub.publish(command)


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
    node = PdController()
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
