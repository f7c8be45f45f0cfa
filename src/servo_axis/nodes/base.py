"""The base of every node: strict parameters and one way to take messages in.

* Parameters: every key the node was given (parameter file, ``-p``,
  ``parameter_overrides``) is checked against the node's schema
  (:func:`servo_axis.params.factories.checked_values`): an unknown key, a
  wrong type, NaN/inf or a value out of range raises
  :class:`ParameterFileError` naming the full key, in the constructor,
  before any publisher exists. The given keys are read through public rclpy
  API (``automatically_declare_parameters_from_overrides``); the rest of the
  schema is declared with its default so that ``ros2 param`` would show it.
* Input: :meth:`ServoNode.subscribe` decodes and validates each message
  with a pure function of :mod:`servo_axis.wire.messages` before the
  node's handler sees it; a message that fails is dropped, counted
  (``rejected``) and logged (throttled): nothing derived from it is
  published.
* QoS and message types come from the topic table (:mod:`servo_axis.wire.topics`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import SignalError
from servo_axis.nodes.runtime import LATCHED_QOS, STREAM_QOS, Throttle
from servo_axis.params.factories import checked_values
from servo_axis.params.schema import BUILTIN
from servo_axis.wire import topics

T = TypeVar("T")

QOS: dict[str, QoSProfile] = {"stream": STREAM_QOS, "latched": LATCHED_QOS}
MESSAGE_CLASSES: dict[str, Any] = {
    topics.JOINT_STATE: JointState,
    topics.FLOAT64_MULTI_ARRAY: Float64MultiArray,
    topics.CLOCK: Clock,
}


def topic_qos(name: str) -> QoSProfile:
    """The QoS profile of a topic of the table."""
    return QOS[topics.topic(name).qos]


class ServoNode(Node):
    """A node of the suite: checked parameters in :attr:`values`, validated input.

    Parameters
    ----------
    role : str
        The node's name and schema (``plant``, ``feedback``, ...).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).
    """

    def __init__(self, role: str, **kwargs: Any) -> None:
        super().__init__(
            role,
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
            **kwargs,
        )
        given = {
            name: _plain(self.get_parameter(name).value)
            for name in self.list_parameters([], 0).names
            if name not in BUILTIN
        }
        self.values: dict[str, Any] = checked_values(role, given)
        for name, value in self.values.items():
            if name not in given and not (isinstance(value, list) and not value):
                self.declare_parameter(name, value)
        self.rejected = 0
        self._complain = Throttle()

    def publisher(self, name: str) -> Publisher:
        """A publisher of table topic ``name`` with its type and QoS."""
        entry = topics.topic(name)
        return self.create_publisher(MESSAGE_CLASSES[entry.type_name], name, QOS[entry.qos])

    def subscribe(
        self,
        name: str,
        decode: Callable[[Any], T],
        handle: Callable[[T], None],
        *,
        raw: bool = False,
    ) -> Subscription:
        """Subscribe to table topic ``name``: ``handle(decode(msg))`` for the valid ones.

        ``decode`` raises :class:`SignalError` for a message that must not be
        used (wrong length, names, NaN/inf, stamp); it is then rejected here.
        """
        entry = topics.topic(name)

        def on_message(msg: Any) -> None:
            try:
                sample = decode(msg)
            except SignalError as err:
                self.reject(f"{name} rejected: {err}")
                return
            handle(sample)

        return self.create_subscription(
            MESSAGE_CLASSES[entry.type_name], name, on_message, QOS[entry.qos], raw=raw
        )

    def reject(self, text: str) -> None:
        """Count a dropped message and log it (at most once a second)."""
        self.rejected += 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (rclpy gives arrays as array.array)."""
    return value.tolist() if hasattr(value, "tolist") else value
