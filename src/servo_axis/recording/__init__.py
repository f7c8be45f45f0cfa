"""Recording: rosbag2-layout MCAP bags (writer, reader, message definitions).

See :mod:`servo_axis.recording.bag`.
"""

from __future__ import annotations

from servo_axis.recording.bag import (
    DEFAULT_QOS,
    BagMessage,
    BagWriter,
    message_class,
    message_definition,
    read_messages,
    read_metadata,
    type_hash,
)

__all__ = [
    "DEFAULT_QOS",
    "BagMessage",
    "BagWriter",
    "message_class",
    "message_definition",
    "read_messages",
    "read_metadata",
    "type_hash",
]
