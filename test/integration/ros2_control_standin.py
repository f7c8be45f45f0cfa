"""A ros2_control stack on the topic-based hardware, in plain rclpy (nothing from servo_axis).

Reproduces on the wire, from the Jazzy sources:

* ``joint_state_topic_hardware_interface/JointStateTopicSystem`` 1.1.0: a
  ``JointState`` command writer ``QoS(1)`` (reliable, volatile, keep-last 1)
  on ``joint_commands_topic`` (default ``/robot_joint_commands``), a
  ``SensorDataQoS`` reader (best effort, keep-last 5) on
  ``joint_states_topic`` (default ``/robot_joint_states``). ``read()``: the
  latest message only, by joint name, each finite value of a non-empty
  field into that joint's state interface (a finite value for an interface
  the joint lacks is a hardware error: nothing is written after it).
  ``write()``: ``diff`` = sum of |state - command| over the position,
  velocity and effort command interfaces; nothing is published while
  ``diff <= trigger_joint_command_threshold`` (NaN never is), else ``name``
  = every joint of the tag in tag order, ``effort`` = one value per joint
  with an effort command interface, stamped with the node's ``now()``,
  ``frame_id`` empty. Every interface starts as NaN.
* ``controller_manager`` (ros2_control 4.46.0): one loop at ``update_rate``
  on absolute deadlines of the monotonic clock (overrun periods skipped),
  each cycle read, update, write; the hardware is active from the start.
* ``effort_controllers/JointGroupEffortController`` (ros2_controllers
  4.42.1) on ``[x_motor]``: writes nothing until it is active and has a
  command; here the command is a PD on the states towards ``target_rad``
  (what a user's node would send on ``/effort_controller/commands``), the
  controller activated ``activate_after`` cycles after the first state (the
  spawner's delay). Before that the hardware publishes NaN every cycle.
  With ``pd_cycles`` > 0 the user's node stops sending after that many
  active cycles and the controller holds its last command.

The tag: ``x_motor`` (command ``effort``; states ``position``, ``velocity``,
``effort``), ``x_table`` (states ``position``, ``velocity``, ``effort``).
On SIGINT it writes ``log`` (JSON): every command published (effort, or
NaN) and when (monotonic s), when the last state came, the cycles run and
skipped.
"""

import json
import math
import signal
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

#: joint -> (command interfaces, state interfaces), in tag order.
TAG = {
    "x_motor": (("effort",), ("position", "velocity", "effort")),
    "x_table": ((), ("position", "velocity", "effort")),
}


class TopicSystem(Node):
    def __init__(self) -> None:
        super().__init__("x_axis")  # the hardware node: the tag's name, lowercased
        p = {
            name: self.declare_parameter(name, default).value
            for name, default in (
                ("joint_commands_topic", "/robot_joint_commands"),
                ("joint_states_topic", "/robot_joint_states"),
                ("trigger_joint_command_threshold", 1e-5),
                ("update_rate", 500),
                ("kp", 3.9),
                ("kd", 0.25),
                ("target_rad", 0.5),
                ("activate_after", 50),
                ("pd_cycles", 0),
                ("log", ""),
            )
        }
        self.p = p
        self.states = {f"{j}/{i}": math.nan for j, (_, s) in TAG.items() for i in s}
        self.commands = {f"{j}/{i}": math.nan for j, (c, _) in TAG.items() for i in c}
        self.latest: JointState | None = None
        self.last_state_s = 0.0
        self.error = ""
        self.first_state_cycle: int | None = None
        self.published: list[float] = []
        self.publish_s: list[float] = []
        self.cycles = self.skipped = 0
        self.pub = self.create_publisher(JointState, p["joint_commands_topic"], QoSProfile(depth=1))
        self.create_subscription(
            JointState, p["joint_states_topic"], self.on_state, qos_profile_sensor_data
        )
        self.stop = threading.Event()
        self.loop = threading.Thread(target=self.run, daemon=True)
        self.loop.start()

    def on_state(self, msg: JointState) -> None:
        self.latest = msg  # no queue, no lock: the plugin copies it as it is
        self.last_state_s = time.monotonic()

    def read(self) -> None:
        msg = self.latest
        if msg is None:
            return
        if self.first_state_cycle is None:
            self.first_state_cycle = self.cycles
        for i, joint in enumerate(msg.name):
            if joint not in TAG:
                continue
            for field in ("position", "velocity", "effort"):
                values = getattr(msg, field)
                if len(values) and len(values) <= i:
                    self.error = f"{field}: {len(values)} values for {len(msg.name)} names"
                    return
                if len(values) and math.isfinite(values[i]):
                    if field not in TAG[joint][1]:
                        self.error = f"state interface {joint}/{field} not found"
                        return
                    self.states[f"{joint}/{field}"] = values[i]

    def update(self) -> None:
        if self.first_state_cycle is None:
            return
        active = self.cycles - self.first_state_cycle - self.p["activate_after"]
        if active < 0:
            return  # not active yet: nothing written
        if 0 < self.p["pd_cycles"] <= active:
            return  # no new command: the controller holds its last one
        error = self.p["target_rad"] - self.states["x_motor/position"]
        effort = self.p["kp"] * error - self.p["kd"] * self.states["x_motor/velocity"]
        if math.isfinite(effort):
            self.commands["x_motor/effort"] = effort

    def write(self) -> None:
        diff = sum(abs(self.states[k] - self.commands[k]) for k in self.commands)
        if diff <= self.p["trigger_joint_command_threshold"]:
            return
        msg = JointState(name=list(TAG))
        msg.header.stamp = self.get_clock().now().to_msg()
        for joint, (commands, _) in TAG.items():
            for interface in commands:
                getattr(msg, interface).append(self.commands[f"{joint}/{interface}"])
        self.pub.publish(msg)
        self.published.append(msg.effort[0])
        self.publish_s.append(time.monotonic())

    def run(self) -> None:
        period = 1.0 / self.p["update_rate"]
        deadline = time.monotonic() + period
        while not self.stop.is_set() and not self.error:
            self.read()
            self.update()
            if not self.error:
                self.write()
            self.cycles += 1
            deadline += period
            now = time.monotonic()
            if now > deadline:  # overrun: the missed periods are skipped
                missed = math.ceil((now - deadline) / period)
                self.skipped += missed
                deadline += missed * period
            time.sleep(max(0.0, deadline - time.monotonic()))

    def save(self) -> None:
        self.stop.set()
        self.loop.join(timeout=2.0)
        if self.p["log"]:
            with open(self.p["log"], "w") as f:
                json.dump(
                    {
                        "published": [None if math.isnan(v) else v for v in self.published],
                        "publish_s": self.publish_s,
                        "last_state_s": self.last_state_s,
                        "cycles": self.cycles,
                        "skipped": self.skipped,
                        "error": self.error,
                    },
                    f,
                )


def main() -> None:
    # SIGINT (Ctrl-C) and SIGTERM set a flag the loop looks at every 0.1 s, and the
    # context is shut down here, once, in this thread. rclpy's own handlers shut it down
    # from a thread of theirs: a try_shutdown() here racing with that fails with
    # "rcl_shutdown already called" (seen under load), and their KeyboardInterrupt can
    # land anywhere, also in the middle of a callback.
    stop: list[int] = []
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda signum, frame: stop.append(signum))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = TopicSystem()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.save()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
