"""Write rosbag2-layout MCAP bags.

A bag is a directory holding ``metadata.yaml`` (``rosbag2_bagfile_information``,
version 9, as ``ros2 bag`` of ROS 2 Jazzy writes it) and one ``<name>_0.mcap``
file: profile ``ros2``, one schema per message type (encoding ``ros2msg``, the
full definition text as rosbag2 builds it), one channel per topic (encoding
``cdr``) whose ``offered_qos_profiles`` metadata is the same text as in
``metadata.yaml`` (rosbags returns no messages when the two differ) and whose
``topic_type_hash`` is the type's RIHS01 hash. Payloads are CDR bytes as
received from a ``raw=True`` subscription or made by ``serialize_message``.

A message a stranger published (a publisher that does not play the topic's
role, :mod:`servo_axis.nodes.senders`) goes on a channel of its own: the
same topic, schema and QoS text, and the channel metadata
``stranger_publisher`` (:data:`STRANGER_KEY`) naming the publisher
(``<namespace>/<node> <gid>``). Readers that merge a topic's channels
(rosbags) see every message that was on the wire, in the topic's count of
``metadata.yaml``; the suite's analysis leaves a stranger's channels out of
the run's streams. The sequence numbers are the topic's, over its channels:
the recorder's order of arrival.

Independent readers that decode these bags: ``rosbags`` (``AnyReader``,
``rosbag2.Reader``), ``mcap-ros2-support`` (``DecoderFactory``),
:func:`servo_axis.recording.reader.read_raw` and
:func:`servo_axis.recording.deserialize.read_messages`.

This module does not import rclpy: :meth:`BagWriter.add_topic` checks that the
message type is installed with :func:`~servo_axis.recording.definitions.message_class`,
which imports the generated message package only when called.
"""

from __future__ import annotations

import operator
import os
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import yaml
from mcap.writer import CompressionType, Writer

from servo_axis.recording.definitions import (
    _split,
    message_class,
    message_definition,
)
from servo_axis.recording.definitions import type_hash as rihs01_hash
from servo_axis.recording.errors import BagError, BagWriteError
from servo_axis.recording.reader import STRANGER_KEY

__all__ = [
    "DEFAULT_QOS",
    "LATCHED_QOS_TEXT",
    "METADATA_VERSION",
    "STRANGER_KEY",
    "BagWriter",
    "offered_qos_text",
]

#: ``rosbag2_bagfile_information.version`` written (ROS 2 Jazzy).
METADATA_VERSION = 9


def offered_qos_text(*, depth: int, durability: str, lease_s: int) -> str:
    """``offered_qos_profiles`` of a reliable keep-last publisher.

    In the form rosbag2 (Jazzy, metadata version 9) writes it: enumerations
    by name, infinite durations as ``9223372036 s 854775807 ns``.
    """
    inf = "    sec: 9223372036\n    nsec: 854775807"
    return (
        f"- history: keep_last\n  depth: {depth}\n  reliability: reliable\n"
        f"  durability: {durability}\n  deadline:\n{inf}\n  lifespan:\n{inf}\n"
        f"  liveliness: automatic\n  liveliness_lease_duration:\n"
        f"    sec: {lease_s}\n    nsec: 0\n"
        "  avoid_ros_namespace_conventions: false"
    )


#: The per-sample streams' profile (``nodes.runtime.STREAM_QOS``).
DEFAULT_QOS = offered_qos_text(depth=2000, durability="transient_local", lease_s=1)
#: The latched topics' profile (``nodes.runtime.LATCHED_QOS``).
LATCHED_QOS_TEXT = offered_qos_text(depth=1, durability="transient_local", lease_s=1)

# The MCAP header's library string, unchanged from the single-module bag.py so that
# bags written before and after the split have identical headers.
_LIBRARY = "servo_axis recording.bag (mcap python)"

_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


@dataclass
class _Topic:
    channel_id: int
    metadata: dict[str, Any]
    schema_id: int
    count: int = 0
    #: The channel of each stranger that published on the topic, by who it is.
    strangers: dict[str, int] = field(default_factory=dict)


