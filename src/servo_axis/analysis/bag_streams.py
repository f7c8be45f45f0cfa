"""A bag's messages per topic in the order the recorder got them, and the streams kept of them.

The pieces :func:`servo_axis.analysis.signals.read_streams` is made of, below
its rules (:class:`~servo_axis.analysis.signals.StreamRules`): the recorded
messages of each topic in arrival order (:func:`recorded_by_topic`), a topic's
table name under any namespace (:func:`table_name`), a stream's payload check
and gate (:class:`Stream`), what was kept of each (:class:`Kept`,
:class:`BagStreams`). No rclpy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from servo_axis.recording.reader import RawMessage, read_raw
from servo_axis.wire import cdr, topics
from servo_axis.wire.layouts import ArrayLayout
from servo_axis.wire.streams import StreamGate


class Kept(NamedTuple):
    """A recorded message that passed its topic's rules."""

    step: int  #: control step (cycle number of cycle_stats, value of recorder/progress)
    data: bytes  #: the CDR payload as recorded
    #: the layout's sample (StateSample, DeformationSample, EstimateData, ...),
    #: the checked values of an array topic without one, the ClockData of /clock
    msg: Any


@dataclass(frozen=True, eq=False)
class BagStreams:
    """The validated streams of a bag (:func:`read_streams`).

    Attributes
    ----------
    kept : dict
        Per recorded topic with rules (its name as recorded), the messages
        kept, in recording order: one per step.
    dropped : dict
        Per topic with rules, how many recorded messages were dropped.
    first_reason : dict
        Per topic with a dropped message, why the first one was dropped.
    counts : dict
        Messages per topic as recorded (every topic, in order of first message).
    repeated : dict
        Per topic with a message that repeats one already kept
        (:class:`Repeated`), how many: neither kept nor dropped.
    strangers : dict
        Per topic with a stranger's channel, how many messages strangers
        published (recorded, in ``counts``; neither kept nor dropped).
    """

    kept: dict[str, list[Kept]]
    dropped: dict[str, int]
    first_reason: dict[str, str]
    counts: dict[str, int]
    repeated: dict[str, int] = field(default_factory=dict)
    strangers: dict[str, int] = field(default_factory=dict)

    def by_table_name(self, name: str) -> list[Kept]:
        """The kept messages of table topic ``name`` (``state``, ``/clock``, ...), every namespace."""
        out: list[Kept] = []
        for topic, kept in self.kept.items():
            if table_name(topic) == name:
                out.extend(kept)
        return out


def table_name(topic: str) -> str | None:
    """The table name (:data:`servo_axis.wire.topics.TOPICS`) of a recorded topic, None if none.

    ``/x/state``, ``/state`` and ``state`` are ``state``; ``/x/clock`` is ``/clock``.
    """
    best: str | None = None
    for entry in topics.TOPICS:
        rel = entry.name.lstrip("/")
        if topic in (rel, "/" + rel) or topic.endswith("/" + rel):
            if best is None or len(rel) > len(best.lstrip("/")):
                best = entry.name
    return best


Check = Callable[[bytes], tuple[int, Any, Callable[[], None] | None]]


class Repeated(Exception):  # noqa: N818 - an outcome, not an error
    """A message that repeats one already kept, value for value: skipped, not junk."""


class AfterTheEnd(Exception):  # noqa: N818 - an outcome, not an error
    """A sample of a plant that owns its clock stamped after the run's last step."""


class Stream:
    """One recorded topic's rules: payload checks, then its gate (if any)."""

    def __init__(self, check: Check, gate: StreamGate | None) -> None:
        self._check = check
        self._gate = gate

    def take(self, data: bytes) -> tuple[int, Any]:
        step, msg, commit = self._check(data)
        if self._gate is not None:
            self._gate.accept(step)
        if commit is not None:
            commit()
        return step, msg


def array_values(layout: ArrayLayout[Any], data: bytes) -> list[float]:
    """The values of a recorded Float64MultiArray of ``layout``, checked by its layout."""
    msg = cdr.decode_float64_multi_array(data)
    return layout.values(msg.labels, msg.sizes, msg.data, msg.strides)


class Recorded(NamedTuple):
    type_name: str
    data: bytes
    stranger: str = ""  #: who published it, if a stranger (its channel's)


def recorded_by_topic(bag_dir: Path) -> dict[str, list[Recorded]]:
    """Every message of a bag per topic, in the order the recorder wrote them.

    Topics in order of first message (log time). Within a topic the order is
    the channel's sequence number: the recorder's arrival order, which is
    what a gate must see. The log times are no such order: the recorder logs
    a message at its stamp (simulation time), so a junk message stamped in
    the past would sort before the real one it follows.
    """
    by_topic: dict[str, list[RawMessage]] = {}
    for m in read_raw(Path(bag_dir)):  # log-time order: topics in order of first message
        by_topic.setdefault(m.topic, []).append(m)
    return {
        topic: [
            Recorded(m.type_name, m.data, m.stranger) for m in sorted(ms, key=lambda m: m.sequence)
        ]
        for topic, ms in by_topic.items()
    }
