"""The live view's channels, without ROS: the axes, their JSON schemas, samples in step order.

What the live process (:mod:`servo_axis.run.live`) forwards and the runner's
side (:mod:`servo_axis.run.live_view`) both need: where it listens, what it
prints once it does, what an axis is (:class:`LiveAxis`), and the pieces
that turn the streams into channels: samples handed on in step order
(:class:`InOrder`), references paired with outputs for the tracking error
(:class:`ErrorPairs`), the JSON schemas of the channels.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

#: Where the live view listens (loopback only) and its default port.
HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: What the process prints once its server listens (the runner waits for it).
READY = "live view serving"
#: How the live process starts a line the runner copies to the user's terminal
#: (a viewer refused, steps not forwarded; :class:`~servo_axis.run.live_view.LogRelay`).
TERMINAL = "live view: "
#: Seconds the live view may go on forwarding after it is told to stop, while
#: the run's last steps are still on their way (it stops sooner once every
#: axis's last state is forwarded, or when nothing arrives for DRAIN_IDLE_S).
DRAIN_MAX_S = 60.0
#: The one line shown when the optional extra is missing.
INSTALL_HINT = (
    "--live needs the optional package foxglove-sdk: install it with "
    "`.venv/bin/pip install -e '.[live]'` (or `pip install 'servo_axis[live]'`)"
)
#: Steps a reference or an output waits for its partner before it is dropped.
PAIR_WINDOW_STEPS = 20_000
#: Samples of a realtime stream that may wait for a missing earlier step
#: before the gap is given up (:class:`InOrder`): a realtime stream skips
#: steps (a late command is not answered), and a viewer must not lag for them.
HOLD_SAMPLES = 200
#: The same in lockstep, where every step comes: a step missing at the bridge
#: is the writers' history, still on its way to a reader matched late, for as
#: long as the writers keep it (their depth, ``STREAM_QOS``). A fixed 200
#: was 50 ms of a 4,000-steps/s run: a viewer once got state 0, then 5, and
#: 1,819 of 2,000 states.
HOLD_LOCKSTEP_SAMPLES = 2000


@dataclass(frozen=True)
class LiveAxis:
    """What the live view needs to know of one axis.

    Attributes
    ----------
    namespace : str
        The axis namespace (``""`` for none, ``"/x"``).
    axis : str
        The axis name (JointState names ``<axis>_motor``, ``<axis>_table``).
    control_period_s : float
        ``T_u``, s.
    sensor : str
        The feedback's controlled output: ``encoder`` or ``scale``.
    lead_m_per_rad : float
        ``R``, m/rad.
    linear : bool
        True when the table moves along a line (the error is also given in
        m, ``R (r - y)``); False for a rotary table.
    lockstep : bool
        The run's time mode is lockstep (every step comes: a gap is waited
        for, :data:`HOLD_LOCKSTEP_SAMPLES`); False: realtime.
    steps : int
        The run's steps (0: not known): the live view drains until the state
        of step ``steps - 1`` and says which steps it did not forward.
    """

    namespace: str
    axis: str
    control_period_s: float
    sensor: str
    lead_m_per_rad: float
    linear: bool
    lockstep: bool = True
    steps: int = 0

    def topic(self, name: str) -> str:
        """The resolved ROS name of the axis's topic ``name``."""
        return f"{self.namespace.rstrip('/')}/{name}"


def url(port: int) -> str:
    """The WebSocket URL of the live view on ``port``."""
    return f"ws://{HOST}:{port}"


class ErrorPairs:
    """Pairs reference positions and controlled outputs of the same step.

    Each stream comes in order of step; a pair is complete when the second
    of its two values arrives. Values older than :data:`PAIR_WINDOW_STEPS`
    behind the newest step seen are dropped, so that a value whose partner
    never comes does not stay forever.
    """

    def __init__(self, window: int = PAIR_WINDOW_STEPS) -> None:
        self._window = window
        self._refs: dict[int, float] = {}
        self._outputs: dict[int, float] = {}
        self._newest = -1

    def reference(self, step: int, position_rad: float) -> tuple[float, float] | None:
        """Offer ``r[step]``; ``(r, y)`` if ``y[step]`` was there."""
        return self._offer(step, position_rad, self._refs, self._outputs, first=False)

    def output(self, step: int, output_rad: float) -> tuple[float, float] | None:
        """Offer ``y[step]``; ``(r, y)`` if ``r[step]`` was there."""
        return self._offer(step, output_rad, self._outputs, self._refs, first=True)

    def _offer(
        self,
        step: int,
        value: float,
        mine: dict[int, float],
        other: dict[int, float],
        *,
        first: bool,
    ) -> tuple[float, float] | None:
        if step > self._newest:
            self._newest = step
            if len(mine) + len(other) > 2 * self._window:
                old = self._newest - self._window
                for table in (mine, other):
                    for k in [k for k in table if k < old]:
                        del table[k]
        partner = other.pop(step, None)
        if partner is None:
            mine[step] = value
            return None
        return (partner, value) if first else (value, partner)


