"""rosbag2-layout MCAP bags: writer and reader.

A bag is a directory with ``metadata.yaml`` (``rosbag2_bagfile_information``,
version 9) and one ``<name>_0.mcap`` file: profile ``ros2``, one schema per
message type (encoding ``ros2msg``, the full definition text as rosbag2
writes it), one channel per topic (encoding ``cdr``) whose
``offered_qos_profiles`` metadata is the same text as in ``metadata.yaml``
(rosbags returns no messages when the two differ). Payloads are CDR bytes as
received from a ``raw=True`` subscription or from ``serialize_message``.
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from servo_axis.core.errors import ConfigError, SignalError

SEPARATOR = "=" * 80

#: offered_qos_profiles of a reliable, volatile, keep-last publisher, as
#: rosbag2 (Jazzy) writes it.
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

_PRIMITIVES = {
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string", "wstring",
}  # fmt: skip


def _share_dir() -> Path:
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    return Path(sys.prefix) / "share"


def _msg_path(type_name: str) -> Path:
    pkg, _, name = _split(type_name)
    return _share_dir() / pkg / "msg" / f"{name}.msg"


def _split(type_name: str) -> tuple[str, str, str]:
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise ConfigError(f"type_name: expected 'pkg/msg/Type', got {type_name!r}")
    return parts[0], parts[1], parts[2]


def _dependencies(text: str, pkg: str) -> list[str]:
    deps: list[str] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        field_type = re.sub(r"\[.*\]$", "", line.split()[0])
        field_type = re.sub(r"<=\d+$", "", field_type)
        if field_type in _PRIMITIVES or "=" in line.split()[0]:
            continue
        if field_type == "Header":
            deps.append("std_msgs/msg/Header")
        elif "/" in field_type:
            p, _, n = _split(field_type)
            deps.append(f"{p}/msg/{n}")
        else:
            deps.append(f"{pkg}/msg/{field_type}")
    return deps


def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` definition text of a message type, nested types included.

    The type's ``.msg`` text, then for each nested type (each once, depth
    first, in the order of first use) a line of 80 ``=``, ``MSG: pkg/Type``
    and its ``.msg`` text, as rosbag2 stores it.

    Raises
    ------
    ConfigError
        If the type's ``.msg`` file is not installed.
    """
    pkg, _, name = _split(type_name)
    path = _msg_path(type_name)
    if not path.is_file():
        raise ConfigError(f"type_name: no message definition for {type_name!r} (looked for {path})")
    text = path.read_text()
    parts = [text.rstrip("\n")]
    seen: set[str] = {f"{pkg}/msg/{name}"}
    stack = list(reversed(_dependencies(text, pkg)))
    while stack:
        dep = stack.pop()
        if dep in seen:
            continue
        seen.add(dep)
        dep_path = _msg_path(dep)
        if not dep_path.is_file():
            raise ConfigError(f"type_name: no message definition for nested {dep!r}")
        dep_text = dep_path.read_text()
        dpkg, _, dname = _split(dep)
        parts.append(f"{SEPARATOR}\nMSG: {dpkg}/{dname}\n{dep_text.rstrip(chr(10))}")
        stack.extend(reversed(_dependencies(dep_text, dpkg)))
    return "\n".join(parts) + "\n"


def type_hash(type_name: str) -> str | None:
    """The RIHS01 type hash from the type's installed ``.json``, or None."""
    pkg, _, name = _split(type_name)
    path = _share_dir() / pkg / "msg" / f"{name}.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    for entry in data.get("type_hashes", []):
        if entry.get("type_name") == f"{pkg}/msg/{name}":
            return str(entry["hash_string"])
    return None


_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


