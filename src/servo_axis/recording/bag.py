"""rosbag2-layout MCAP bags: writer and reader.

A bag is a directory holding ``metadata.yaml`` (``rosbag2_bagfile_information``,
version 9, as ``ros2 bag`` of ROS 2 Jazzy writes it) and one ``<name>_0.mcap``
file: profile ``ros2``, one schema per message type (encoding ``ros2msg``, the
full definition text as rosbag2 builds it), one channel per topic (encoding
``cdr``) whose ``offered_qos_profiles`` metadata is the same text as in
``metadata.yaml`` (rosbags returns no messages when the two differ) and whose
``topic_type_hash`` is the type's RIHS01 hash. Payloads are CDR bytes as
received from a ``raw=True`` subscription or made by ``serialize_message``.

Independent readers that decode these bags: ``rosbags`` (``AnyReader``,
``rosbag2.Reader``), ``mcap-ros2-support`` (``DecoderFactory``) and
:func:`read_messages`.
"""

from __future__ import annotations

import functools
import heapq
import importlib
import json
import operator
import os
import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import yaml
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, Writer

from servo_axis.core.errors import ConfigError, SignalError

__all__ = [
    "DEFAULT_QOS",
    "METADATA_VERSION",
    "SEPARATOR",
    "BagMessage",
    "BagWriter",
    "message_class",
    "message_definition",
    "read_messages",
    "read_metadata",
    "type_hash",
]

#: The line between two definitions in ``ros2msg`` text.
SEPARATOR = "=" * 80

#: ``rosbag2_bagfile_information.version`` written (ROS 2 Jazzy).
METADATA_VERSION = 9

#: ``offered_qos_profiles`` of a reliable, volatile, keep-last (depth 2000)
#: publisher, in the form rosbag2 (Jazzy, metadata version 9) writes it:
#: enumerations by name, infinite durations as ``9223372036 s 854775807 ns``.
DEFAULT_QOS = """- history: keep_last
  depth: 2000
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""

_LIBRARY = "servo_axis recording.bag (mcap python)"

_PRIMITIVES = frozenset(
    {
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
        "int32", "uint32", "int64", "uint64", "string", "wstring",
    }
)  # fmt: skip

# The field type at the start of a .msg line: ``pkg/Type``, ``Type``, ``string<=8``,
# ``float64[]``, ``float64[3]``, ``int32[<=4]``; comments and blank lines do not match.
_FIELD_TYPE = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_/]*)(?:<=\d+)?(?:\[[^\]]*\])?\s+\S")

_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}

_NAME = r"[A-Za-z][A-Za-z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:(msg)/)?({_NAME})$")


# --------------------------------------------------------------------------- types


def _split(type_name: str) -> tuple[str, str]:
    """``(package, Type)`` of ``pkg/msg/Type`` or ``pkg/Type``.

    Raises
    ------
    ConfigError
        If ``type_name`` is not a message type name.
    """
    match = _TYPE_NAME.match(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise ConfigError(f"type_name: expected 'pkg/msg/Type', got {type_name!r}")
    return match.group(1), match.group(3)


@functools.cache
def _package_share(package: str) -> Path:
    """Share directory of an installed ROS package (``<prefix>/share/<pkg>``)."""
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        return Path(sys.prefix) / "share" / package


def _interface_file(type_name: str, suffix: str) -> Path:
    package, name = _split(type_name)
    return _package_share(package) / "msg" / f"{name}{suffix}"


@functools.cache
def _msg_text(type_name: str) -> str:
    """The installed ``.msg`` text of ``pkg/Type``.

    Raises
    ------
    ConfigError
        If no ``.msg`` file is installed for the type.
    """
    path = _interface_file(type_name, ".msg")
    try:
        return path.read_text()
    except OSError:
        raise ConfigError(
            f"type_name: unknown message type {type_name!r} (no definition at {path})"
        ) from None


def _dependencies(text: str, package: str) -> list[str]:
    """Nested types (``pkg/Type``) of a ``.msg`` text, sorted and unique like rosbag2."""
    deps: set[str] = set()
    for line in text.splitlines():
        match = _FIELD_TYPE.match(line)
        if match is None:
            continue
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        if field_type == "Header":
            deps.add("std_msgs/Header")
        elif "/" not in field_type:
            deps.add(f"{package}/{field_type}")
        else:
            dep_package, dep_name = _split(field_type)
            deps.add(f"{dep_package}/{dep_name}")
    return sorted(deps)


@functools.cache
def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` definition text of a message type, nested types included.

    The text is built as rosbag2 (``LocalMessageDefinitionSource``) builds it:
    the type's ``.msg`` file, then, depth first with the nested types of each
    definition in sorted order and every type once, a newline, a line of 80
    ``=``, a line ``MSG: pkg/Type`` and that type's ``.msg`` file.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type`` (or ``pkg/Type``), e.g.
        ``sensor_msgs/msg/JointState``.

    Returns
    -------
    str
        The definition text (schema data of the type's MCAP schema).

    Raises
    ------
    ConfigError
        If the type or one of its nested types has no installed ``.msg`` file.
    """
    package, name = _split(type_name)
    seen = {f"{package}/{name}"}

    def append(pkg_type: str, depth: int) -> list[str]:
        if depth > 64:
            raise ConfigError(f"type_name: {type_name!r} nests types more than 64 deep")
        text = _msg_text(pkg_type)
        parts = [text]
        for dep in _dependencies(text, pkg_type.split("/", 1)[0]):
            if dep in seen:
                continue
            seen.add(dep)
            parts.append(f"\n{SEPARATOR}\nMSG: {dep}\n")
            parts.extend(append(dep, depth + 1))
        return parts

    return "".join(append(f"{package}/{name}", 0))


