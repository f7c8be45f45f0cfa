"""Read rosbag2-layout MCAP bags as deserialised rclpy messages.

Built on :func:`servo_axis.recording.reader.read_raw`; rclpy is imported when
:func:`read_messages` runs, not when this module is imported, so importing
:mod:`servo_axis.recording` stays free of ROS.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servo_axis.recording.definitions import message_class
from servo_axis.recording.reader import read_raw

__all__ = ["BagMessage", "read_messages"]


@dataclass(frozen=True)
class BagMessage:
    """A message read back from a bag.

    Attributes
    ----------
    topic : str
        Topic name.
    type_name : str
        Message type, ``pkg/msg/Type``.
    log_time_ns : int
        Log (receive) time in ns.
    message : Any
        The deserialised rosidl message.
    """

    topic: str
    type_name: str
    log_time_ns: int
    message: Any


def read_messages(directory: Path, *, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
    """Deserialised messages of a bag in log-time order (our own reader).

    Parameters
    ----------
    directory : Path
        The bag directory (its ``metadata.yaml`` names the MCAP files; without
        it every ``*.mcap`` in the directory is read).
    topics : iterable of str or None
        Only these topics; all if None.

    Yields
    ------
    BagMessage
        Topic, type, log time and the message deserialised with
        ``rclpy.serialization.deserialize_message``.

    Raises
    ------
    BagError
        If a message type is not installed.
    """
    from rclpy.serialization import deserialize_message

    classes: dict[str, Any] = {}
    for raw in read_raw(directory, topics=topics):
        cls = classes.get(raw.type_name)
        if cls is None:
            cls = classes[raw.type_name] = message_class(raw.type_name)
        yield BagMessage(
            raw.topic, raw.type_name, raw.log_time_ns, deserialize_message(raw.data, cls)
        )