def sample_schema(cls: type, title: str) -> dict[str, Any]:
    """JSON schema of a sample dataclass (its fields) plus ``timestamp`` (sec, nsec)."""
    kinds = {"int": "integer", "float": "number", "bool": "boolean"}
    properties: dict[str, Any] = {"timestamp": TIME_SCHEMA}
    for f in dataclasses.fields(cls):
        properties[f.name] = {"type": kinds.get(str(f.type), "number")}
    return {"title": title, "type": "object", "properties": properties}


TIME_SCHEMA: dict[str, Any] = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0}},
}

ERROR_FIELDS = ("step", "reference_rad", "output_rad", "error_rad")

DIAGNOSTICS_SCHEMA: dict[str, Any] = {
    "title": "diagnostic_msgs/msg/DiagnosticArray",
    "type": "object",
    "properties": {
        "header": {
            "type": "object",
            "properties": {"stamp": TIME_SCHEMA, "frame_id": {"type": "string"}},
        },
        "status": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "level": {"type": "integer"},
                    "name": {"type": "string"},
                    "message": {"type": "string"},
                    "hardware_id": {"type": "string"},
                    "values": {
                        "type": "array",
                        "items": {
                            "type": "object",
                            "properties": {
                                "key": {"type": "string"},
                                "value": {"type": "string"},
                            },
                        },
                    },
                },
            },
        },
    },
}


def error_schema(axis: LiveAxis) -> dict[str, Any]:
    """JSON schema of ``<ns>/tracking_error``."""
    properties: dict[str, Any] = {"timestamp": TIME_SCHEMA, "step": {"type": "integer"}}
    for name in ERROR_FIELDS[1:]:
        properties[name] = {"type": "number"}
    if axis.linear:
        properties["error_m"] = {"type": "number"}
    return {"title": "servo_axis tracking error r - y", "type": "object", "properties": properties}


def stamp_json(ns: int) -> dict[str, int]:
    """``{"sec", "nsec"}`` of a time in ns."""
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


class IncreasingSteps:
    """Forwards a channel's samples in increasing step only (a stranger's repeat is dropped)."""

    def __init__(self) -> None:
        self.last = -1

    def take(self, step: int) -> bool:
        if step <= self.last:
            return False
        self.last = step
        return True


class InOrder:
    """Hands a stream's samples on in increasing step, each step once.

    The bridge's reader can be matched with a writer after its first
    samples: it then gets the writer's history (transient-local) after some
    newer samples, and an increasing-only gate dropped the older ones (a
    viewer once got state 0, then 5: 15 of 2,000 states missing). The first
    sample starts the stream (a bridge may join one under way); a sample
    that comes ahead of a missing step waits for it, while at most ``hold``
    samples wait; past that the gap is given up (a realtime stream may skip
    steps). A step at or before the last one handed on is dropped (a
    stranger's repeat).

    Parameters
    ----------
    hold : int
        Samples that may wait for a missing step, >= 0.
    """

    def __init__(self, hold: int = HOLD_SAMPLES) -> None:
        self.hold = hold
        self.last = -1
        self._waiting: dict[int, Any] = {}

    def put(self, step: int, item: Any) -> list[Any]:
        """The items to hand on now, in step order, once ``item`` of ``step`` came."""
        if self.last < 0 and not self._waiting:
            self.last = step - 1  # the first sample starts the stream
        if step <= self.last or step in self._waiting:
            return []
        self._waiting[step] = item
        out = []
        while self._waiting and (self.last + 1 in self._waiting or len(self._waiting) > self.hold):
            step = self.last + 1 if self.last + 1 in self._waiting else min(self._waiting)
            out.append(self._waiting.pop(step))
            self.last = step
        return out

    def skip(self, step: int) -> None:
        """``step`` went by unused: the stream goes on after it."""
        self.last = max(self.last, step)
        for old in [k for k in self._waiting if k <= step]:
            del self._waiting[old]

    def flush(self) -> list[Any]:
        """Everything still waiting, in step order (the stream has ended)."""
        out = [self._waiting[k] for k in sorted(self._waiting)]
        if self._waiting:
            self.last = max(self._waiting)
        self._waiting.clear()
        return out


def diagnostics_json(msg: Any) -> dict[str, Any]:
    """A ``diagnostic_msgs/DiagnosticArray`` as plain JSON."""
    stamp = msg.header.stamp
    return {
        "header": {
            "stamp": {"sec": stamp.sec, "nsec": stamp.nanosec},
            "frame_id": msg.header.frame_id,
        },
        "status": [
            {
                "level": s.level[0] if isinstance(s.level, bytes | bytearray) else int(s.level),
                "name": s.name,
                "message": s.message,
                "hardware_id": s.hardware_id,
                "values": [{"key": v.key, "value": v.value} for v in s.values],
            }
            for s in msg.status
        ],
    }
