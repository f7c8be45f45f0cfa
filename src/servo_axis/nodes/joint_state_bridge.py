"""The outside plant for an axis ros2_control drives: ``joint_states`` in, ``state`` out.

Run beside ``python -m servo_axis run SCENARIO --external plant`` (realtime,
``state_stamps: plant_clock``), in the axis's namespace, with the scenario's
parameter file (its ``/**`` section gives ``mode``, ``state_stamps``,
``axis`` and ``lead_m_per_rad``)::

    python -m servo_axis.nodes.joint_state_bridge --ros-args -r __ns:=/x \\
        --params-file SCENARIO

It subscribes to ``joint_states_topic`` (default ``/joint_states``, what
``joint_state_broadcaster`` publishes at the root namespace) with the
sensor-data profile (best effort, keep-last 5: it matches the broadcaster's
system-default writer and any other) and maps each message by joint name to
the suite's ``state`` (:func:`servo_axis.wire.joint_states.axis_state`),
stamped with the broadcaster's own stamp. It follows the start rule of an
outside plant: nothing is published before ``command`` has a publisher, so
the first state it publishes is step 0 for every node of the run, whatever
the broadcaster sent before; and, as a plant that can count its readers
does, not before its own ``state`` writer has matched every subscription
of ``state`` it lists, the counts held :data:`~servo_axis.nodes.graph.MATCH_SETTLE_S`
(a reader this process learns of late would miss the first states). It subscribes to ``command`` (the run waits for
its plant there) and keeps the newest torque for a motor effort the
broadcaster has not (NaN). The torque reaches ros2_control through the
feedback's ``forward_commands_topic`` (one hop fewer than through here). It
ends by itself once ``command`` has had no publisher for 1 s after the start
(the run is over). Lockstep is refused: a controller manager steps on its
own clock and waits for no one.

A plain rclpy node, not a role of the run: it reads only the few keys below
and ignores the others of the scenario file.
"""

from __future__ import annotations

import math
import sys

from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import JointState

from servo_axis.core.errors import ConfigError, require_positive
from servo_axis.nodes.graph import Settle
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.schemas import SHARED
from servo_axis.wire.joint_states import BridgeStream, axis_state

#: The node's name (any would do: the run waits for its plant by topic, not by node name).
NAME = "joint_state_bridge"
#: How often the start rule and the end are checked (s, wall time).
CHECK_S = 0.01
#: With no publisher on ``command`` this long after the start, the run is over (s).
GONE_S = 1.0


class JointStateBridge(Node):
    """``joint_states`` -> ``state`` under the start rule; ``command`` held for the effort.

    Raises
    ------
    ConfigError
        ``mode`` not realtime, ``state_stamps`` not plant_clock, or
        ``lead_m_per_rad`` not > 0.
    """

    def __init__(self) -> None:
        super().__init__(NAME)
        try:
            self._configure()
        except ConfigError:
            self.destroy_node()  # refused: nothing of it stays in the graph
            raise
        self.names = [f"{self.axis}_motor", f"{self.axis}_table"]
        self.stream = BridgeStream()
        self.started = self.finished = False
        self.held_torque_Nm = 0.0
        self._matched = Settle()
        self._gone_since: Time | None = None
        # Reliable, volatile, keep-last 10: what the suite's readers take from a default publisher.
        self.pub = self.create_publisher(JointState, "state", QoSProfile(depth=10))
        self.commands = self.create_subscription(
            JointState, "command", self._on_command, QoSProfile(depth=10)
        )
        self.create_subscription(
            JointState, self.topic, self._on_joint_states, qos_profile_sensor_data
        )
        self.create_timer(CHECK_S, self._check, clock=steady_clock())

    def _configure(self) -> None:
        """The parameters, checked."""
        p = lambda name, value: self.declare_parameter(name, value).value  # noqa: E731
        mode = p("mode", SHARED["mode"].default)
        stamps = p("state_stamps", SHARED["state_stamps"].default)
        if mode != "realtime":
            raise ConfigError(
                f"mode: expected realtime, got {mode!r}: a ros2_control stack has no lockstep "
                "(its controller manager steps on its own clock); give the scenario's file "
                "(--params-file) or -p mode:=realtime"
            )
        if stamps != "plant_clock":
            raise ConfigError(
                f"state_stamps: expected plant_clock, got {stamps!r}: the states carry the "
                "broadcaster's stamps (the controller manager's now()), not k T_u"
            )
        self.axis = str(p("axis", SHARED["axis"].default))
        self.lead = require_positive(
            "lead_m_per_rad", p("lead_m_per_rad", SHARED["lead_m_per_rad"].default)
        )
        self.topic = str(p("joint_states_topic", "/joint_states"))

    def _check(self) -> None:
        commanded = self.commands.get_publisher_count() > 0
        if not self.started:
            if commanded and self._writer_matched():  # the start rule
                self.started = True
                self.get_logger().info(
                    f"command has a publisher and state {self.pub.get_subscription_count()} "
                    "matched readers: the next joint state is step 0"
                )
            return
        now = self.get_clock().now()
        if commanded:
            self._gone_since = None
        elif self._gone_since is None:
            self._gone_since = now
        elif (now - self._gone_since).nanoseconds * 1e-9 >= GONE_S:
            self.finished = True

    def _writer_matched(self) -> bool:
        """Whether the ``state`` writer has matched each reader listed, held a while.

        Measured (CI, a loaded host): the recorder's reader was listed at the
        feedback 0.5 s before it made ``command``, yet the first 5 states
        reached the feedback and not the recorder: this process had not yet
        matched it. Only the writer's side can tell.
        """
        listed = self.count_subscribers(self.pub.topic_name)
        matched = self.pub.get_subscription_count()
        if listed == 0 or matched < listed:
            self._matched.forget("state")
            return False
        return self._matched.held("state", (listed, matched))

    def _on_command(self, msg: JointState) -> None:
        if len(msg.effort) and math.isfinite(msg.effort[0]):
            self.held_torque_Nm = float(msg.effort[0])

    def _on_joint_states(self, msg: JointState) -> None:
        if not self.started:
            return
        state = axis_state(
            msg, axis=self.axis, lead_m_per_rad=self.lead, held_torque_Nm=self.held_torque_Nm
        )
        stamp = msg.header.stamp
        if not self.stream.take(stamp.sec * 1_000_000_000 + stamp.nanosec, state):
            return
        assert state is not None
        out = JointState(name=self.names, position=list(state.position))
        out.velocity, out.effort = list(state.velocity), list(state.effort)
        out.header.stamp = stamp
        self.pub.publish(out)

    def close(self) -> None:
        s = self.stream
        self.get_logger().info(
            f"states published: {s.taken}; joint states dropped: {s.out_of_order} not after "
            f"the last stamp, {s.no_value} with no motor position yet"
        )


def main(args: list[str] | None = None) -> int:
    return run_main(
        NAME,
        [JointStateBridge],
        args,
        done=lambda nodes: bool(getattr(nodes[0], "finished", False)),
    )


if __name__ == "__main__":
    sys.exit(main())
