"""Progress of a run: the runner's own rclpy node on ``recorder/progress`` and a progress line.

The watcher joins the run's ROS domain with its discovery settings without
changing the caller's environment for good: the domain goes to
``rclpy.init(domain_id=...)``, and the variables rcl and Fast DDS read when a
context and its participant are made are set only while the watcher's
context and node are created (:func:`temporary_environ`), then put back.

What the watcher shows is validated (:class:`ProgressFilter`): a
``recorder/progress`` message must be labelled ``steps_recorded`` and hold
one finite whole number of steps, not less than the last one taken and not
more than the run's steps; anything else (NaN, inf, a wrong layout, a value
from the past or beyond the run) is dropped and counted, never shown and
never raised. Only the recorder's messages are taken: each comes with its
publisher's GID (:class:`~servo_axis.nodes.identified.IdentifiedSubscription`),
and a publisher that is not the run's recorder node (``recorder`` in the
axis namespace, as the ROS graph names it) is a stranger, whose messages
are counted in :attr:`ProgressWatcher.strangers` and never shown: a
stranger's well-formed ``steps_recorded`` equal to the run's steps would
otherwise end a run with an outside plant.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, TextIO

from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import PROGRESS_LABELS, check_labelled_values


@contextmanager
def temporary_environ(values: Mapping[str, str]) -> Iterator[None]:
    """Set ``values`` in ``os.environ`` for the ``with`` block only.

    Afterwards every variable has its previous value again, and those that
    were unset are removed.
    """
    previous = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in previous.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


class ProgressFilter:
    """The values of ``recorder/progress`` that move the shown progress.

    Parameters
    ----------
    total : int or None
        The run's steps (a value beyond them is refused); None: no bound.

    Attributes
    ----------
    steps : int
        The last value taken (-1 before the first).
    rejected : int
        Messages refused so far.
    last_reason : str or None
        Why the last refused message was refused.
    """

    def __init__(self, total: int | None = None) -> None:
        self.total = total
        self.steps = -1
        self.rejected = 0
        self.last_reason: str | None = None

    def check(
        self, dim_labels: Sequence[str], dim_sizes: Sequence[int], data: Sequence[float]
    ) -> int:
        """The steps a message says are recorded; :class:`SignalError` if it must not be shown."""
        (value,) = check_labelled_values(dim_labels, dim_sizes, data, PROGRESS_LABELS)
        if not value.is_integer() or value < 0:
            raise SignalError(f"steps_recorded: expected a whole number >= 0, got {value!r}")
        steps = int(value)
        if self.total is not None and steps > self.total:
            raise SignalError(f"steps_recorded: {steps} is beyond the run's {self.total} steps")
        if steps < self.steps:
            raise SignalError(f"steps_recorded: {steps} after {self.steps} (it never decreases)")
        return steps

    def offer(
        self, dim_labels: Sequence[str], dim_sizes: Sequence[int], data: Sequence[float]
    ) -> bool:
        """Take a message's value if it passes :meth:`check`, else count it; True if taken."""
        try:
            steps = self.check(dim_labels, dim_sizes, data)
        except SignalError as err:
            self.rejected += 1
            self.last_reason = str(err)
            return False
        self.steps = steps
        return True