class BagWriter:
    """Write a rosbag2-layout MCAP bag from CDR-serialised messages.

    Parameters
    ----------
    directory : Path
        Bag directory to create; it may exist only if empty. The MCAP file is
        ``<directory>/<directory name>_0.mcap``.
    compression : str
        Chunk compression: ``"zstd"``, ``"lz4"`` or ``"none"``.
    chunk_size : int
        Uncompressed chunk size in bytes.
    file_name : str or None
        Name of the MCAP file in ``directory``; ``<directory name>_0.mcap``
        (as rosbag2 names it) if None.

    Raises
    ------
    BagError
        If ``compression`` or ``chunk_size`` is invalid, or ``directory`` is a
        file or a non-empty directory.

    Notes
    -----
    Close the writer (``close()``, a ``with`` block or ``try``/``finally``)
    also when a run fails: closing writes the MCAP summary and
    ``metadata.yaml``, and a bag closed after any number of writes reads back.

    Examples
    --------
    >>> with BagWriter(path) as bag:  # doctest: +SKIP
    ...     bag.add_topic("/clock", "rosgraph_msgs/msg/Clock")
    ...     bag.write("/clock", serialize_message(msg), log_time_ns=t)
    """

    def __init__(
        self,
        directory: Path,
        *,
        compression: str = "zstd",
        chunk_size: int = 1024 * 1024,
        file_name: str | None = None,
    ) -> None:
        if compression not in _COMPRESSION:
            raise BagError(
                f"compression: expected one of {sorted(_COMPRESSION)}, got {compression!r}"
            )
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
            raise BagError(f"chunk_size: expected an int >= 1 (bytes), got {chunk_size!r}")
        directory = Path(directory)
        if directory.exists() and not directory.is_dir():
            raise BagError(f"directory: {directory} exists and is not a directory")
        if directory.is_dir() and any(directory.iterdir()):
            raise BagError(f"directory: {directory} exists and is not empty")
        directory.mkdir(parents=True, exist_ok=True)
        self.directory = directory
        if file_name is not None and (
            not isinstance(file_name, str) or not file_name or Path(file_name).name != file_name
        ):
            raise BagError(f"file_name: expected a plain file name, got {file_name!r}")
        self.file_name = file_name if file_name is not None else f"{directory.name}_0.mcap"
        self._file = (directory / self.file_name).open("wb")
        try:
            self._writer = Writer(
                self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression]
            )
            self._writer.start(profile="ros2", library=_LIBRARY)
            # The magic and header in the file at once: a bag killed before its
            # first flush is then an empty MCAP, not a file of 0 bytes.
            self._file.flush()
        except BaseException:
            self._file.close()
            raise
        self._schemas: dict[str, int] = {}
        self._topics: dict[str, _Topic] = {}
        self._first_ns: int | None = None
        self._last_ns: int | None = None
        self._closed = False

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._closed

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written per topic (registered topics, in registration order)."""
        return {name: t.count for name, t in self._topics.items()}

    @property
    def first_log_time_ns(self) -> int | None:
        """Smallest log time written (ns); None before the first message."""
        return self._first_ns

    @property
    def last_log_time_ns(self) -> int | None:
        """Largest log time written (ns); None before the first message."""
        return self._last_ns

    @property
    def message_count(self) -> int:
        """Messages written in total."""
        return sum(t.count for t in self._topics.values())

    def add_topic(self, name: str, type_name: str, *, qos_text: str = DEFAULT_QOS) -> int:
        """Register a topic: its type's schema (once per type) and a channel.

        Parameters
        ----------
        name : str
            Fully qualified topic name, e.g. ``/joint_states``.
        type_name : str
            Message type, ``pkg/msg/Type``.
        qos_text : str
            ``offered_qos_profiles`` YAML text (a list of QoS mappings); written
            unchanged to the channel metadata and to ``metadata.yaml``.

        Returns
        -------
        int
            The MCAP channel id.

        Raises
        ------
        BagError
            If the writer is closed, the topic is already registered, the name
            is empty, the type is unknown, or ``qos_text`` is not a YAML list.
        """
        self._check_new_topic(name)
        package, tname = _split(type_name)
        full = f"{package}/msg/{tname}"
        definition = message_definition(full)
        message_class(full)
        return self._register(
            name, full, definition=definition, qos_text=qos_text, type_hash=rihs01_hash(full) or ""
        )

    def add_recorded_topic(
        self, name: str, type_name: str, *, definition: str, qos_text: str, type_hash: str
    ) -> int:
        """Register a topic from what a bag recorded, without looking the type up.

        :meth:`add_topic` without the installed message package: the schema
        text, QoS text and type hash are given as another bag holds them (its
        schema record and channel metadata), so that a copy of a bag keeps
        them unchanged. Used by :mod:`servo_axis.recording.recover`.

        Returns
        -------
        int
            The MCAP channel id.

        Raises
        ------
        BagError
            As :meth:`add_topic`, except for an unknown type.
        """
        self._check_new_topic(name)
        return self._register(
            name, type_name, definition=definition, qos_text=qos_text, type_hash=type_hash
        )

    def _check_new_topic(self, name: str) -> None:
        if self._closed:
            raise BagError(f"name: cannot add topic {name!r}, the bag is closed")
        if not isinstance(name, str) or not name:
            raise BagError(f"name: expected a non-empty topic name, got {name!r}")
        if name in self._topics:
            raise BagError(f"name: topic {name!r} is already registered")

    def _register(
        self, name: str, type_name: str, *, definition: str, qos_text: str, type_hash: str
    ) -> int:
        package, tname = _split(type_name)
        full = f"{package}/msg/{tname}"
        try:
            qos = yaml.safe_load(qos_text) if isinstance(qos_text, str) else None
        except yaml.YAMLError:
            qos = None
        if not isinstance(qos, list):
            raise BagError(
                f"qos_text: expected a YAML list of QoS profiles for {name!r}, got {qos_text!r}"
            )
        digest = type_hash
        if full not in self._schemas:
            self._schemas[full] = self._writer.register_schema(
                name=full, encoding="ros2msg", data=definition.encode()
            )
        channel_id = self._writer.register_channel(
            topic=name,
            message_encoding="cdr",
            schema_id=self._schemas[full],
            metadata={"offered_qos_profiles": qos_text, "topic_type_hash": digest},
        )
        self._topics[name] = _Topic(
            channel_id,
            {
                "name": name,
                "type": full,
                "serialization_format": "cdr",
                "offered_qos_profiles": qos_text,
                "type_description_hash": digest,
            },
            self._schemas[full],
        )
        return channel_id

    def stranger_channel(self, topic: str, who: str) -> int:
        """The channel of ``topic`` for the messages of stranger ``who`` (made on first use).

        Same topic, schema, QoS text and type hash as the topic's channel;
        its metadata's :data:`STRANGER_KEY` is ``who``.

        Raises
        ------
        BagWriteError
            If the topic is not registered or the bag is closed.
        """
        state = self._topics.get(topic)
        if state is None:
            raise BagWriteError(f"topic: {topic!r} was not registered with add_topic")
        if self._closed:
            raise BagWriteError(f"topic: cannot add a channel to {topic!r}, the bag is closed")
        channel = state.strangers.get(who)
        if channel is None:
            channel = state.strangers[who] = self._writer.register_channel(
                topic=topic,
                message_encoding="cdr",
                schema_id=state.schema_id,
                metadata={
                    "offered_qos_profiles": state.metadata["offered_qos_profiles"],
                    "topic_type_hash": state.metadata["type_description_hash"],
                    STRANGER_KEY: who,
                },
            )
        return channel

    def write(
        self,
        topic: str,
        data: bytes,
        *,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        stranger: str | None = None,
    ) -> None:
        """Append one CDR-serialised message of a registered topic.

        Parameters
        ----------
        topic : str
            A topic registered with :meth:`add_topic`.
        data : bytes
            The CDR payload (``serialize_message`` or a ``raw=True`` subscription).
        log_time_ns : int
            Receive (log) time in ns since the epoch, >= 0.
        publish_time_ns : int or None
            Publish time in ns; ``log_time_ns`` if None.
        stranger : str or None
            Who published it, when that is a stranger: the message goes on
            that stranger's channel (:meth:`stranger_channel`); None: the
            topic's channel.

        Raises
        ------
        BagWriteError
            If the topic is not registered, the bag is closed, or a time is
            not an int >= 0.
        """
        state = self._topics.get(topic)
        if state is None:
            raise BagWriteError(f"topic: {topic!r} was not registered with add_topic")
        if self._closed:
            raise BagWriteError(f"topic: cannot write {topic!r}, the bag is closed")
        try:
            log_time_ns = operator.index(log_time_ns)
            publish = log_time_ns if publish_time_ns is None else operator.index(publish_time_ns)
        except TypeError:
            raise BagWriteError(
                f"log_time_ns/publish_time_ns: expected ints (ns) for {topic!r}, "
                f"got {log_time_ns!r}/{publish_time_ns!r}"
            ) from None
        if log_time_ns < 0 or publish < 0:
            raise BagWriteError(
                f"log_time_ns/publish_time_ns: expected >= 0 for {topic!r}, "
                f"got {log_time_ns}/{publish}"
            )
        channel_id = (
            state.channel_id if stranger is None else self.stranger_channel(topic, stranger)
        )
        state.count += 1
        self._writer.add_message(
            channel_id=channel_id,
            log_time=log_time_ns,
            publish_time=publish,
            data=data if type(data) is bytes else bytes(data),
            sequence=state.count & 0xFFFFFFFF,
        )
        if self._first_ns is None:
            self._first_ns = self._last_ns = log_time_ns
        elif log_time_ns < self._first_ns:
            self._first_ns = log_time_ns
        elif log_time_ns > self._last_ns:  # type: ignore[operator]
            self._last_ns = log_time_ns

    def flush(self) -> None:
        """Close the chunk in progress early and hand every byte to the OS (no fsync).

        After it the file holds every message written so far in complete
        chunks (a chunk is written only when it has a message; the header,
        schemas and channels go with the first one), so a process killed
        afterwards, even by SIGKILL, loses none of them: the bytes are in the
        OS's file, only a power loss could drop them. Summary-based readers
        read the file only after :meth:`close`;
        :func:`servo_axis.recording.recover.recover_bag` makes a file that was
        never closed whole again. Flushing often means smaller chunks and
        slightly less compression.
        """
        if not self._closed:
            self._writer.flush()

    def metadata(self) -> dict[str, Any]:
        """The ``rosbag2_bagfile_information`` mapping of the messages written so far.

        Returns
        -------
        dict
            What :meth:`close` writes to ``metadata.yaml`` under
            ``rosbag2_bagfile_information``.
        """
        start = self._first_ns if self._first_ns is not None else 0
        duration = (self._last_ns - start) if self._last_ns is not None else 0
        total = self.message_count
        return {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": total,
            "topics_with_message_count": [
                {"topic_metadata": dict(t.metadata), "message_count": t.count}
                for t in self._topics.values()
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.file_name],
            "files": [
                {
                    "path": self.file_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": total,
                }
            ],
            "custom_data": {},
            "ros_distro": "jazzy",
        }

    def close(self) -> None:
        """Finish the MCAP file and write ``metadata.yaml`` (idempotent).

        The MCAP file also gets a ``rosbag2`` metadata record holding the same
        metadata (``serialized_metadata``), as rosbag2's MCAP storage writes it.
        """
        if self._closed:
            return
        self._closed = True
        info = self.metadata()
        try:
            try:
                self._writer.add_metadata(
                    "rosbag2", {"serialized_metadata": _dump_yaml(info).rstrip("\n")}
                )
            finally:
                self._writer.finish()
        finally:
            self._file.close()
            text = _dump_yaml({"rosbag2_bagfile_information": info})
            tmp = self.directory / "metadata.yaml.tmp"
            tmp.write_text(text)
            os.replace(tmp, self.directory / "metadata.yaml")

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _dump_yaml(data: dict[str, Any]) -> str:
    return str(yaml.safe_dump(data, sort_keys=False, width=1_000_000, allow_unicode=True))
