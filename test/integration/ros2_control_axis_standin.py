"""A ros2_control stack driving a rigid axis, in plain rclpy (nothing from servo_axis).

Reproduces on the wire, from the Jazzy sources:

* ``controller_manager`` (ros2_control 4.46.0): one loop at ``update_rate``
  (here 1000 Hz, so T_u = 1 ms) on absolute deadlines of the monotonic
  clock (overrun periods skipped), each cycle read, update, write; the
  hardware is active from the start. (Its loop thread runs SCHED_FIFO 50 when
  it may; this stand-in stays on the default scheduler, as the CM does when
  it may not.)
* ``joint_state_broadcaster`` (ros2_controllers 4.42.1): every cycle one
  ``sensor_msgs/JointState`` on ``joint_states`` (the CM at the root:
  ``/joint_states``), ``qos_profile_system_default``; ``name`` = the joints
  with a position, velocity or effort state interface, sorted; each of
  ``position``, ``velocity``, ``effort`` one value per name, NaN where the
  joint lacks the interface; ``header.stamp`` = the node's ``now()`` at the
  update, ``frame_id`` ``base_link``. It publishes from its first cycle,
  whoever listens.
* ``effort_controllers/JointGroupEffortController`` (ros2_controllers
  4.42.1) named ``effort_controller`` on ``joints: [x_motor]``: a
  ``std_msgs/Float64MultiArray`` reader on ``~/commands``
  (``/effort_controller/commands``), ``qos_profile_system_default``; a
  message with a non-finite value dropped; only the newest kept; in
  ``update()`` a message of another length than ``joints`` deactivates it
  (effort command 0.0, later messages ignored); no message yet: the command
  interface keeps its value (NaN: the hardware applies nothing).

The hardware (the tag): ``x_motor`` (command ``effort``; states ``position``,
``velocity``, ``effort``), ``x_table`` (state ``position`` only, so NaN in
its ``velocity`` and ``effort``). The axis is rigid, ``J w' = tau - B w``,
integrated exactly over the time since the last read with the torque held
(clipped at ``torque_limit_Nm``); the table is at ``lead * angle``.

On SIGINT it writes ``log`` (JSON): the stamps (ns) of every joint state
published, each command value the controller took (in order), whether it
was deactivated, the messages dropped, the cycles run and skipped.
"""

import json
import math
import signal
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_system_default
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray


class ControllerManager(Node):
    def __init__(self) -> None:
        super().__init__("controller_manager")
        p = {
            name: self.declare_parameter(name, default).value
            for name, default in (
                ("update_rate", 1000),
                ("inertia_kgm2", 0.01),
                ("damping_Nms_per_rad", 0.1),
                ("lead_m_per_rad", 0.00191),
                ("torque_limit_Nm", 21.45),
                ("log", ""),
            )
        }
        self.p = p
        self.angle = self.speed = 0.0
        self.command = math.nan  # x_motor/effort: NaN until the controller writes
        self.applied = 0.0  # the torque the axis holds
        self.buffer: list[float] | None = None  # the controller's newest message
        self.deactivated, self.dropped = False, 0
        self.taken: list[float] = []
        self.stamps: list[int] = []
        self.cycles = self.skipped = 0
        self.jsb = self.create_publisher(JointState, "joint_states", qos_profile_system_default)
        # The controller's node: its `~/commands` is /effort_controller/commands.
        self.controller = rclpy.create_node("effort_controller", context=self.context)
        self.controller.create_subscription(
            Float64MultiArray, "~/commands", self.on_commands, qos_profile_system_default
        )
        self.last_read = time.monotonic()

    def on_commands(self, msg: Float64MultiArray) -> None:
        if not all(math.isfinite(v) for v in msg.data):
            self.dropped += 1  # "Non-finite value received. Dropping message"
            return
        self.buffer = list(msg.data)

    def read(self) -> None:
        now = time.monotonic()
        dt, self.last_read = now - self.last_read, now
        J, B = self.p["inertia_kgm2"], self.p["damping_Nms_per_rad"]
        a, w_inf = math.exp(-B * dt / J), self.applied / B
        self.angle += w_inf * dt + (self.speed - w_inf) * (1 - a) * J / B
        self.speed = w_inf + (self.speed - w_inf) * a

    def update(self) -> None:
        # joint_state_broadcaster: the sorted joints, NaN for x_table's missing interfaces.
        msg = JointState(name=["x_motor", "x_table"])
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "base_link"
        msg.position = [self.angle, self.p["lead_m_per_rad"] * self.angle]
        msg.velocity = [self.speed, math.nan]
        msg.effort = [self.applied, math.nan]
        self.jsb.publish(msg)
        self.stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
        # effort_controller, after the broadcaster (the CM's order of controllers).
        data, self.buffer = self.buffer, None
        if self.deactivated or data is None:
            return
        if len(data) != 1:
            self.deactivated, self.command = True, 0.0  # ERROR -> on_deactivate: effort 0.0
            return
        self.command = data[0]
        self.taken.append(data[0])

    def write(self) -> None:
        if math.isfinite(self.command):
            limit = self.p["torque_limit_Nm"]
            self.applied = max(-limit, min(limit, self.command))

    def run(self, executor: SingleThreadedExecutor, stop: list[int]) -> None:
        """The CM's loop, until ``stop`` holds a signal; the subscriptions are served
        between cycles in this one thread (two Python threads would wait on each other for
        the GIL: ms of latency)."""
        period = 1.0 / self.p["update_rate"]
        deadline = time.monotonic() + period
        while not stop and rclpy.ok():
            self.read()
            self.update()
            self.write()
            self.cycles += 1
            deadline += period
            now = time.monotonic()
            if now > deadline:  # overrun: the missed periods are skipped
                missed = math.ceil((now - deadline) / period)
                self.skipped += missed
                deadline += missed * period
            while (left := deadline - time.monotonic()) > 0:
                executor.spin_once(timeout_sec=left)

    def save(self) -> None:
        if self.p["log"]:
            with open(self.p["log"], "w") as f:
                json.dump(
                    {
                        "stamps": self.stamps,
                        "taken": self.taken,
                        "deactivated": self.deactivated,
                        "dropped": self.dropped,
                        "cycles": self.cycles,
                        "skipped": self.skipped,
                    },
                    f,
                )


def main() -> None:
    # SIGINT and SIGTERM set a flag the loop looks at every cycle, and the context is
    # shut down here, once, in this thread (rclpy's own handlers shut it down from a
    # thread of theirs, and a try_shutdown() racing with that fails).
    stop: list[int] = []
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda signum, frame: stop.append(signum))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = ControllerManager()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    executor.add_node(node.controller)
    try:
        node.run(executor, stop)
    finally:
        node.save()
        executor.shutdown()
        node.controller.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
