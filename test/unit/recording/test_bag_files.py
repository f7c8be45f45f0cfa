"""rosbag2-layout MCAP bags: written by BagWriter, read back by three independent readers.

No ROS graph: messages are made and serialised with rclpy.serialization.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from mcap.reader import make_reader
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.recording.definitions import SEPARATOR, message_definition, type_hash
from servo_axis.recording.deserialize import read_messages
from servo_axis.recording.errors import BagError, BagWriteError
from servo_axis.recording.reader import read_metadata, read_raw
from servo_axis.recording.writer import DEFAULT_QOS, BagWriter

N = 400
T0_NS = 1_700_000_000_123_456_789
JOINT_NAMES = ["x_motor", "x_table"]
LABELS = ["position_m", "velocity_mps", "current_A"]
TYPES = {
    "/state": "sensor_msgs/msg/JointState",
    "/trace": "std_msgs/msg/Float64MultiArray",
    "/clock": "rosgraph_msgs/msg/Clock",
}
SPECIAL = [0.0, -0.0, 1e-300, -1e300, 5e-324, math.pi, math.inf, -math.inf]


# ----------------------------------------------------------------- messages


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def make_messages(n: int = N) -> list[tuple[str, int, Any]]:
    """(topic, log_time_ns, message) in log-time order, distinct times, all three topics."""
    rng = np.random.default_rng(7)
    out: list[tuple[str, int, Any]] = []
    for k in range(n):
        t = T0_NS + k * 1_000_000
        js = JointState()
        js.header.stamp = _stamp(k * 1_000_000)
        js.header.frame_id = f"axis_{k % 3}"
        js.name = list(JOINT_NAMES)
        js.position = rng.normal(size=2).tolist()
        js.velocity = (rng.normal(size=2) * 1e3).tolist()
        js.effort = [SPECIAL[k % len(SPECIAL)], float(rng.uniform(-5, 5))]
        out.append(("/state", t, js))

        fa = Float64MultiArray()
        rows = 1 + k % 3
        fa.layout.dim = [
            MultiArrayDimension(label="step", size=rows, stride=rows * len(LABELS)),
            MultiArrayDimension(label=",".join(LABELS), size=len(LABELS), stride=len(LABELS)),
        ]
        fa.layout.data_offset = k % 5
        fa.data = rng.normal(size=rows * len(LABELS)).tolist()
        out.append(("/trace", t + 300_000, fa))

        out.append(("/clock", t + 600_000, Clock(clock=_stamp(k * 1_000_000))))
    return out


def write_bag(
    directory: Path,
    messages: list[tuple[str, int, Any]],
    *,
    compression: str = "zstd",
    chunk_size: int = 16 * 1024,
) -> BagWriter:
    with BagWriter(directory, compression=compression, chunk_size=chunk_size) as writer:
        for topic, type_name in TYPES.items():
            writer.add_topic(topic, type_name)
        for topic, t, msg in messages:
            writer.write(topic, serialize_message(msg), log_time_ns=t)
    return writer


def write_payloads(directory: Path, messages: list[tuple[str, int, Any]]) -> list[bytes]:
    """Write a bag like :func:`write_bag`; return the payloads in write order.

    ``serialize_message`` may pad its buffer with arbitrary bytes, so a payload
    is compared with the bytes that were written, not with a new serialisation.
    """
    payloads = [serialize_message(msg) for _topic, _t, msg in messages]
    with BagWriter(directory) as writer:
        for topic, type_name in TYPES.items():
            writer.add_topic(topic, type_name)
        for (topic, t, _msg), data in zip(messages, payloads, strict=True):
            writer.write(topic, data, log_time_ns=t)
    return payloads


# --------------------------------------------------- plain form for comparison


def _time(t: Any) -> tuple[int, int]:
    return int(t.sec), int(t.nanosec)


def plain(topic: str, msg: Any) -> dict[str, Any]:
    """Fields of a message from any reader (rclpy, rosbags, mcap_ros2) as plain values."""
    if topic == "/state":
        return {
            "stamp": _time(msg.header.stamp),
            "frame_id": str(msg.header.frame_id),
            "name": [str(x) for x in msg.name],
            "position": np.asarray(msg.position, dtype=float),
            "velocity": np.asarray(msg.velocity, dtype=float),
            "effort": np.asarray(msg.effort, dtype=float),
        }
    if topic == "/trace":
        return {
            "dim": [(str(d.label), int(d.size), int(d.stride)) for d in msg.layout.dim],
            "data_offset": int(msg.layout.data_offset),
            "data": np.asarray(msg.data, dtype=float),
        }
    assert topic == "/clock"
    return {"clock": _time(msg.clock)}


def assert_same(
    expected: list[tuple[str, int, Any]], got: list[tuple[str, int, Any]], reader: str
) -> None:
    """Every message (topic, log time and every field) equal, in log-time order."""
    assert len(got) == len(expected), reader
    for (et, etime, emsg), (gt, gtime, gmsg) in zip(expected, got, strict=True):
        assert (gt, gtime) == (et, etime), reader
        a, b = plain(et, emsg), plain(gt, gmsg)
        assert a.keys() == b.keys()
        for key, value in a.items():
            if isinstance(value, np.ndarray):
                np.testing.assert_allclose(b[key], value, rtol=0, atol=0, err_msg=f"{reader} {key}")
                # -0.0 and 0.0 compare equal: the sign bit must survive too
                assert np.array_equal(np.signbit(b[key]), np.signbit(value)), reader
            else:
                assert b[key] == value, f"{reader} {key}"


# ------------------------------------------------------------------ readers


def read_rosbags_anyreader(bag: Path, typestore: Any | None) -> list[tuple[str, int, Any]]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag], default_typestore=typestore) as reader:
        return [
            (conn.topic, t, reader.deserialize(raw, conn.msgtype))
            for conn, t, raw in reader.messages()
        ]


def read_rosbags_rosbag2(bag: Path) -> tuple[list[tuple[str, int, Any]], dict[str, int]]:
    """rosbags.rosbag2.Reader with the types parsed from the bag's own definitions."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    typestore = get_typestore(Stores.EMPTY)
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        for conn in reader.connections:
            assert conn.msgdef.data, f"{conn.topic}: no message definition in the bag"
            typestore.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        out = [
            (conn.topic, t, typestore.deserialize_cdr(raw, conn.msgtype))
            for conn, t, raw in reader.messages()
        ]
    return out, counts


