"""recover_bag: a bag whose recorder died, made readable again by independent readers.

And split bags: one rosbag2 directory, several MCAP files, read as one by every reader.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml
from builtin_interfaces.msg import Time
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.__main__ import main as cli
from servo_axis.recording.errors import BagError, NoBagError, NotMcapError
from servo_axis.recording.reader import mcap_files, read_metadata, read_raw
from servo_axis.recording.recover import RecoveryReport, recover_bag
from servo_axis.recording.writer import MIN_SPLIT_SIZE_BYTES, BagWriter

TYPES = {
    "/state": "sensor_msgs/msg/JointState",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/status": "std_msgs/msg/Float64MultiArray",
    "/never": "std_msgs/msg/Float64MultiArray",
}

Written = list[tuple[str, int, bytes]]


def _time(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def batch(start: int, n: int) -> Written:
    """``n`` steps from ``start``: a state per step, a clock every 10, a status every 50.

    ``(topic, log time, payload)`` in write order, which is log-time order.
    """
    out: Written = []
    for k in range(start, start + n):
        t = k * 1_000_000
        js = JointState(name=["x_motor", "x_table"], position=[k * 1e-6, -k * 1e-9])
        js.header.stamp = _time(t)
        out.append(("/state", t, serialize_message(js)))
        # Distinct log times, so that every reader's order is the write order.
        if k % 10 == 0:
            out.append(("/clock", t + 1, serialize_message(Clock(clock=_time(t)))))
        if k % 50 == 0:
            out.append(("/status", t + 2, serialize_message(Float64MultiArray(data=[float(k)]))))
    return out


def open_writer(directory: Path, chunk_size: int = 1 << 20) -> BagWriter:
    writer = BagWriter(directory, chunk_size=chunk_size)
    for topic, type_name in TYPES.items():
        writer.add_topic(topic, type_name)
    return writer


def write(writer: BagWriter, messages: Written) -> None:
    for topic, t, data in messages:
        writer.write(topic, data, log_time_ns=t)


def killed_copy(data: bytes, directory: Path) -> Path:
    """What a SIGKILLed recorder leaves: the file's bytes as they were, no metadata.yaml."""
    directory.mkdir(parents=True)
    (directory / f"{directory.name}_0.mcap").write_bytes(data)
    return directory


def read_rosbags(bag: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, payload) in log-time order, with rosbags' rosbag2 reader."""
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


def read_mcap_ros2(bag: Path) -> list[tuple[str, int, Any]]:

    from mcap_ros2.decoder import DecoderFactory

    (path,) = bag.glob("*.mcap")
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [
            (m.channel.topic, m.message.log_time, m.decoded_message)
            for m in reader.iter_decoded_messages(log_time_order=True)
        ]


def snapshot(directory: Path) -> dict[str, tuple[bytes, int]]:
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(directory.iterdir())}


def test_flushed_messages_of_a_killed_writer_are_all_recovered(tmp_path: Path) -> None:
    messages = batch(0, 700) + batch(700, 300)
    writer = open_writer(tmp_path / "live" / "bag", chunk_size=16 * 1024)
    try:
        write(writer, messages[:900])
        writer.flush()
        flushed = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
        write(writer, messages[900:])  # written after the flush: still in the open chunk
        unflushed = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    finally:
        writer.close()
    bag = killed_copy(unflushed, tmp_path / "killed" / "bag")
    with pytest.raises(FileNotFoundError, match="metadata"):  # unreadable before recovery
        read_rosbags(bag)

    report = recover_bag(bag)

    # Everything up to the flush, and whole chunks beyond it (16 KiB ones filled since).
    got = read_rosbags(bag)
    assert len(got) >= 900
    assert got == messages[: len(got)]
    assert report.needed_recovery
    assert report.message_count == len(got)
    assert (report.first_log_time_ns, report.last_log_time_ns) == (0, got[-1][1])
    assert list(report.message_counts) == list(TYPES)  # every channel, the empty one too
    assert report.message_counts["/never"] == 0
    assert report.kept == bag / "bag_0.mcap.unfinished"
    assert report.kept.read_bytes() == unflushed  # the original is kept as it was
    # A flushed file recovers every message written before the flush.
    bag2 = killed_copy(flushed, tmp_path / "killed2" / "bag")
    assert recover_bag(bag2).dropped_bytes == 0
    assert read_rosbags(bag2) == (messages[:900])
    decoded = read_mcap_ros2(bag2)
    assert [(t, n) for t, n, _ in decoded] == [(t, n) for t, n, _ in read_rosbags(bag2)]
    states = [m for topic, _n, m in decoded if topic == "/state"]
    assert [list(s.position) for s in states[:2]] == [[0.0, 0.0], [1e-6, -1e-9]]


