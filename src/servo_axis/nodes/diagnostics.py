"""A node's health on ``/diagnostics`` (``diagnostic_msgs/msg/DiagnosticArray``).

Each node publishes one ``DiagnosticStatus`` about once a second of wall
time (a steady-clock timer, off the per-sample path) and once when it
closes, on the absolute topic ``/diagnostics`` with the QoS ROS tools use
for it (reliable, volatile, keep-last 10). It is not in the topic table and
never recorded: its timing is the wall clock's, and the bag of a lockstep
run must be the same every run.

The status is built by :func:`node_status` from plain values (no rclpy):

* ``name``: the node's fully qualified name (``/x/plant``); ``hardware_id``:
  the axis;
* ``level``: ERROR on a fallback (:mod:`servo_axis.wire.node_report`) or an
  error the node states (the feedback's trip), WARN when messages were
  rejected or strangers publish on its topics, OK otherwise;
* ``message``: one line saying why;
* ``values``: the node's own state first (:meth:`ServoNode.diagnostic_values
  <servo_axis.nodes.base.ServoNode.diagnostic_values>`), then
  ``rejected`` (total) and ``rejected <topic>`` per topic, ``strangers
  <topic>``, ``stranger messages <topic>`` (messages of strangers, not
  applied), ``fallbacks`` and the last ``fallback``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from servo_axis.wire.node_report import NodeHealth

#: ``DiagnosticStatus`` levels (diagnostic_msgs: OK=0, WARN=1, ERROR=2).
OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR"}
#: Seconds of wall time between two statuses.
DIAGNOSTICS_PERIOD_S = 1.0
#: The topic (absolute, as every ROS diagnostics tool expects it).
DIAGNOSTICS_TOPIC = "/diagnostics"


@dataclass(frozen=True)
class Status:
    """What one ``DiagnosticStatus`` says.

    Attributes
    ----------
    level : int
        :data:`OK`, :data:`WARN` or :data:`ERROR`.
    message : str
        One line.
    values : tuple of (str, str)
        Key-value pairs, the values as text.
    """

    level: int
    message: str
    values: tuple[tuple[str, str], ...]

    @property
    def level_name(self) -> str:
        return LEVEL_NAMES[self.level]


def text(value: object) -> str:
    """A value as ``KeyValue.value`` text (numbers in full precision, booleans lower-case)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def node_status(
    health: NodeHealth, state: Sequence[tuple[str, Any]] = (), error: str | None = None
) -> Status:
    """The status of a node from its health report and its own state.

    Parameters
    ----------
    health : NodeHealth
        Rejected messages per topic, strangers per topic, fallbacks.
    state : sequence of (str, object)
        The node's own values (``step``, ``mode``, ``tripped``, ...), first.
    error : str or None
        An error the node is in (a trip), one line; ERROR when given.

    Returns
    -------
    Status
    """
    rejected = sum(health.rejected.values())
    strangers = sum(len(v) for v in health.strangers.values())
    values = [(str(k), text(v)) for k, v in state]
    values.append(("rejected", text(rejected)))
    values += [(f"rejected {t}", text(n)) for t, n in sorted(health.rejected.items())]
    values += [(f"strangers {t}", ", ".join(w)) for t, w in sorted(health.strangers.items())]
    values += [
        (f"stranger messages {t}", text(n)) for t, n in sorted(health.stranger_messages.items())
    ]
    values.append(("fallbacks", text(len(health.fallbacks))))
    if health.fallbacks:
        last = health.fallbacks[-1]
        values.append(("fallback", f"{last.kind} at step {last.step}: {last.detail}"))
    problems = []
    if rejected:
        per_topic = ", ".join(f"{n} {t}" for t, n in sorted(health.rejected.items()))
        problems.append(f"{rejected} messages rejected ({per_topic})")
    if strangers:
        problems.append(f"{strangers} strangers on {', '.join(sorted(health.strangers))}")
    ignored = sum(health.stranger_messages.values())
    if ignored:
        problems.append(f"{ignored} messages of strangers not applied")
    if error is not None or health.fallbacks:
        first = []
        if error is not None:
            first.append(error)
        if health.fallbacks:
            last = health.fallbacks[-1]
            first.append(f"fallback {last.kind} at step {last.step}")
        return Status(ERROR, "; ".join(first + problems), tuple(values))
    if problems:
        return Status(WARN, "; ".join(problems), tuple(values))
    return Status(OK, "running, no rejected input, no stranger, no fallback", tuple(values))


def diagnostic_array(status: Status, *, name: str, hardware_id: str, stamp_ns: int) -> Any:
    """A ``DiagnosticArray`` with one ``DiagnosticStatus`` of ``status``."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    msg = DiagnosticArray()
    msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    msg.status = [
        DiagnosticStatus(
            level=bytes([status.level]),
            name=name,
            message=status.message,
            hardware_id=hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in status.values],
        )
    ]
    return msg