def read_mcap_ros2(bag: Path) -> list[tuple[str, int, Any]]:
    from mcap_ros2.decoder import DecoderFactory

    (mcap_file,) = bag.glob("*.mcap")
    with mcap_file.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [
            (m.channel.topic, m.message.log_time, m.decoded_message)
            for m in reader.iter_decoded_messages(log_time_order=True)
        ]


def read_ours(bag: Path) -> list[tuple[str, int, Any]]:
    out = []
    for m in read_messages(bag):
        assert m.type_name == TYPES[m.topic]
        out.append((m.topic, m.log_time_ns, m.message))
    return out


def jazzy_typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


READERS: dict[str, Callable[[Path], list[tuple[str, int, Any]]]] = {
    "rosbags AnyReader (jazzy typestore)": lambda b: read_rosbags_anyreader(b, jazzy_typestore()),
    "rosbags AnyReader (bag definitions)": lambda b: read_rosbags_anyreader(b, None),
    "rosbags rosbag2.Reader": lambda b: read_rosbags_rosbag2(b)[0],
    "mcap_ros2 DecoderFactory": read_mcap_ros2,
    "servo_axis read_messages": read_ours,
}


def counts_of(messages: list[tuple[str, int, Any]]) -> dict[str, int]:
    out = dict.fromkeys(TYPES, 0)
    for topic, _t, _m in messages:
        out[topic] += 1
    return out