def test_a_strangers_channel_is_recovered_with_its_metadata_and_messages(tmp_path: Path) -> None:
    """A stranger's messages (a channel of their own, registered mid-recording) come back on
    a stranger's channel of the same topic, in the topic's order of arrival."""
    from servo_axis.recording.reader import read_raw

    who = "/junk 010f78fd316f8cfd0000000000002303"
    messages = batch(0, 300)
    writer = open_writer(tmp_path / "live" / "bag", chunk_size=8 * 1024)
    try:
        write(writer, messages[:150])
        for topic, t, data in messages[150:]:
            if topic == "/state":
                writer.write(topic, data, log_time_ns=t, stranger=who)
            writer.write(topic, data, log_time_ns=t)
        writer.flush()
        flushed = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    finally:
        writer.close()
    original = [
        (m.topic, m.sequence, m.stranger, m.data) for m in read_raw(tmp_path / "live" / "bag")
    ]
    extra = sum(1 for topic, _, _ in messages[150:] if topic == "/state")
    assert extra > 100
    bag = killed_copy(flushed, tmp_path / "killed" / "bag")
    report = recover_bag(bag)
    assert report.message_counts["/state"] == 300 + extra
    got = [(m.topic, m.sequence, m.stranger, m.data) for m in read_raw(bag)]
    assert sorted(got) == sorted(original)
    assert sum(1 for m in got if m[2] == who) == extra
    assert len(read_rosbags(bag)) == len(messages) + extra  # the topic's channels merged


def test_recovered_metadata_is_what_closing_the_writer_writes(tmp_path: Path) -> None:
    messages = batch(0, 400)
    writer = open_writer(tmp_path / "live" / "bag")
    write(writer, messages)
    writer.flush()
    data = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    writer.close()
    bag = killed_copy(data, tmp_path / "killed" / "bag")
    recover_bag(bag)
    closed = yaml.safe_load((tmp_path / "live" / "bag" / "metadata.yaml").read_text())
    recovered = yaml.safe_load((bag / "metadata.yaml").read_text())
    assert recovered == closed
    info = recovered["rosbag2_bagfile_information"]
    assert info["message_count"] == len(messages)
    assert info["duration"]["nanoseconds"] == 399 * 1_000_000
    # The MCAP file is a finished one: summary, statistics, the rosbag2 metadata record.

    with (bag / "bag_0.mcap").open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == len(messages)
        assert [m.name for m in reader.iter_metadata()] == ["rosbag2"]