class ProgressWatcher:
    """Follows ``recorder/progress`` from the runner (an rclpy node of its own).

    Parameters
    ----------
    namespace : str
        The axis namespace (``"/"`` for none).
    domain_id : int or None
        The run's ROS domain; None: ``ROS_DOMAIN_ID`` of the environment.
    environ : mapping or None
        Discovery settings (``ROS_AUTOMATIC_DISCOVERY_RANGE``,
        ``FASTDDS_BUILTIN_TRANSPORTS``, ``FASTRTPS_DEFAULT_PROFILES_FILE``,
        ``ROS_LOG_DIR``) in force while the context and the node are created;
        ``os.environ`` is as before once the watcher exists. ``ROS_LOG_DIR``
        is only used when the caller has none (rclpy's logging is set up
        once per process).
    steps : int or None
        The run's steps: a progress beyond them is refused (None: no bound).

    Attributes
    ----------
    steps : int
        Steps recorded, as the last valid message said (-1 before the first).
    rejected : int
        ``recorder/progress`` messages refused (:class:`ProgressFilter`).
    """

    def __init__(
        self,
        namespace: str,
        *,
        domain_id: int | None = None,
        environ: Mapping[str, str] | None = None,
        steps: int | None = None,
    ) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import Float64MultiArray

        from servo_axis.nodes.base import reader_qos

        settings = dict(environ or {})
        if "ROS_LOG_DIR" in os.environ:
            settings.pop("ROS_LOG_DIR", None)
        self._rclpy = rclpy
        self._context = rclpy.context.Context()
        with temporary_environ(settings):
            # The runner handles SIGINT/SIGTERM itself (it must stop the nodes).
            rclpy.init(
                args=[],
                context=self._context,
                domain_id=domain_id,
                signal_handler_options=SignalHandlerOptions.NO,
            )
            try:
                # The participant is made with the context's first node.
                self.node = rclpy.create_node(
                    "servo_axis_run",
                    namespace=namespace,
                    context=self._context,
                    enable_rosout=False,
                    start_parameter_services=False,
                )
            except BaseException:
                rclpy.try_shutdown(context=self._context)
                raise
        from servo_axis.nodes.graph import Endpoint, Strangers
        from servo_axis.nodes.identified import IdentifiedSubscription
        from servo_axis.nodes.senders import Senders

        self.filter = ProgressFilter(steps)
        #: ``recorder/progress`` messages of strangers (never shown).
        self.strangers = 0
        self._msg_type = Float64MultiArray
        judging = Strangers(namespace=self.node.get_namespace(), external_roles=())
        topic = self.node.resolve_topic_name("recorder/progress")

        def judge(gid: str, final: bool) -> bool | None:
            endpoints = [Endpoint.of(i) for i in self.node.get_publishers_info_by_topic(topic)]
            return judging.plays_role("recorder/progress", "recorder", endpoints, gid, final=final)

        self._senders: Senders[bytes] = Senders(judge)
        self._subscription = IdentifiedSubscription(
            self.node, Float64MultiArray, "recorder/progress", reader_qos("recorder/progress"),
            self._on_raw,
        )  # fmt: skip
        self.node.create_timer(0.05, lambda: self._take(self._senders.retry()))
        from diagnostic_msgs.msg import DiagnosticArray

        #: The nodes that have reported on ``/diagnostics`` (their fully qualified names):
        #: a node's first status comes once it is built and spinning.
        self.reported: set[str] = set()
        self.node.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            lambda msg: self.reported.update(s.name for s in msg.status),
            100,
        )
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)

    @property
    def steps(self) -> int:
        """Steps recorded, as the last valid message said (-1 before the first)."""
        return self.filter.steps

    @property
    def rejected(self) -> int:
        """``recorder/progress`` messages refused so far."""
        return self.filter.rejected

    def _on_raw(self, data: bytes, gid: str) -> None:
        self._take(self._senders.offer(gid, data))

    def _take(self, released: list[tuple[bytes, str, bool]]) -> None:
        from rclpy.serialization import deserialize_message

        for data, _gid, from_recorder in released:
            if from_recorder:
                self._on(deserialize_message(data, self._msg_type))
            else:
                self.strangers += 1

    def _on(self, msg: Any) -> None:
        dims = list(msg.layout.dim)
        self.filter.offer([d.label for d in dims], [d.size for d in dims], msg.data)

    def endpoints(self, topic: str) -> tuple[int, int]:
        """Publishers and subscribers of ``topic`` (relative to the axis namespace) in the graph."""
        return self.node.count_publishers(topic), self.node.count_subscribers(topic)

    def spin(self, seconds: float) -> None:
        """Handle what has arrived, waiting at most ``seconds``."""
        self._executor.spin_once(timeout_sec=seconds)

    def close(self) -> None:
        """Destroy the node and shut the context down."""
        self._executor.shutdown()
        self._subscription.destroy()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self._context)


class ProgressLine:
    """One progress line, rewritten in place on a terminal (every 5 s otherwise)."""

    def __init__(self, total: int, out: TextIO) -> None:
        self.total = total
        self.out = out
        self.tty = out.isatty()
        self._last = 0.0

    def show(self, steps: int, elapsed_s: float, final: bool = False) -> None:
        """Show ``steps`` of ``total`` and the rate since the first step."""
        now = time.monotonic()
        if not final and now - self._last < (0.25 if self.tty else 5.0):
            return
        self._last = now
        frac = max(steps, 0) / self.total
        bar = "#" * int(30 * frac)
        rate = max(steps, 0) / elapsed_s if elapsed_s > 0 else 0.0
        text = f"[{bar:<30}] {max(steps, 0)}/{self.total} steps  {rate:,.0f} steps/s"
        if self.tty:
            self.out.write("\r" + text + ("\n" if final else ""))
        else:
            self.out.write(text + "\n")
        self.out.flush()