@functools.cache
def type_hash(type_name: str) -> str | None:
    """The RIHS01 type hash of a message type, from its installed ``.json``.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type``.

    Returns
    -------
    str or None
        ``RIHS01_<64 hex digits>`` (``type_hashes`` entry of the type in
        ``share/<pkg>/msg/<Type>.json``), or None if the file or entry is missing.
    """
    package, name = _split(type_name)
    path = _interface_file(type_name, ".json")
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    full = f"{package}/msg/{name}"
    for entry in data.get("type_hashes", []) if isinstance(data, dict) else []:
        if isinstance(entry, dict) and entry.get("type_name") == full:
            value = entry.get("hash_string")
            return str(value) if value else None
    return None


def message_class(type_name: str) -> Any:
    """Python class of a message type.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type``.

    Returns
    -------
    type
        The rosidl-generated message class.

    Raises
    ------
    ConfigError
        If the package or type is not installed.
    """
    package, name = _split(type_name)
    try:
        from rosidl_runtime_py.utilities import get_message
    except ImportError:
        pass
    else:
        try:
            return get_message(f"{package}/msg/{name}")
        except (ImportError, AttributeError, ValueError) as err:
            raise ConfigError(f"type_name: unknown message type {type_name!r}") from err
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as err:
        raise ConfigError(f"type_name: unknown message type {type_name!r}") from err


# --------------------------------------------------------------------------- writer