class BagWriter:
    """Write a rosbag2-layout MCAP bag from serialised messages.

    Parameters
    ----------
    directory : Path
        Bag directory to create (must not exist or be empty).
    compression : str
        Chunk compression: ``zstd``, ``lz4`` or ``none``.
    chunk_size : int
        Chunk size in bytes.
    """

    def __init__(
        self, directory: Path, *, compression: str = "zstd", chunk_size: int = 1024 * 1024
    ) -> None:
        if compression not in _COMPRESSION:
            raise ConfigError(
                f"compression: expected one of {sorted(_COMPRESSION)}, got {compression!r}"
            )
        directory = Path(directory)
        if directory.exists() and any(directory.iterdir()):
            raise ConfigError(f"directory: {directory} exists and is not empty")
        directory.mkdir(parents=True, exist_ok=True)
        self.directory = directory
        self.file_name = f"{directory.name}_0.mcap"
        self._file = (directory / self.file_name).open("wb")
        self._writer = Writer(
            self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression]
        )
        self._writer.start(profile="ros2", library="servo_axis (mcap python)")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._topics: dict[str, dict[str, Any]] = {}
        self._sequence: dict[str, int] = {}
        self._counts: dict[str, int] = {}
        self._first_ns: int | None = None
        self._last_ns = 0
        self._closed = False

    def add_topic(self, name: str, type_name: str, *, qos_text: str = DEFAULT_QOS) -> int:
        """Register a topic and its type; return the channel id."""
        if name in self._channels:
            raise ConfigError(f"name: topic {name!r} is already registered")
        pkg, _, tname = _split(type_name)
        full = f"{pkg}/msg/{tname}"
        if full not in self._schemas:
            self._schemas[full] = self._writer.register_schema(
                name=full, encoding="ros2msg", data=message_definition(full).encode()
            )
        hash_ = type_hash(full)
        metadata = {"offered_qos_profiles": qos_text}
        if hash_:
            metadata["topic_type_hash"] = hash_
        self._channels[name] = self._writer.register_channel(
            topic=name, message_encoding="cdr", schema_id=self._schemas[full], metadata=metadata
        )
        meta: dict[str, Any] = {
            "name": name,
            "type": full,
            "serialization_format": "cdr",
            "offered_qos_profiles": qos_text,
        }
        if hash_:
            meta["type_description_hash"] = hash_
        self._topics[name] = meta
        self._sequence[name] = 0
        self._counts[name] = 0
        return self._channels[name]

    def write(
        self, topic: str, data: bytes, *, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Append one serialised message of a registered topic."""
        channel = self._channels.get(topic)
        if channel is None:
            raise SignalError(f"topic: {topic!r} was not registered with add_topic")
        self._sequence[topic] += 1
        self._writer.add_message(
            channel_id=channel,
            log_time=log_time_ns,
            publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
            data=bytes(data),
            sequence=self._sequence[topic],
        )
        self._counts[topic] += 1
        if self._first_ns is None or log_time_ns < self._first_ns:
            self._first_ns = log_time_ns
        self._last_ns = max(self._last_ns, log_time_ns)

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written per topic."""
        return dict(self._counts)

    def close(self) -> None:
        """Finish the MCAP file and write ``metadata.yaml`` (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._writer.finish()
        self._file.close()
        start = self._first_ns or 0
        duration = max(0, self._last_ns - start)
        total = sum(self._counts.values())
        info = {
            "version": 9,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": total,
            "topics_with_message_count": [
                {"topic_metadata": self._topics[t], "message_count": self._counts[t]}
                for t in self._topics
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
        text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False, width=1000)
        (self.directory / "metadata.yaml").write_text(text)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class BagMessage:
    """A message read back from a bag."""

    topic: str
    type_name: str
    log_time_ns: int
    message: Any


def message_class(type_name: str) -> Any:
    """Python class of a message type (``pkg/msg/Type``).

    Raises
    ------
    ConfigError
        If the package or type is not installed.
    """
    import importlib

    pkg, _, name = _split(type_name)
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), name)
    except (ImportError, AttributeError) as err:
        raise ConfigError(f"type_name: unknown message type {type_name!r}") from err


def read_metadata(directory: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag."""
    data = yaml.safe_load((Path(directory) / "metadata.yaml").read_text())
    info: dict[str, Any] = data["rosbag2_bagfile_information"]
    return info


def read_messages(directory: Path, *, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
    """Deserialised messages of a bag in log-time order (our own reader)."""
    from rclpy.serialization import deserialize_message

    wanted = list(topics) if topics is not None else None
    classes: dict[str, Any] = {}
    for path in sorted(Path(directory).glob("*.mcap")):
        with path.open("rb") as f:
            for schema, channel, msg in make_reader(f).iter_messages(
                topics=wanted, log_time_order=True
            ):
                type_name = schema.name if schema is not None else ""
                cls = classes.get(type_name)
                if cls is None:
                    cls = classes[type_name] = message_class(type_name)
                yield BagMessage(
                    channel.topic, type_name, msg.log_time, deserialize_message(msg.data, cls)
                )