def test_truncated_file_gives_every_message_of_its_complete_chunks(tmp_path: Path) -> None:

    parts = [batch(0, 300), batch(300, 300), batch(600, 300)]
    writer = open_writer(tmp_path / "live" / "bag")
    ends = []
    try:
        for part in parts:
            write(writer, part)
            writer.flush()  # one chunk per part, each followed by its message indexes
            ends.append((tmp_path / "live" / "bag" / "bag_0.mcap").stat().st_size)
        data = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    finally:
        writer.close()
    with (tmp_path / "live" / "bag" / "bag_0.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = [(c.chunk_start_offset, c.chunk_length) for c in summary.chunk_indexes]
    assert len(chunks) == 3
    third_start, third_length = chunks[2]
    # (cut at, messages recovered, bytes dropped: from the end of the last complete record)
    everything = parts[0] + parts[1] + parts[2]
    mid_second = chunks[1][0] + chunks[1][1] // 2
    mid_third = third_start + third_length // 2
    cases = {
        "mid second chunk": (mid_second, parts[0], mid_second - ends[0]),
        "after the second chunk's indexes": (ends[1], parts[0] + parts[1], 0),
        "mid third chunk": (mid_third, parts[0] + parts[1], mid_third - ends[1]),
        "third chunk one byte short": (
            third_start + third_length - 1,
            parts[0] + parts[1],
            third_start + third_length - 1 - ends[1],
        ),
        "third chunk whole, its indexes cut": (third_start + third_length + 5, everything, 5),
        "all flushed": (ends[2], everything, 0),
    }
    for i, (label, (size, expected, dropped)) in enumerate(cases.items()):
        bag = killed_copy(data[:size], tmp_path / f"cut{i}" / "bag")
        report = recover_bag(bag)
        assert read_rosbags(bag) == expected, label
        assert report.message_count == len(expected), label
        assert report.dropped_bytes == dropped, label
        assert report.kept is not None and report.kept.read_bytes() == data[:size], label


def test_killed_before_any_message_gives_an_empty_readable_bag(tmp_path: Path) -> None:
    writer = open_writer(tmp_path / "live" / "bag")
    data = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    writer.close()
    assert data.startswith(b"\x89MCAP0\r\n")  # the header reached the file at once
    for i, cut in enumerate((data, b"", data[:5])):
        bag = killed_copy(cut, tmp_path / f"k{i}" / "bag")
        report = recover_bag(bag)
        assert report.needed_recovery and report.message_count == 0
        assert read_rosbags(bag) == []


def test_complete_bag_is_left_unchanged(tmp_path: Path) -> None:
    messages = batch(0, 200)
    with open_writer(tmp_path / "bag") as writer:
        write(writer, messages)
    before = snapshot(tmp_path / "bag")
    report = recover_bag(tmp_path / "bag")
    assert snapshot(tmp_path / "bag") == before
    assert not report.needed_recovery and report.kept is None
    assert report.message_counts == {"/state": 200, "/clock": 20, "/status": 4, "/never": 0}
    assert (report.first_log_time_ns, report.last_log_time_ns) == (0, 199_000_000)
    assert "complete, nothing to recover" in report.line()


def test_complete_mcap_without_metadata_gets_only_its_metadata(tmp_path: Path) -> None:
    with open_writer(tmp_path / "bag") as writer:
        write(writer, batch(0, 100))
    mcap_before = snapshot(tmp_path / "bag")["bag_0.mcap"]
    expected = (tmp_path / "bag" / "metadata.yaml").read_text()
    (tmp_path / "bag" / "metadata.yaml").unlink()
    report = recover_bag(tmp_path / "bag")
    assert report.needed_recovery and report.kept is None
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    assert snapshot(tmp_path / "bag")["bag_0.mcap"] == mcap_before
    assert yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text()) == yaml.safe_load(
        expected
    )
    assert recover_bag(tmp_path / "bag").needed_recovery is False


def test_second_recovery_of_a_new_unfinished_file_keeps_both_originals(tmp_path: Path) -> None:
    writer = open_writer(tmp_path / "live" / "bag")
    write(writer, batch(0, 50))
    writer.flush()
    data = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    writer.close()
    bag = killed_copy(data, tmp_path / "k" / "bag")
    recover_bag(bag)
    (bag / "bag_0.mcap").write_bytes(data)  # unfinished again
    report = recover_bag(bag)
    assert report.kept == bag / "bag_0.mcap.unfinished.1"
    assert len(read_rosbags(bag)) == len(batch(0, 50))