@dataclass
class Bag:
    path: Path
    messages: list[tuple[str, int, Any]]
    writer: BagWriter


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bag]:
    messages = make_messages()
    path = tmp_path_factory.mktemp("bags") / "run"
    writer = write_bag(path, messages)
    yield Bag(path, messages, writer)


# -------------------------------------------------------------- definitions


def test_joint_state_definition_has_each_nested_type_once() -> None:
    text = message_definition("sensor_msgs/msg/JointState")
    assert text.count("MSG: std_msgs/Header\n") == 1
    assert text.count("MSG: builtin_interfaces/Time\n") == 1
    assert text.count(SEPARATOR + "\n") == 2
    assert text.index("MSG: std_msgs/Header") < text.index("MSG: builtin_interfaces/Time")
    assert text.startswith("# This is a message that holds data")
    assert "\nfloat64[] effort\n" in text and "\nstd_msgs/Header header\n" in text
    # the short form of the name gives the same text
    assert message_definition("sensor_msgs/JointState") == text


def test_nested_definitions_of_other_types() -> None:
    fma = message_definition("std_msgs/msg/Float64MultiArray")
    assert [line for line in fma.splitlines() if line.startswith("MSG: ")] == [
        "MSG: std_msgs/MultiArrayLayout",  # unqualified name, same package
        "MSG: std_msgs/MultiArrayDimension",
    ]
    clock = message_definition("rosgraph_msgs/msg/Clock")
    assert [line for line in clock.splitlines() if line.startswith("MSG: ")] == [
        "MSG: builtin_interfaces/Time"
    ]
    # a type used twice in the tree (Header -> Time, and Time itself) appears once
    odom = message_definition("nav_msgs/msg/Odometry")
    heads = [line for line in odom.splitlines() if line.startswith("MSG: ")]
    assert len(heads) == len(set(heads)) and "MSG: geometry_msgs/Point" in heads


def test_definition_parses_in_independent_parsers() -> None:
    from mcap_ros2._dynamic import generate_dynamic
    from rosbags.typesys import get_types_from_msg

    nested = {
        "sensor_msgs/msg/JointState": {"std_msgs/msg/Header", "builtin_interfaces/msg/Time"},
        "std_msgs/msg/Float64MultiArray": {
            "std_msgs/msg/MultiArrayLayout",
            "std_msgs/msg/MultiArrayDimension",
        },
        "rosgraph_msgs/msg/Clock": {"builtin_interfaces/msg/Time"},
    }
    for type_name in TYPES.values():
        text = message_definition(type_name)
        assert set(get_types_from_msg(text, type_name)) == {type_name} | nested[type_name]
        assert type_name in generate_dynamic(type_name, text)


def test_type_hash_is_the_rihs01_of_the_type() -> None:
    store = jazzy_typestore()
    for type_name in TYPES.values():
        digest = type_hash(type_name)
        assert digest is not None and digest.startswith("RIHS01_") and len(digest) == 71
        assert digest == store.hash_rihs01(type_name)
    assert type_hash("no_such_pkg/msg/Nothing") is None


def test_unknown_type_rejected_naming_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no_such_pkg/msg/Nothing"):
        message_definition("no_such_pkg/msg/Nothing")
    with BagWriter(tmp_path / "b") as writer:
        with pytest.raises(ConfigError, match="sensor_msgs/msg/NoSuchType"):
            writer.add_topic("/x", "sensor_msgs/msg/NoSuchType")
        with pytest.raises(ConfigError, match="not_a_type"):
            writer.add_topic("/x", "not_a_type")


# ------------------------------------------------------------------- writer


