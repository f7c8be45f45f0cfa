"""Write rosbag2-layout MCAP bags.

A bag is a directory holding ``metadata.yaml`` (``rosbag2_bagfile_information``,
version 9, as ``ros2 bag`` of ROS 2 Jazzy writes it) and one ``<name>_0.mcap``
file, or, split by size or duration as ``ros2 bag record --max-bag-size`` /
``--max-bag-duration`` splits (``max_file_size_bytes``,
``max_file_duration_ns``), the files ``<name>_0.mcap``, ``<name>_1.mcap``, ...
listed in order under ``relative_file_paths`` and ``files`` (each with its
start, duration and message count), every topic registered in every file.
Each file is profile ``ros2``, one schema per message type (encoding ``ros2msg``, the
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
from servo_axis.recording.reader import MIN_SPLIT_SIZE_BYTES, STRANGER_KEY

__all__ = [
    "DEFAULT_QOS",
    "LATCHED_QOS_TEXT",
    "METADATA_VERSION",
    "MIN_SPLIT_SIZE_BYTES",
    "STRANGER_KEY",
    "BagFile",
    "BagWriter",
    "bagfile_information",
    "dump_yaml",
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
    definition: str
    count: int = 0
    #: The channel of each stranger that published on the topic, by who it is.
    strangers: dict[str, int] = field(default_factory=dict)


@dataclass
class BagFile:
    """One MCAP file of a bag: its name, messages and log-time span (ns)."""

    path: str
    count: int = 0
    first_ns: int | None = None
    last_ns: int | None = None

    def entry(self) -> dict[str, Any]:
        start = self.first_ns if self.first_ns is not None else 0
        duration = (self.last_ns - start) if self.last_ns is not None else 0
        return {
            "path": self.path,
            "starting_time": {"nanoseconds_since_epoch": start},
            "duration": {"nanoseconds": duration},
            "message_count": self.count,
        }


class BagWriter:
    """Write a rosbag2-layout MCAP bag from CDR-serialised messages.

    Parameters
    ----------
    directory : Path
        Bag directory to create; it may exist only if empty. The MCAP files
        are ``<directory>/<directory name>_<i>.mcap``, ``i`` = 0, 1, ...
    compression : str
        Chunk compression: ``"zstd"``, ``"lz4"`` or ``"none"``.
    chunk_size : int
        Uncompressed chunk size in bytes.
    file_name : str or None
        Name of the (one) MCAP file in ``directory``; ``<directory name>_0.mcap``
        (as rosbag2 names it) if None. Only for a bag that is not split.
    max_file_size_bytes : int
        Start the next file before a message once the file holds at least
        this many bytes (0: never). What counts is what is in the file: the
        chunks closed so far (``chunk_size``, or a :meth:`flush`), so that a
        file ends up to one chunk and its summary larger, as with rosbag2's
        MCAP storage. At least :data:`MIN_SPLIT_SIZE_BYTES`.
    max_file_duration_ns : int
        Start the next file before a message whose log time is more than
        this after the file's first (0: never).

    Raises
    ------
    BagError
        If ``compression``, ``chunk_size`` or a split bound is invalid, or
        ``directory`` is a file or a non-empty directory.

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
        max_file_size_bytes: int = 0,
        max_file_duration_ns: int = 0,
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
        for key, bound in (
            ("max_file_size_bytes", max_file_size_bytes),
            ("max_file_duration_ns", max_file_duration_ns),
        ):
            if isinstance(bound, bool) or not isinstance(bound, int) or bound < 0:
                raise BagError(f"{key}: expected an int >= 0 (0: no split), got {bound!r}")
        if 0 < max_file_size_bytes < MIN_SPLIT_SIZE_BYTES:
            raise BagError(
                f"max_file_size_bytes: expected 0 (no split) or >= {MIN_SPLIT_SIZE_BYTES}, "
                f"got {max_file_size_bytes}"
            )
        if file_name is not None and (max_file_size_bytes or max_file_duration_ns):
            raise BagError("file_name: a bag that splits names its files itself")
        self.file_name = file_name if file_name is not None else f"{directory.name}_0.mcap"
        self._max_size = max_file_size_bytes
        self._max_duration_ns = max_file_duration_ns
        self._chunk_size = chunk_size
        self._compression = _COMPRESSION[compression]
        self._schemas: dict[str, int] = {}
        self._topics: dict[str, _Topic] = {}
        self._files: list[BagFile] = []
        self._first_ns: int | None = None
        self._last_ns: int | None = None
        self._closed = False
        self._open_file(self.file_name)

    def _open_file(self, name: str) -> None:
        """Start MCAP file ``name``: header, then every schema and channel so far."""
        self._file = (self.directory / name).open("wb")
        try:
            self._writer = Writer(
                self._file, chunk_size=self._chunk_size, compression=self._compression
            )
            self._writer.start(profile="ros2", library=_LIBRARY)
            # Schemas and channels in the same order: the channel ids stay.
            definitions = {t.metadata["type"]: t.definition for t in self._topics.values()}
            self._schemas = {
                full: self._writer.register_schema(
                    name=full, encoding="ros2msg", data=definitions[full].encode()
                )
                for full in self._schemas
            }
            for topic in self._topics.values():
                topic.channel_id = self._register_channel(topic.metadata)
                for who in topic.strangers:
                    topic.strangers[who] = self._register_channel(topic.metadata, who)
            # The magic and header in the file at once: a bag killed before its
            # first flush is then an empty MCAP, not a file of 0 bytes.
            self._file.flush()
        except BaseException:
            self._file.close()
            raise
        self._files.append(BagFile(name))

    def _finish_file(self) -> None:
        """Finish the MCAP file in progress (its summary and rosbag2 metadata record)."""
        try:
            try:
                self._writer.add_metadata(
                    "rosbag2", {"serialized_metadata": dump_yaml(self.metadata()).rstrip("\n")}
                )
            finally:
                self._writer.finish()
        finally:
            self._file.close()

    def _split(self) -> None:
        self._finish_file()
        self._open_file(f"{self.directory.name}_{len(self._files)}.mcap")

    def _register_channel(self, metadata: dict[str, Any], stranger: str | None = None) -> int:
        """A channel of the file in progress: a topic's, or a stranger's on it."""
        channel = {
            "offered_qos_profiles": metadata["offered_qos_profiles"],
            "topic_type_hash": metadata["type_description_hash"],
        }
        if stranger is not None:
            channel[STRANGER_KEY] = stranger
        return int(
            self._writer.register_channel(
                topic=metadata["name"],
                message_encoding="cdr",
                schema_id=self._schemas[metadata["type"]],
                metadata=channel,
            )
        )

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
    def file_names(self) -> list[str]:
        """The bag's MCAP files so far, in order (the last one is being written)."""
        return [f.path for f in self._files]

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
        if full not in self._schemas:
            self._schemas[full] = self._writer.register_schema(
                name=full, encoding="ros2msg", data=definition.encode()
            )
        metadata = {
            "name": name,
            "type": full,
            "serialization_format": "cdr",
            "offered_qos_profiles": qos_text,
            "type_description_hash": type_hash,
        }
        channel_id = self._register_channel(metadata)
        self._topics[name] = _Topic(channel_id, metadata, definition)
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
            channel = state.strangers[who] = self._register_channel(state.metadata, who)
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
        file = self._files[-1]
        if file.count and (
            (self._max_size and self._file.tell() >= self._max_size)
            or (
                self._max_duration_ns and log_time_ns - file.first_ns > self._max_duration_ns  # type: ignore[operator]
            )
        ):
            self._split()
            file = self._files[-1]
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
        _extend(file, log_time_ns)
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
        return bagfile_information(
            [(t.metadata, t.count) for t in self._topics.values()], self._files
        )

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
            self._finish_file()
        finally:
            text = dump_yaml({"rosbag2_bagfile_information": info})
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