@dataclass
class _Topic:
    channel_id: int
    metadata: dict[str, Any]
    count: int = 0


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

    Raises
    ------
    ConfigError
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
        self, directory: Path, *, compression: str = "zstd", chunk_size: int = 1024 * 1024
    ) -> None:
        if compression not in _COMPRESSION:
            raise ConfigError(
                f"compression: expected one of {sorted(_COMPRESSION)}, got {compression!r}"
            )
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
            raise ConfigError(f"chunk_size: expected an int >= 1 (bytes), got {chunk_size!r}")
        directory = Path(directory)
        if directory.exists() and not directory.is_dir():
            raise ConfigError(f"directory: {directory} exists and is not a directory")
        if directory.is_dir() and any(directory.iterdir()):
            raise ConfigError(f"directory: {directory} exists and is not empty")
        directory.mkdir(parents=True, exist_ok=True)
        self.directory = directory
        self.file_name = f"{directory.name}_0.mcap"
        self._file = (directory / self.file_name).open("wb")
        try:
            self._writer = Writer(
                self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression]
            )
            self._writer.start(profile="ros2", library=_LIBRARY)
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
        ConfigError
            If the writer is closed, the topic is already registered, the name
            is empty, the type is unknown, or ``qos_text`` is not a YAML list.
        """
        if self._closed:
            raise ConfigError(f"name: cannot add topic {name!r}, the bag is closed")
        if not isinstance(name, str) or not name:
            raise ConfigError(f"name: expected a non-empty topic name, got {name!r}")
        if name in self._topics:
            raise ConfigError(f"name: topic {name!r} is already registered")
        package, tname = _split(type_name)
        full = f"{package}/msg/{tname}"
        definition = message_definition(full)
        message_class(full)
        try:
            qos = yaml.safe_load(qos_text) if isinstance(qos_text, str) else None
        except yaml.YAMLError:
            qos = None
        if not isinstance(qos, list):
            raise ConfigError(
                f"qos_text: expected a YAML list of QoS profiles for {name!r}, got {qos_text!r}"
            )
        digest = type_hash(full) or ""
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
        )
        return channel_id

    def write(
        self, topic: str, data: bytes, *, log_time_ns: int, publish_time_ns: int | None = None
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

        Raises
        ------
        SignalError
            If the topic is not registered, the bag is closed, or a time is
            not an int >= 0.
        """
        state = self._topics.get(topic)
        if state is None:
            raise SignalError(f"topic: {topic!r} was not registered with add_topic")
        if self._closed:
            raise SignalError(f"topic: cannot write {topic!r}, the bag is closed")
        try:
            log_time_ns = operator.index(log_time_ns)
            publish = log_time_ns if publish_time_ns is None else operator.index(publish_time_ns)
        except TypeError:
            raise SignalError(
                f"log_time_ns/publish_time_ns: expected ints (ns) for {topic!r}, "
                f"got {log_time_ns!r}/{publish_time_ns!r}"
            ) from None
        if log_time_ns < 0 or publish < 0:
            raise SignalError(
                f"log_time_ns/publish_time_ns: expected >= 0 for {topic!r}, "
                f"got {log_time_ns}/{publish}"
            )
        state.count += 1
        self._writer.add_message(
            channel_id=state.channel_id,
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
        """Finish the chunk in progress and flush the file (no fsync).

        The file stays unreadable by summary-based readers until :meth:`close`;
        flushing bounds what a crash loses. Flushing often lowers compression.
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


# --------------------------------------------------------------------------- reader


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


def read_metadata(directory: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag's ``metadata.yaml``.

    Parameters
    ----------
    directory : Path
        The bag directory.

    Returns
    -------
    dict
        The parsed mapping (``version``, ``topics_with_message_count``, ...).

    Raises
    ------
    ConfigError
        If ``metadata.yaml`` is missing or is not rosbag2 metadata.
    """
    path = Path(directory) / "metadata.yaml"
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ConfigError(f"directory: cannot read bag metadata {path}: {err}") from err
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise ConfigError(f"directory: {path} has no 'rosbag2_bagfile_information' mapping")
    return info


def _mcap_files(directory: Path) -> list[Path]:
    try:
        names = read_metadata(directory)["relative_file_paths"]
        return [directory / Path(str(n)).name for n in names]
    except (ConfigError, KeyError, TypeError):
        return sorted(directory.glob("*.mcap"))


def _file_messages(path: Path, topics: list[str] | None) -> Iterator[tuple[int, Any, Any, Any]]:
    """``(log_time, schema, channel, message)`` of one MCAP file in log-time order.

    A file that was never finished (no summary, possibly truncated) is read
    record by record up to its last complete record and then sorted.
    """
    with path.open("rb") as f:
        reader = make_reader(f)
        try:
            summary = reader.get_summary()
        except (McapError, EOFError, ValueError):
            summary = None
        if summary is not None:
            for schema, channel, msg in reader.iter_messages(topics=topics, log_time_order=True):
                yield msg.log_time, schema, channel, msg
            return
        f.seek(0)
        items = []
        try:
            for schema, channel, msg in NonSeekingReader(f).iter_messages(
                topics=topics, log_time_order=False
            ):
                items.append((msg.log_time, schema, channel, msg))
        except (McapError, EOFError, ValueError):
            pass
    items.sort(key=operator.itemgetter(0))
    yield from items


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
    ConfigError
        If a message type is not installed.
    """
    from rclpy.serialization import deserialize_message

    directory = Path(directory)
    wanted = list(topics) if topics is not None else None
    classes: dict[str, Any] = {}
    streams = [_file_messages(p, wanted) for p in _mcap_files(directory)]
    merged = heapq.merge(*streams, key=operator.itemgetter(0))
    for log_time, schema, channel, msg in merged:
        type_name = schema.name if schema is not None else ""
        cls = classes.get(type_name)
        if cls is None:
            cls = classes[type_name] = message_class(type_name)
        yield BagMessage(channel.topic, type_name, log_time, deserialize_message(msg.data, cls))
