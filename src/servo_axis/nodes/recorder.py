"""Recorder node: every topic of the run into a rosbag2-layout MCAP directory.

Subscribes to ``topics`` (with their ``types``) without deserialising
(``raw=True``) and writes the CDR bytes as they come. Publishes
``recorder/progress`` (Float64MultiArray ``[steps_recorded]``, latched): the
smallest message count over ``counted_topics``, i.e. the number of steps that
are fully on disk. The plant uses it for flow control in lockstep, so the
recorder never loses a message. A first ``[0]`` means "all subscriptions
matched, ready".

The bag is closed (metadata.yaml written) on shutdown, SIGINT or SIGTERM.

Run::

    python -m servo_axis.nodes.recorder --ros-args --params-file config/<scenario>.yaml \
        -p recorder:output_dir:=<dir>
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.runtime import LATCHED_QOS, STREAM_QOS, run_main, steady_clock
from servo_axis.params.factories import run_steps
from servo_axis.recording.definitions import message_class as bag_message_class
from servo_axis.recording.writer import BagWriter
from servo_axis.wire import messages as msgs


def message_class(type_name: str) -> Any:
    """Python class of ``pkg/msg/Type``; ParameterFileError if there is none."""
    try:
        return bag_message_class(type_name)
    except ConfigError as err:
        raise ParameterFileError(f"parameter 'types': {err}") from err


class RecorderNode(ServoNode):
    """Recorder; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        values = self.values
        topics, types = values["topics"], values["types"]
        if len(topics) != len(types) or not topics:
            raise ParameterFileError(
                f"parameter 'types': expected one type per topic ({len(topics)} topics), got {len(types)}"
            )
        for key in ("latched_topics", "counted_topics"):
            extra = set(values[key]) - set(topics)
            if extra:
                raise ParameterFileError(f"parameter '{key}': {sorted(extra)} not in 'topics'")
        if not values["output_dir"]:
            raise ParameterFileError(
                "parameter 'output_dir': required (the bag directory to create)"
            )
        classes = [message_class(t) for t in types]
        self._v = values
        self._steps = run_steps(values)
        try:
            self.writer = BagWriter(Path(values["output_dir"]), compression=values["compression"])
        except (OSError, ValueError) as err:
            raise ParameterFileError(f"parameter 'output_dir': {err}") from err

        self._progress_pub = self.publisher("recorder/progress")
        self._counts: dict[str, int] = {}
        self._counted: list[str] = []
        self._subs = []
        for topic, type_name, cls in zip(topics, types, classes, strict=True):
            name = self.resolve_topic_name(topic)
            self.writer.add_topic(name, type_name)
            self._counts[name] = 0
            if topic in values["counted_topics"]:
                self._counted.append(name)
            qos = LATCHED_QOS if topic in values["latched_topics"] else STREAM_QOS
            self._subs.append(
                self.create_subscription(cls, topic, self._callback(name), qos, raw=True)
            )
        self.recorded = -1
        self._ready_timer = self.create_timer(0.01, self._check_ready, clock=steady_clock())
        self._closed = False

    def _callback(self, name: str) -> Any:
        writer = self.writer
        counts = self._counts

        def on_message(data: bytes) -> None:
            writer.write(name, data, log_time_ns=time.time_ns())
            counts[name] += 1
            if name in self._counted:
                self._update_progress()

        return on_message

    def _check_ready(self) -> None:
        if self._v["wait_for_publishers"] and any(s.get_publisher_count() < 1 for s in self._subs):
            return
        self._ready_timer.cancel()
        self.recorded = 0
        self._update_progress(force=True)

    def _update_progress(self, force: bool = False) -> None:
        if self.recorded < 0:
            return
        done = min(self._counts[n] for n in self._counted) if self._counted else 0
        if done == self.recorded and not force:
            return
        self.recorded = done
        if force or done % self._v["ack_every_steps"] == 0 or done >= self._steps:
            self._progress_pub.publish(msgs.labelled_array(msgs.PROGRESS_LABELS, [done]))

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written per topic."""
        return dict(self._counts)

    def close(self) -> None:
        """Finish the bag (idempotent)."""
        if not self._closed:
            self._closed = True
            self.writer.close()
        super().close()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.recorder``."""
    return run_main("recorder", [RecorderNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