def test_what_is_not_a_bag_is_refused_with_a_bag_error(tmp_path: Path) -> None:
    with pytest.raises(NoBagError, match="not a directory"):
        recover_bag(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(NoBagError, match=r"no \*\.mcap file"):
        recover_bag(tmp_path / "empty")
    (tmp_path / "text").mkdir()
    (tmp_path / "text" / "text_0.mcap").write_text("rosbag2_bagfile_information: {}\n")
    with pytest.raises(NotMcapError, match="not an MCAP file"):
        recover_bag(tmp_path / "text")
    assert sorted(p.name for p in (tmp_path / "text").iterdir()) == ["text_0.mcap"]
    (tmp_path / "two").mkdir()
    (tmp_path / "two" / "two_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    (tmp_path / "two" / "two_1.mcap").write_text("not mcap")
    with pytest.raises(NotMcapError, match=r"two_1\.mcap: not an MCAP file"):
        recover_bag(tmp_path / "two")  # a split bag: every file is checked first
    assert sorted(p.name for p in (tmp_path / "two").iterdir()) == ["two_0.mcap", "two_1.mcap"]
    assert issubclass(NoBagError, BagError) and issubclass(NotMcapError, BagError)


def test_command_line_prints_one_line_and_exits_2_on_a_bad_bag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    writer = open_writer(tmp_path / "live" / "bag")
    write(writer, batch(0, 1000))
    writer.flush()
    data = (tmp_path / "live" / "bag" / "bag_0.mcap").read_bytes()
    writer.close()
    bag = killed_copy(data, tmp_path / "k" / "bag")
    assert cli(["bag", "recover", str(bag)]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    assert "recovered 1120 messages (/state 1000, /clock 100, /status 20, /never 0;" in out
    assert "log times 0.000 s .. 0.999 s (0.999 s)" in out  # 990 ms + 2 ns: the last status
    assert cli(["bag", "recover", str(bag)]) == 0
    assert "complete, nothing to recover" in capsys.readouterr().out
    assert cli(["bag", "recover", str(tmp_path / "nothing")]) == 2
    assert "no bag there" in capsys.readouterr().err


def test_report_is_frozen(tmp_path: Path) -> None:
    report = RecoveryReport(tmp_path, {"/a": 1}, 0, 0, needed_recovery=True)
    with pytest.raises(AttributeError):
        report.needed_recovery = False  # type: ignore[misc]


def split_writer(directory: Path, **split: int) -> BagWriter:
    # Small chunks, so that the file grows on disk as messages come.
    writer = BagWriter(directory, chunk_size=2048, **split)
    for topic, type_name in TYPES.items():
        writer.add_topic(topic, type_name)
    return writer


def read_ours(bag: Path) -> Written:
    return [(m.topic, m.log_time_ns, m.data) for m in read_raw(bag)]


def test_split_by_size_lists_every_file_and_reads_as_one(tmp_path: Path) -> None:
    messages = batch(0, 3000)
    bag = tmp_path / "bag"
    with split_writer(bag, max_file_size_bytes=20_000) as writer:
        write(writer, messages)
    info = read_metadata(bag)
    names = [f"bag_{i}.mcap" for i in range(len(info["relative_file_paths"]))]
    assert len(names) >= 3, names
    assert info["relative_file_paths"] == names
    assert sorted(p.name for p in bag.glob("*.mcap")) == sorted(names)
    assert [f["path"] for f in info["files"]] == names
    assert (
        sum(f["message_count"] for f in info["files"]) == info["message_count"] == 3000 + 300 + 60
    )
    for name in names[:-1]:
        # Split once the file's data held the bound, past it by at most what the
        # writer had in hand: the chunk that crossed it and the one in progress,
        # with their message indexes (the summary follows; the footer says where).
        data = (bag / name).read_bytes()
        summary_start = int.from_bytes(data[-28:-20], "little")
        assert 20_000 <= summary_start < 20_000 + 3 * 2048, (name, summary_start)
    for name, entry in zip(names, info["files"], strict=True):
        with (bag / name).open("rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None
        assert sorted(c.topic for c in summary.channels.values()) == sorted(TYPES)
        assert summary.statistics.message_count == entry["message_count"]
        assert (
            summary.statistics.message_start_time
            == entry["starting_time"]["nanoseconds_since_epoch"]
        )
    assert read_ours(bag) == messages
    assert read_rosbags(bag) == messages  # an independent reader of rosbag2 directories


def test_split_by_duration_is_by_log_time(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    with split_writer(bag, max_file_duration_ns=250_000_000) as writer:
        write(writer, batch(0, 1000))
    # A file ends before the first message more than 250 ms after its first
    # (states at k ms, clocks at +1 ns, statuses at +2 ns): the clock at
    # 250 ms + 1 starts file 1, the status at 500 ms + 2 file 2 (whose status
    # at 750 ms + 2 is exactly 250 ms after its first), the state at 751 ms
    # file 3. File 0: states 0..250 ms, clocks 0..240 ms, statuses 0..200 ms.
    files = read_metadata(bag)["files"]
    assert [f["starting_time"]["nanoseconds_since_epoch"] for f in files] == [
        0,
        250_000_001,
        500_000_002,
        751_000_000,
    ]
    assert [f["duration"]["nanoseconds"] for f in files] == [250_000_000] * 3 + [248_000_000]
    assert [f["message_count"] for f in files] == [251 + 25 + 5, 281, 281, 1120 - 3 * 281]
    info = read_metadata(bag)
    assert info["starting_time"]["nanoseconds_since_epoch"] == 0
    assert info["duration"]["nanoseconds"] == 999_000_000


def test_split_bounds_are_checked_naming_the_argument(tmp_path: Path) -> None:
    for kwargs, match in (
        ({"max_file_size_bytes": -1}, "max_file_size_bytes: expected an int >= 0"),
        ({"max_file_size_bytes": MIN_SPLIT_SIZE_BYTES - 1}, "max_file_size_bytes: expected 0"),
        ({"max_file_duration_ns": 0.5}, "max_file_duration_ns: expected an int >= 0"),
        ({"max_file_duration_ns": 1, "file_name": "a.mcap"}, "file_name: a bag that splits"),
    ):
        with pytest.raises(BagError, match=match):
            BagWriter(tmp_path / "bad", **kwargs)  # type: ignore[arg-type]
        assert not (tmp_path / "bad").exists() or not any((tmp_path / "bad").iterdir())


def test_files_without_metadata_are_read_in_the_order_of_their_numbers(tmp_path: Path) -> None:
    for i in (0, 1, 2, 10, 11):
        (tmp_path / f"bag_{i}.mcap").write_bytes(b"")
    assert [p.name for p in mcap_files(tmp_path)] == [
        "bag_0.mcap",
        "bag_1.mcap",
        "bag_2.mcap",
        "bag_10.mcap",
        "bag_11.mcap",
    ]


def test_killed_split_bag_is_recovered_whole(tmp_path: Path) -> None:
    messages = batch(0, 2000)
    live = tmp_path / "live" / "bag"
    writer = split_writer(live, max_file_size_bytes=10_000)
    write(writer, messages)
    writer.flush()
    # What SIGKILL leaves: the finished files, the last one flushed but unfinished.
    bag = tmp_path / "k" / "bag"
    shutil.copytree(live, bag)
    writer.close()
    names = writer.file_names
    assert len(names) >= 3 and not (bag / "metadata.yaml").exists()
    assert read_ours(bag) == messages  # readable file by file, even before recovery
    report = recover_bag(bag)
    assert report.needed_recovery and report.files == len(names)
    assert report.kept == bag / f"{names[-1]}.unfinished"
    assert report.message_counts == {"/state": 2000, "/clock": 200, "/status": 40, "/never": 0}
    assert f"; {len(names)} files" in report.line()
    recovered = read_metadata(bag)
    closed = yaml.safe_load((live / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert recovered == closed  # as the recorder would have closed it
    assert read_rosbags(bag) == messages
    again = recover_bag(bag)
    assert not again.needed_recovery and again.message_count == 2240 and again.files == len(names)


def test_a_split_bags_writer_keeps_the_index_of_its_current_file_only(tmp_path: Path) -> None:
    """One MCAP file keeps an index of every chunk in memory until its summary is
    written: a recorder that flushes 4 times a second grows by it all run long."""
    import tracemalloc

    messages = batch(0, 20)  # a state a chunk at 80 Hz, say: the index is per chunk

    def growth(directory: Path, **split: int) -> list[int]:
        writer = open_writer(directory) if not split else split_writer(directory, **split)
        chunks = 0

        def chunk() -> None:
            nonlocal chunks
            for topic, t, data in messages:
                writer.write(topic, data, log_time_ns=t + chunks * 250_000_000)
            writer.flush()  # what the recorder does every 0.25 s
            chunks += 1

        for _ in range(10):
            chunk()
        kept = []
        tracemalloc.start()
        try:
            for _ in range(2):
                before = tracemalloc.get_traced_memory()[0]
                for _ in range(40):
                    chunk()
                kept.append(tracemalloc.get_traced_memory()[0] - before)
        finally:
            tracemalloc.stop()
            writer.close()
        return kept

    one = growth(tmp_path / "one")
    split = growth(tmp_path / "split", max_file_duration_ns=2_500_000_000)  # 10 chunks a file
    assert min(one) > 40 * 300, one  # the chunk indexes, hundreds of bytes each
    assert max(split[1:]) < 10 * 1_000, split  # at most a file's


def test_a_strangers_channel_is_in_every_file_after_its_first_message(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    messages = batch(0, 600)
    with split_writer(bag, max_file_duration_ns=200_000_000) as writer:
        write(writer, messages[:10])
        writer.write("/state", b"junk-a", log_time_ns=5_000_000, stranger="/x/junk 01.02")
        write(writer, messages[10:])
        writer.write("/state", b"junk-b", log_time_ns=599_000_000, stranger="/x/junk 01.02")
    names = read_metadata(bag)["relative_file_paths"]
    assert len(names) == 3
    for name in names:
        with (bag / name).open("rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None
        strangers = [c for c in summary.channels.values() if "stranger_publisher" in c.metadata]
        assert [(c.topic, c.metadata["stranger_publisher"]) for c in strangers] == [
            ("/state", "/x/junk 01.02")
        ]
    junk = [(m.data, m.stranger) for m in read_raw(bag) if m.stranger]
    assert junk == [(b"junk-a", "/x/junk 01.02"), (b"junk-b", "/x/junk 01.02")]
    counts = {
        t["topic_metadata"]["name"]: t["message_count"]
        for t in read_metadata(bag)["topics_with_message_count"]
    }
    assert counts["/state"] == 602  # the topic's, over its channels
