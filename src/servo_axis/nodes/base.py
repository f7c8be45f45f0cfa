"""The base of every node: strict parameters, and the parts every role shares.

* Parameters: every key the node was given (parameter file, ``-p``,
  ``parameter_overrides``) is checked against the node's schema
  (:func:`servo_axis.params.factories.checked_values`): an unknown key, a
  wrong type, NaN/inf or a value out of range raises
  :class:`ParameterFileError` naming the full key, in the constructor,
  before any publisher exists. The given keys are read through public rclpy
  API (``automatically_declare_parameters_from_overrides``); then every key
  of the schema is declared (the rest with its default) with a read-only
  descriptor made from the schema (:mod:`servo_axis.nodes.parameters`:
  meaning, unit, range), so that ``ros2 param describe`` shows it and a
  ``ros2 param set`` while running is refused with a reason.
* Output: :meth:`ServoNode.publisher` makes a table topic's publisher with
  its type and QoS (:mod:`servo_axis.wire.topics`).
* The parts, each of its own module and testable without the others:

  - :attr:`~ServoNode.report` (:class:`~servo_axis.nodes.reporting.Reporter`):
    rejected messages, strangers, fallbacks; the report file the runner
    reads; the ``/diagnostics`` status;
  - :attr:`~ServoNode.graph` (:class:`~servo_axis.nodes.graph.GraphWatch`):
    consumers matched, the node that answers, declared producers and
    strangers, publishers in this process;
  - :attr:`~ServoNode.inputs` (:class:`~servo_axis.nodes.inputs.Inputs`):
    subscriptions made once their topic is published, with the profile that
    matches it, each message judged by its sender (a stranger's is counted,
    not applied), decoded and gated before the role sees it; whether a peer
    lives;
  - :attr:`~ServoNode.realtime`
    (:class:`~servo_axis.nodes.realtime.RealtimeScheduling`): the realtime
    priority a role asks for with :attr:`~ServoNode.realtime_below`.

* Strangers: twice a second (:data:`~servo_axis.nodes.graph.STRANGER_CHECK_S`)
  and when it closes, the node compares each topic it subscribes to with
  its declared producer; a new stranger is logged and reported.
* Diagnostics: about once a second of wall time and when it closes, a
  ``DiagnosticArray`` on ``/diagnostics`` (:mod:`servo_axis.nodes.diagnostics`):
  the report with a level, and what :meth:`ServoNode.diagnostic_values`
  adds.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher

from servo_axis.nodes.diagnostics import (
    DIAGNOSTICS_PERIOD_S,
    DIAGNOSTICS_TOPIC,
    Status,
    diagnostic_array,
)
from servo_axis.nodes.graph import STRANGER_CHECK_S, GraphWatch
from servo_axis.nodes.inputs import Inputs
from servo_axis.nodes.parameters import descriptor
from servo_axis.nodes.realtime import RealtimeScheduling, realtime_priority
from servo_axis.nodes.reporting import Reporter
from servo_axis.nodes.runtime import (  # noqa: F401  (the table's QoS and types, imported from here)
    MESSAGE_CLASSES,
    QOS,
    READER_QOS,
    reader_qos,
    steady_clock,
    topic_qos,
)
from servo_axis.params.factories import checked_values, external_roles, node_schema
from servo_axis.params.param import BUILTIN, Param
from servo_axis.params.values import SharedValues
from servo_axis.wire import topics


class ServoNode(Node):
    """A node of the suite: checked parameters in :attr:`values`, and the shared parts.

    Parameters
    ----------
    role : str
        The node's name and schema (``plant``, ``feedback``, ...).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Attributes
    ----------
    values : SharedValues
        The node's typed values (:mod:`servo_axis.params.values`; a role
        declares its own class: ``values: FeedbackValues``), checked once,
        read as attributes.
    """

    values: SharedValues

    #: In realtime mode, how far below ``thread_priority`` the role's threads
    #: run (:func:`~servo_axis.nodes.realtime.realtime_priority`); None: the
    #: default scheduler always.
    realtime_below: int | None = None

    def __init__(self, role: str, **kwargs: Any) -> None:
        super().__init__(
            role,
            automatically_declare_parameters_from_overrides=True,
            **kwargs,
        )
        given = {
            name: _plain(self.get_parameter(name).value)
            for name in self.list_parameters([], 0).names
            if name not in BUILTIN
        }
        self.values = checked_values(role, given)
        values = self.values
        self._describe_parameters(node_schema(role, given), set(given))
        report_dir = Path(values.report_dir) if values.report_dir else None
        self.report = Reporter(role, report_dir=report_dir, logger=self.get_logger())
        self.graph = GraphWatch(
            self,
            external_roles=external_roles(values),
            wait_for_producers=values.wait_for_producers,
        )
        self.inputs = Inputs(
            self, self.graph, reject=self.report.reject, stranger=self.report.stranger_message
        )
        self.realtime = RealtimeScheduling(
            realtime_priority(
                mode=values.mode,
                thread_priority=values.thread_priority,
                below=self.realtime_below,
            ),
            warn=self.get_logger().warning,
            middleware_priority=values.realtime.middleware_priority,
        )
        self.create_timer(STRANGER_CHECK_S, self._look_for_strangers, clock=steady_clock())
        # Default QoS (reliable, volatile, keep-last 10), as ROS's diagnostics tools use.
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self.publish_diagnostics, clock=steady_clock())

    def _describe_parameters(self, schema: Mapping[str, Param], given: set[str]) -> None:
        """Declare every schema key with its descriptor (read-only) and its checked value.

        The given keys were declared from the overrides without a descriptor:
        they get theirs now, with the checked value (an integer given for a
        number becomes that number). The others are declared with their
        default; an empty list, whose type rclpy cannot infer, is declared by
        its type (its value is then not set).
        """
        declared = self.values.as_dict()  # rclpy's parameters: flat dotted keys
        for name, param in schema.items():
            desc = descriptor(name, param)
            value = Parameter(name, Parameter.Type(desc.type), declared[name])
            if name in given:
                self.set_descriptor(name, desc, value.get_parameter_value())
            elif isinstance(declared[name], list) and not declared[name]:
                self.declare_parameter(name, Parameter.Type(desc.type), desc)
            else:
                self.declare_parameter(name, value.value, desc, ignore_override=True)

    def publisher(self, name: str) -> Publisher:
        """A publisher of table topic ``name`` with its type and QoS."""
        entry = topics.topic(name)
        return self.create_publisher(MESSAGE_CLASSES[entry.type_name], name, QOS[entry.qos])

    def _look_for_strangers(self) -> None:
        """Report the new strangers on the topics the node subscribes to (written once)."""
        found = self.graph.strangers(self.inputs.topics)
        for name, who, declared in found:
            self.report.stranger(name, who, declared)
        if found:
            self.report.write()

    # -- what a role adds -------------------------------------------------------------
    def diagnostic_values(self) -> list[tuple[str, Any]]:
        """The node's own state on ``/diagnostics`` (a node adds its own: step, mode, ...)."""
        return []

    def diagnostic_error(self) -> str | None:
        """An error the node is in (one line: its status is then ERROR), None if none."""
        return None

    def diagnostic_stamp_ns(self) -> int:
        """The stamp of a status: the node's clock (simulation time with ``use_sim_time``)."""
        return int(self.get_clock().now().nanoseconds)

    def realtime_counts(self) -> dict[str, Any]:
        """What the node counted of a realtime run for the summary's ``realtime`` block
        (fields of :class:`~servo_axis.analysis.summary.Realtime`; put in the report
        when it closes); none here."""
        return {}

    # -- diagnostics and the end ------------------------------------------------------
    def diagnostic_status(self) -> Status:
        """What the node's next ``/diagnostics`` status says."""
        return self.report.status(self.diagnostic_values(), self.diagnostic_error())

    def publish_diagnostics(self) -> None:
        """Publish the node's status on ``/diagnostics`` (:mod:`servo_axis.nodes.diagnostics`)."""
        self._diagnostics_pub.publish(
            diagnostic_array(
                self.diagnostic_status(),
                name=self.get_fully_qualified_name(),
                hardware_id=str(self.values.axis),
                stamp_ns=self.diagnostic_stamp_ns(),
            )
        )

    def destroy_node(self) -> None:
        """Destroy the node: first the subscriptions its inputs made (rclpy does not know them)."""
        self.inputs.destroy()
        super().destroy_node()

    def close(self) -> None:
        """Called once when the node's process ends: a last look for strangers, the report, a last status.

        The graph is looked at every :data:`~servo_axis.nodes.graph.STRANGER_CHECK_S`;
        a stranger that began publishing after the last look of a short run
        (a lockstep run of 0.2 s) would otherwise go unreported.
        """
        if self.context.ok():
            try:
                self._look_for_strangers()
            except Exception as err:  # the context may be going down
                self.get_logger().warning(f"no last look for strangers: {err}")
        counts = self.realtime_counts()
        if counts and self.values.mode != "lockstep":
            self.report.health.realtime = counts
        self.report.write()
        if self.context.ok():
            try:
                self.publish_diagnostics()
            except Exception as err:  # the context may be going down
                self.get_logger().warning(f"no last /diagnostics status: {err}")


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (rclpy gives arrays as array.array)."""
    return value.tolist() if hasattr(value, "tolist") else value
