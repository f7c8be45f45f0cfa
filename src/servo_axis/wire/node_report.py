"""What a node tells the runner about its run: rejected input, strangers, fallbacks.

Each node writes ``<report_dir>/<role>.health.json`` when something worth
reporting happens and when it closes; the runner folds the files into the
run's summary. A fallback is anything that let the run go on other than by
the lockstep protocol (a command, reference or correction that did not come
from a live peer, a flow control switched off): a run with one is not the
deterministic result of its scenario, and the runner's exit code says so.

Nothing here imports rclpy.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

#: Kinds of fallback (``Fallback.kind``).
FALLBACK_KINDS = (
    "command_timeout",  # plant: zero current, the feedback is gone
    "input_timeout",  # feedback: tripped, the feedforward (or its reference) is gone
    "learning_timeout",  # feedforward: last correction kept, the learning unit is gone
    "recorder_gone",  # plant: flow control off, the recorder is gone
    "publisher_gone",  # recorder: a counted topic's producer is gone, no longer counted
)


@dataclass(frozen=True)
class Fallback:
    """One departure from the lockstep protocol.

    Attributes
    ----------
    kind : str
        One of :data:`FALLBACK_KINDS`.
    step : int
        The control step it applies from (-1 if none).
    detail : str
        One line for a person.
    """

    kind: str
    step: int
    detail: str


@dataclass
class NodeHealth:
    """A node's report (one per node of a run).

    Attributes
    ----------
    role : str
    rejected : dict
        Messages refused per topic (invalid payload or stamp).
    strangers : dict
        Per topic, the publishers the run did not start
        (``"<namespace>/<node> <gid>"``), as the ROS graph showed them.
    stranger_messages : dict
        Per topic, the messages that came from a publisher other than the
        one playing the topic's role: never applied (the recorder writes them
        to the bag, on a channel of their own, and does not count them).
    fallbacks : list of Fallback
    realtime : dict
        A realtime run's figures of the node, as fields of
        :class:`servo_axis.analysis.summary.Realtime`: the plant's clock
        (ticks, deadline misses, lateness), the feedback's
        ``references_held``, the feedforward generator's ``late_estimates``
        and ``late_corrections``; empty otherwise.
    stepping : dict
        The plant's wall time of its steps: ``steps``, and ``first_s`` and
        ``last_s`` (``CLOCK_MONOTONIC`` seconds, the host's one clock) when
        state 0 went out and when the last step was integrated; empty
        otherwise. The runner's start-up and end are outside that span.
    """

    role: str
    rejected: dict[str, int] = field(default_factory=dict)
    strangers: dict[str, list[str]] = field(default_factory=dict)
    stranger_messages: dict[str, int] = field(default_factory=dict)
    fallbacks: list[Fallback] = field(default_factory=list)
    realtime: dict[str, Any] = field(default_factory=dict)
    stepping: dict[str, Any] = field(default_factory=dict)

    @property
    def deterministic(self) -> bool:
        """No fallback happened."""
        return not self.fallbacks

    def to_dict(self) -> dict[str, Any]:
        """As a mapping (``stranger_messages``, ``realtime`` and ``stepping`` only if they
        hold something)."""
        out = asdict(self)
        for optional in ("stranger_messages", "realtime", "stepping"):
            if not out[optional]:
                del out[optional]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NodeHealth:
        return cls(
            role=str(data["role"]),
            rejected={str(k): int(v) for k, v in data.get("rejected", {}).items()},
            strangers={str(k): [str(x) for x in v] for k, v in data.get("strangers", {}).items()},
            stranger_messages={
                str(k): int(v) for k, v in data.get("stranger_messages", {}).items()
            },
            fallbacks=[Fallback(**f) for f in data.get("fallbacks", [])],
            realtime=dict(data.get("realtime", {})),
            stepping=dict(data.get("stepping", {})),
        )


def health_path(report_dir: Path, role: str) -> Path:
    """Where ``role`` writes its report."""
    return report_dir / f"{role}.health.json"


def write_health(report_dir: Path, health: NodeHealth) -> Path:
    """Write ``health`` atomically (a reader never sees half a file)."""
    path = health_path(report_dir, health.role)
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    tmp.write_text(json.dumps(health.to_dict(), indent=1) + "\n")
    os.replace(tmp, path)
    return path


def read_health(report_dir: Path) -> dict[str, NodeHealth]:
    """Every report in ``report_dir`` by role (a missing folder: none)."""
    out: dict[str, NodeHealth] = {}
    for path in sorted(report_dir.glob("*.health.json")) if report_dir.is_dir() else []:
        health = NodeHealth.from_dict(json.loads(path.read_text()))
        out[health.role] = health
    return out