def bagfile_information(
    topics: list[tuple[dict[str, Any], int]], files: list[BagFile]
) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag (metadata version 9).

    Parameters
    ----------
    topics : list of (dict, int)
        Each topic's ``topic_metadata`` (name, type, serialization_format,
        offered_qos_profiles, type_description_hash) and its message count,
        in registration order.
    files : list of BagFile
        The MCAP files in order: name, message count, log-time span.
    """
    firsts = [f.first_ns for f in files if f.first_ns is not None]
    lasts = [f.last_ns for f in files if f.last_ns is not None]
    start = min(firsts) if firsts else 0
    duration = (max(lasts) - start) if lasts else 0
    return {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(count for _, count in topics),
        "topics_with_message_count": [
            {"topic_metadata": dict(metadata), "message_count": count} for metadata, count in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [f.entry() for f in files],
        "custom_data": {},
        "ros_distro": "jazzy",
    }


def _extend(file: BagFile, log_time_ns: int) -> None:
    """Count one message of log time ``log_time_ns`` in ``file``."""
    file.count += 1
    if file.first_ns is None or log_time_ns < file.first_ns:
        file.first_ns = log_time_ns
    if file.last_ns is None or log_time_ns > file.last_ns:
        file.last_ns = log_time_ns


def dump_yaml(data: dict[str, Any]) -> str:
    """``data`` as the YAML text of ``metadata.yaml`` (key order kept, no line wrap)."""
    return str(yaml.safe_dump(data, sort_keys=False, width=1_000_000, allow_unicode=True))
