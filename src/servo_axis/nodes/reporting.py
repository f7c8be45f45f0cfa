"""A node's health: what it rejected, the strangers it saw, the fallbacks it took.

:class:`Reporter` is the one place a node records them. It keeps the
:class:`~servo_axis.wire.node_report.NodeHealth` the runner reads (written
to ``<report_dir>/<role>.health.json`` on each fallback, on new strangers
and when the node closes), logs each (a rejection at most once a second),
and sums them up as the node's ``/diagnostics`` status
(:func:`~servo_axis.nodes.diagnostics.node_status`).

Nothing here imports rclpy: the logger is anything with ``warning`` and
``error`` (a node's ``get_logger()``, a :class:`logging.Logger`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

from servo_axis.nodes.diagnostics import Status, node_status
from servo_axis.wire.node_report import Fallback, NodeHealth, write_health


class Logger(Protocol):
    def warning(self, message: str) -> Any: ...

    def error(self, message: str) -> Any: ...


class Throttle:
    """At most one log line per ``period_s`` of wall time for a repeated complaint."""

    def __init__(self, period_s: float = 1.0) -> None:
        self._period = period_s
        self._last = -1e18

    def ready(self) -> bool:
        now = time.monotonic()
        if now - self._last >= self._period:
            self._last = now
            return True
        return False


class Reporter:
    """A node's health report and its log lines.

    Parameters
    ----------
    role : str
        The node's role (the report file's name).
    report_dir : Path or None
        Where the report is written; None: nowhere (a node started by hand).
    logger : Logger
        Where the lines go.
    """

    def __init__(self, role: str, *, report_dir: Path | None, logger: Logger) -> None:
        self.health = NodeHealth(role)
        #: Messages rejected, all topics together.
        self.rejected = 0
        self._report_dir = report_dir
        self._log = logger
        self._complain = Throttle()
        self._complain_stranger = Throttle()
        #: Messages of strangers, all topics together (never applied).
        self.stranger_messages = 0

    def reject(self, topic: str, text: str) -> None:
        """Count a dropped message of ``topic`` and log ``text`` (at most once a second)."""
        self.rejected += 1
        self.health.rejected[topic] = self.health.rejected.get(topic, 0) + 1
        if self._complain.ready():
            self._log.warning(f"{text} ({self.rejected} rejected so far)")

    def stranger(self, topic: str, who: str, declared: str) -> None:
        """Record and log a publisher on ``topic`` the run did not declare (:meth:`write` after)."""
        self.health.strangers.setdefault(topic, []).append(who)
        self._log.warning(
            f"stranger publishing on {topic}: {who} (the run declared only {declared}); "
            "its messages are validated like any other"
        )

    def stranger_message(self, topic: str, who: str) -> None:
        """Count a message of ``topic`` from ``who``, a publisher that does not play the
        topic's role: not applied (logged at most once a second)."""
        self.stranger_messages += 1
        counts = self.health.stranger_messages
        counts[topic] = counts.get(topic, 0) + 1
        if self._complain_stranger.ready():
            self._log.warning(
                f"{topic} from a stranger ({who}): not applied "
                f"({self.stranger_messages} stranger messages so far)"
            )

    def fallback(self, kind: str, step: int, detail: str) -> None:
        """Record (log, report) that the node went on other than by the protocol."""
        self.health.fallbacks.append(Fallback(kind, step, detail))
        self._log.error(
            f"FALLBACK ({kind}) at step {step}: {detail}; "
            "this run is not the deterministic result of its scenario"
        )
        self.write()

    def write(self) -> None:
        """Write the report to ``report_dir`` (if set); a failure is logged, not raised."""
        if self._report_dir is None:
            return
        try:
            write_health(self._report_dir, self.health)
        except OSError as err:
            self._log.error(f"cannot write the health report: {err}")

    def status(self, values: Sequence[tuple[str, Any]] = (), error: str | None = None) -> Status:
        """The node's ``/diagnostics`` status: its own ``values`` first, an ``error`` it is in."""
        return node_status(self.health, values, error)