def test_metadata_yaml_matches_what_was_written(bag: Bag) -> None:
    info = read_metadata(bag.path)
    expected = counts_of(bag.messages)
    assert expected == dict.fromkeys(TYPES, N)
    assert bag.writer.message_counts == expected
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["ros_distro"] == "jazzy"
    assert info["compression_format"] == "" and info["compression_mode"] == ""
    assert info["custom_data"] == {}
    assert info["relative_file_paths"] == ["run_0.mcap"]
    assert info["message_count"] == 3 * N
    first, last = bag.messages[0][1], bag.messages[-1][1]
    assert info["starting_time"]["nanoseconds_since_epoch"] == first
    assert info["duration"]["nanoseconds"] == last - first
    (file_info,) = info["files"]
    assert file_info == {
        "path": "run_0.mcap",
        "starting_time": {"nanoseconds_since_epoch": first},
        "duration": {"nanoseconds": last - first},
        "message_count": 3 * N,
    }
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {name: t["message_count"] for name, t in topics.items()} == expected
    with (bag.path / "run_0.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    channels = {c.topic: c for c in summary.channels.values()}
    assert {channels[t].id: n for t, n in expected.items()} == dict(
        summary.statistics.channel_message_counts
    )
    for name, type_name in TYPES.items():
        meta = topics[name]["topic_metadata"]
        assert meta["type"] == type_name and meta["serialization_format"] == "cdr"
        assert meta["offered_qos_profiles"] == DEFAULT_QOS
        assert channels[name].metadata["offered_qos_profiles"] == DEFAULT_QOS
        assert meta["type_description_hash"] == type_hash(type_name)
        assert channels[name].metadata["topic_type_hash"] == type_hash(type_name)
        assert channels[name].message_encoding == "cdr"
        schema = summary.schemas[channels[name].schema_id]
        assert (schema.name, schema.encoding) == (type_name, "ros2msg")
        assert schema.data.decode() == message_definition(type_name)
    # the rosbag2 metadata record holds the same metadata
    with (bag.path / "run_0.mcap").open("rb") as f:
        records = list(make_reader(f).iter_metadata())
    (record,) = [r for r in records if r.name == "rosbag2"]
    assert yaml.safe_load(record.metadata["serialized_metadata"]) == info


def test_sequences_per_channel_and_header(bag: Bag) -> None:
    with (bag.path / "run_0.mcap").open("rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        seqs: dict[str, list[int]] = {}
        for _s, channel, msg in reader.iter_messages(log_time_order=False):
            seqs.setdefault(channel.topic, []).append(msg.sequence)
            assert msg.publish_time == msg.log_time
    assert header.profile == "ros2" and "servo_axis" in header.library
    assert seqs == {t: list(range(1, N + 1)) for t in TYPES}


@pytest.mark.parametrize("reader", list(READERS))
def test_every_reader_gets_every_field_back(bag: Bag, reader: str) -> None:
    got = READERS[reader](bag.path)
    assert counts_of(got) == dict.fromkeys(TYPES, N)
    assert_same(bag.messages, got, reader)


def test_reader_counts_equal_metadata(bag: Bag) -> None:
    from rosbags.highlevel import AnyReader

    info = read_metadata(bag.path)
    in_metadata = {
        t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]
    }
    _msgs, rosbag2_counts = read_rosbags_rosbag2(bag.path)
    with AnyReader([bag.path], default_typestore=jazzy_typestore()) as reader:
        any_counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.message_count == 3 * N
        assert reader.start_time == bag.messages[0][1]
    assert rosbag2_counts == any_counts == in_metadata == dict.fromkeys(TYPES, N)


def test_read_messages_filters_topics(bag: Bag) -> None:
    got = [(m.topic, m.log_time_ns, m.message) for m in read_messages(bag.path, topics=["/clock"])]
    assert_same([m for m in bag.messages if m[0] == "/clock"], got, "read_messages /clock")


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_other_compressions_read_back(tmp_path: Path, compression: str) -> None:
    messages = make_messages(50)
    write_bag(tmp_path / "b", messages, compression=compression)
    for name, reader in READERS.items():
        assert_same(messages, reader(tmp_path / "b"), f"{name} ({compression})")


def test_bag_closed_after_an_error_mid_run_reads_back(tmp_path: Path) -> None:
    messages = make_messages(300)
    path = tmp_path / "partial"

    class CrashError(RuntimeError):
        pass

    written = 0
    with pytest.raises(CrashError):
        writer = BagWriter(path, chunk_size=4096)
        try:
            for topic, type_name in TYPES.items():
                writer.add_topic(topic, type_name)
            for topic, t, msg in messages:
                if written == 437:
                    raise CrashError("controller diverged")
                writer.write(topic, serialize_message(msg), log_time_ns=t)
                written += 1
        finally:
            writer.close()
    expected = messages[:written]
    info = read_metadata(path)
    assert info["message_count"] == written
    in_metadata = {
        t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]
    }
    assert in_metadata == counts_of(expected) == writer.message_counts
    for name, reader in READERS.items():
        assert_same(expected, reader(path), name)


