"""A rigid servo axis in plain rclpy: the `plant` role of a servo_axis run, `state` out only.

It imports nothing from servo_axis and uses the default QoS. Motor and table are one rigid
body, J w' = tau - B w, integrated exactly over each sample with tau held (zero-order hold);
tau = the commanded motor torque (N m), clipped at torque_limit_Nm. It publishes state[0]
once `command` has a publisher (the run's one start rule), then answers each command[k]
with state[k + 1], stamped k T_u, until `steps` states are out. With realtime:=true it
steps on its own timer instead, stamps each state with its own clock and applies the newest
command received (a drive's set-point).

    python examples/rigid_axis.py --ros-args -r __ns:=/x -p inertia_kgm2:=0.01 -p steps:=2000
    python -m servo_axis.examples.rigid_axis --ros-args -r __ns:=/x   # from an installed servo_axis
"""

import math
import signal

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time
from sensor_msgs.msg import JointState


class RigidAxis(Node):
    def __init__(self) -> None:
        super().__init__("my_axis")
        p = lambda name, value: self.declare_parameter(name, value).value  # noqa: E731
        self.J, self.B = p("inertia_kgm2", 0.01), p("damping_Nms_per_rad", 0.1)
        self.T, self.lead = p("control_period_s", 0.001), p("lead_m_per_rad", 0.00191)
        self.limit, self.steps = p("torque_limit_Nm", 21.45), p("steps", 2000)
        self.realtime, axis = p("realtime", False), p("axis", "x")
        self.names = [f"{axis}_motor", f"{axis}_table"]
        self.k, self.angle, self.speed, self.torque = 0, 0.0, 0.0, 0.0
        self.pub = self.create_publisher(JointState, "state", 10)
        self.sub = self.create_subscription(JointState, "command", self.on_command, 10)
        self.start = self.create_timer(0.01, self.start_once_commanded)

    def start_once_commanded(self) -> None:
        if self.sub.get_publisher_count() > 0:  # the start rule: `command` has a publisher
            self.start.cancel()
            self.publish(self.get_clock().now() if self.realtime else None)
            if self.realtime:
                self.create_timer(self.T, self.tick)

    def on_command(self, msg: JointState) -> None:
        torque = max(-self.limit, min(self.limit, msg.effort[0]))
        if self.realtime:
            self.torque = torque  # the newest command, whatever its stamp
        elif (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec) == self.k * round(
            self.T * 1e9
        ):
            self.torque = torque  # lockstep: command[k] answers state[k]
            self.tick()

    def tick(self) -> None:
        if self.k + 1 >= self.steps:
            return
        dt, self.last = self.T, self.get_clock().now()  # realtime: the time since the last state
        if self.realtime:
            dt = (self.last - self.stamp).nanoseconds * 1e-9
        a, w_inf = math.exp(-self.B * dt / self.J), self.torque / self.B
        self.angle += w_inf * dt + (self.speed - w_inf) * (1 - a) * self.J / self.B
        self.speed = w_inf + (self.speed - w_inf) * a
        self.k += 1
        self.publish(self.last if self.realtime else None)

    def publish(self, stamp: Time | None) -> None:
        msg = JointState(name=self.names, position=[self.angle, self.lead * self.angle])
        msg.velocity, msg.effort = [self.speed, self.lead * self.speed], [self.torque, 0.0]
        ns = self.k * round(self.T * 1e9)
        msg.header.stamp.sec, msg.header.stamp.nanosec = ns // 10**9, ns % 10**9
        if stamp is not None:
            self.stamp, msg.header.stamp = stamp, stamp.to_msg()
        self.pub.publish(msg)


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
    node = RigidAxis()
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