def test_bag_with_no_messages_reads_back(tmp_path: Path) -> None:
    write_bag(tmp_path / "empty", [])
    info = read_metadata(tmp_path / "empty")
    assert info["message_count"] == 0
    for name, reader in READERS.items():
        assert reader(tmp_path / "empty") == [], name


def test_flushed_but_unclosed_bag_reads_with_our_reader(tmp_path: Path) -> None:
    messages = make_messages(40)
    writer = BagWriter(tmp_path / "open", chunk_size=1 << 20)
    for topic, type_name in TYPES.items():
        writer.add_topic(topic, type_name)
    for topic, t, msg in messages:
        writer.write(topic, serialize_message(msg), log_time_ns=t)
    writer.flush()
    # no summary, no metadata.yaml yet (as after a SIGKILL)
    assert not (tmp_path / "open" / "metadata.yaml").exists()
    got = [(m.topic, m.log_time_ns, m.message) for m in read_messages(tmp_path / "open")]
    assert_same(messages, got, "read_messages of an unfinished file")
    writer.close()
    assert read_metadata(tmp_path / "open")["message_count"] == len(messages)


def test_out_of_order_log_times_are_read_in_order(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        for t in (30, 10, 20):
            writer.write("/clock", serialize_message(Clock(clock=_stamp(t))), log_time_ns=t)
    info = read_metadata(tmp_path / "b")
    assert info["starting_time"]["nanoseconds_since_epoch"] == 10
    assert info["duration"]["nanoseconds"] == 20
    assert [m.message.clock.nanosec for m in read_messages(tmp_path / "b")] == [10, 20, 30]


@pytest.mark.parametrize("sorted_in_memory", [True, False])
def test_read_raw_keeps_mcaps_log_time_order_over_chunks_and_ties(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sorted_in_memory: bool
) -> None:
    """Read whole and sorted, or streamed in mcap's log-time order: the same order,
    equal log times in file order, across chunks whose times overlap."""
    from servo_axis.recording import reader

    monkeypatch.setattr(reader, "SORTED_IN_MEMORY_MESSAGES", 10**9 if sorted_in_memory else 0)
    rng = np.random.default_rng(7)
    times = [int(t) for t in rng.integers(0, 40, size=300)]  # many ties, out of order
    with BagWriter(tmp_path / "b", chunk_size=512) as writer:
        writer.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        writer.add_topic("/trace", "std_msgs/msg/Float64MultiArray")
        for i, t in enumerate(times):
            if i % 2:
                payload = serialize_message(Float64MultiArray(data=[float(i)]))
                writer.write("/trace", payload, log_time_ns=t)
            else:
                writer.write("/clock", serialize_message(Clock(clock=_stamp(i))), log_time_ns=t)
    (path,) = (tmp_path / "b").glob("*.mcap")
    with path.open("rb") as f:
        mcap_reader = make_reader(f)
        assert len(mcap_reader.get_summary().chunk_indexes) > 10
        expected = [
            (c.topic, m.log_time, bytes(m.data))
            for _s, c, m in mcap_reader.iter_messages(log_time_order=True)
        ]
    got = [(r.topic, r.log_time_ns, r.data) for r in read_raw(tmp_path / "b")]
    assert got == expected
    assert [t for _topic, t, _d in got] == sorted(times)


# --------------------------------------------------------------- validation


def test_write_to_unregistered_topic_names_it(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        data = serialize_message(Clock())
        with pytest.raises(SignalError, match="/not_registered"):
            writer.write("/not_registered", data, log_time_ns=1)
        with pytest.raises(SignalError, match="log_time_ns"):
            writer.write("/clock", data, log_time_ns=-1)
        with pytest.raises(SignalError, match="log_time_ns"):
            writer.write("/clock", data, log_time_ns=1.5)  # type: ignore[arg-type]
        with pytest.raises(ConfigError, match="/clock"):
            writer.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        with pytest.raises(ConfigError, match="qos_text"):
            writer.add_topic("/c2", "rosgraph_msgs/msg/Clock", qos_text="history: keep_last")
        writer.write("/clock", data, log_time_ns=np.int64(5))  # type: ignore[arg-type]
    assert writer.message_counts == {"/clock": 1}
    writer.close()  # idempotent
    with pytest.raises(SignalError, match="closed"):
        writer.write("/clock", data, log_time_ns=6)


def test_writer_arguments_validated(tmp_path: Path) -> None:
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(ConfigError, match="not empty"):
        BagWriter(tmp_path / "full")
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="not a directory"):
        BagWriter(tmp_path / "file")
    with pytest.raises(ConfigError, match="compression"):
        BagWriter(tmp_path / "c", compression="gzip")
    with pytest.raises(ConfigError, match="chunk_size"):
        BagWriter(tmp_path / "c", chunk_size=0)
    (tmp_path / "empty").mkdir()
    BagWriter(tmp_path / "empty").close()  # an existing empty directory is fine
    assert (tmp_path / "empty" / "empty_0.mcap").is_file()


def test_custom_qos_text_is_the_same_in_channel_and_metadata(tmp_path: Path) -> None:
    qos = DEFAULT_QOS.replace("reliability: reliable", "reliability: best_effort").replace(
        "depth: 2000", "depth: 1"
    )
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic("/clock", "rosgraph_msgs/msg/Clock", qos_text=qos)
        writer.write("/clock", serialize_message(Clock(clock=_stamp(1))), log_time_ns=1)
    (topic,) = read_metadata(tmp_path / "b")["topics_with_message_count"]
    assert topic["topic_metadata"]["offered_qos_profiles"] == qos
    got = read_rosbags_anyreader(tmp_path / "b", jazzy_typestore())
    assert [(t, n) for t, n, _m in got] == [("/clock", 1)]


# ----------------------------------------------------------------- raw reader


def test_read_raw_gives_what_read_messages_and_mcap_give(
    bag: Bag, raw_payloads: Callable[[Path], dict[str, list[bytes]]]
) -> None:
    raw = list(read_raw(bag.path))
    decoded = list(read_messages(bag.path))
    assert [(r.topic, r.type_name, r.log_time_ns) for r in raw] == [
        (m.topic, m.type_name, m.log_time_ns) for m in decoded
    ]
    assert [(r.topic, r.log_time_ns) for r in raw] == [(t, n) for t, n, _m in bag.messages]
    assert all(type(r.data) is bytes for r in raw)
    # payloads byte for byte as the mcap library reads them, per topic in write order
    per_topic: dict[str, list[bytes]] = {}
    for r in raw:
        per_topic.setdefault(r.topic, []).append(r.data)
    assert per_topic == raw_payloads(bag.path)
    # and each payload is the message read_messages returned
    for r, m in zip(raw, decoded, strict=True):
        assert deserialize_message(r.data, type(m.message)) == m.message


def test_read_raw_payloads_are_the_written_bytes(tmp_path: Path) -> None:
    messages = make_messages(30)
    payloads = write_payloads(tmp_path / "b", messages)
    raw = list(read_raw(tmp_path / "b"))
    assert [(r.topic, r.type_name, r.log_time_ns, r.data) for r in raw] == [
        (topic, TYPES[topic], t, data)
        for (topic, t, _m), data in zip(messages, payloads, strict=True)
    ]
    got = list(read_raw(tmp_path / "b", topics=iter(["/trace", "/clock"])))
    assert [(r.topic, r.log_time_ns, r.data) for r in got] == [
        (topic, t, data)
        for (topic, t, _m), data in zip(messages, payloads, strict=True)
        if topic in ("/trace", "/clock")
    ]


def test_read_raw_decodes_with_the_ros_free_cdr_decoders(bag: Bag) -> None:
    """The analysis path (read_raw, then servo_axis.wire.cdr) gets every field back."""
    from servo_axis.wire.cdr import decode

    got = []
    for r in read_raw(bag.path):
        d: Any = decode(r.type_name, r.data)
        if r.topic == "/state":
            sec, nanosec = divmod(d.stamp_ns, 1_000_000_000)
            msg: Any = JointState(name=list(d.name), position=d.position)
            msg.header.stamp, msg.header.frame_id = Time(sec=sec, nanosec=nanosec), d.frame_id
            msg.velocity, msg.effort = d.velocity, d.effort
        elif r.topic == "/trace":
            msg = Float64MultiArray(data=d.data)
            msg.layout.dim = [
                MultiArrayDimension(label=label, size=size, stride=stride)
                for label, size, stride in zip(d.labels, d.sizes, d.strides, strict=True)
            ]
            msg.layout.data_offset = d.data_offset
        else:
            msg = Clock(clock=_stamp(d.stamp_ns))
        got.append((r.topic, r.log_time_ns, msg))
    assert_same(bag.messages, got, "read_raw + wire.cdr")


def test_unfinished_truncated_bag_yields_every_complete_record(tmp_path: Path) -> None:
    messages = make_messages(60)
    first, second = messages[:90], messages[90:]
    writer = BagWriter(tmp_path / "open", chunk_size=1 << 20)
    try:
        for topic, type_name in TYPES.items():
            writer.add_topic(topic, type_name)
        payloads = []
        for part in (first, second):
            for topic, t, msg in part:
                payloads.append(serialize_message(msg))
                writer.write(topic, payloads[-1], log_time_ns=t)
            writer.flush()
            if part is first:
                size_first = (tmp_path / "open" / "open_0.mcap").stat().st_size
        data = (tmp_path / "open" / "open_0.mcap").read_bytes()
    finally:
        writer.close()
    expected = [(topic, t, p) for (topic, t, _m), p in zip(messages, payloads, strict=True)]
    # What a killed recorder leaves: no summary, no metadata.yaml, the file cut anywhere.
    # Every complete chunk is read, and nothing of a chunk cut short.
    cuts = {*range(0, len(data), 97), size_first - 1, size_first, len(data) - 1, len(data)}
    for size in sorted(cuts):
        bag_dir = tmp_path / f"cut_{size}"
        bag_dir.mkdir()
        (bag_dir / f"cut_{size}_0.mcap").write_bytes(data[:size])
        got = [(r.topic, r.log_time_ns, r.data) for r in read_raw(bag_dir)]
        # whole chunks: none, the first (flushed before size_first) or both
        least = len(messages) if size == len(data) else len(first) if size >= size_first else 0
        assert got in [expected[:n] for n in (0, len(first), len(messages)) if n >= least], size
    assert {len(first), len(messages)} <= {
        len(list(read_raw(tmp_path / f"cut_{size}"))) for size in cuts
    }


def test_errors_are_the_core_errors_they_were(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="compression"):
        BagWriter(tmp_path / "c", compression="gzip")
    with pytest.raises(BagError, match="metadata"):
        read_metadata(tmp_path)
    with BagWriter(tmp_path / "b") as writer:
        with pytest.raises(BagWriteError, match="/nothing"):
            writer.write("/nothing", b"", log_time_ns=0)
    assert issubclass(BagError, ConfigError) and issubclass(BagWriteError, SignalError)
    assert not issubclass(BagError, SignalError) and not issubclass(BagWriteError, ConfigError)
