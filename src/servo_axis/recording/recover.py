"""Make a bag whose recorder died readable again (like ``ros2 bag reindex``).

A recorder killed mid-run (SIGKILL, a crash, a power cut of the process)
leaves an *unfinished* bag: ``<name>_0.mcap`` without the MCAP summary and
footer, possibly cut inside its last record, and no ``metadata.yaml``.
Readers that start from the summary (rosbags, ``mcap`` ``SeekingReader``) or
from ``metadata.yaml`` cannot read it. :func:`recover_bag`

1. reads the file front to back (``mcap``'s :class:`~mcap.stream_reader.StreamReader`,
   which needs no summary) and keeps every complete record: the schemas,
   the channels and every message of every chunk that is whole and passes
   its CRC, up to the first record that is cut short or damaged (what
   follows it is dropped; a killed process only ever loses the end);
2. writes them, in the order they were recorded, with log and publish
   times unchanged, through :class:`~servo_axis.recording.writer.BagWriter`
   into a new file of the same name, with the same schemas and channel
   metadata (QoS text, type hash) and the first chunk's compression, and
   closes it, which writes the summary, the footer and ``metadata.yaml``
   exactly as a recorder that closed its bag does (one code path);
3. keeps the original file as ``<name>_0.mcap.unfinished`` (``.unfinished.1``
   ... if that exists) and puts the new file in its place (the bag's MCAP
   file exists at every moment: the original is hard-linked, or copied,
   before it is replaced).

A bag that is already complete (an MCAP file with its summary and
``metadata.yaml``) is left untouched. A complete MCAP file without
``metadata.yaml`` (the process died between the two) gets its
``metadata.yaml`` and nothing else.

A split bag (``bag_0.mcap``, ``bag_1.mcap``, ...: the recorder's
``max_bag_size_bytes``, ``max_bag_duration_s``) whose recorder was killed
has its earlier files complete (each was finished when the next began) and
its last one unfinished: each unfinished file is recovered as above, and
``metadata.yaml`` lists every file, with the counts and times of their
summaries.

Only the ``mcap`` and ``yaml`` packages are used: no ROS is needed.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from servo_axis.recording.errors import BagError, NoBagError, NotMcapError
from servo_axis.recording.reader import (
    STRANGER_KEY,
    UNFINISHED_SUFFIX,
    mcap_files,
    read_metadata,
)
from servo_axis.recording.writer import (
    DEFAULT_QOS,
    BagFile,
    BagWriter,
    bagfile_information,
    dump_yaml,
)

__all__ = ["UNFINISHED_SUFFIX", "RecoveryReport", "recover_bag"]


_MAGIC = b"\x89MCAP0\r\n"
_COMPRESSIONS = {"zstd": "zstd", "lz4": "lz4", "": "none"}


@dataclass(frozen=True)
class RecoveryReport:
    """What :func:`recover_bag` found and did.

    Attributes
    ----------
    path : Path
        The bag directory.
    message_counts : dict of str to int
        Messages per topic in the (recovered) bag, every channel's topic,
        in channel order.
    first_log_time_ns, last_log_time_ns : int or None
        Smallest and largest log time (ns); None without messages.
    needed_recovery : bool
        Whether anything was written (False: the bag was complete).
    kept : Path or None
        Where the original MCAP file was kept (None if it was not replaced;
        of a split bag, the last file's that was).
    dropped_bytes : int
        Bytes at the end of the original file that held no complete record
        (a chunk cut short by the kill, or damaged); of a split bag, of
        all its files.
    files : int
        The bag's MCAP files (several: a split bag).
    """

    path: Path
    message_counts: dict[str, int] = field(default_factory=dict)
    first_log_time_ns: int | None = None
    last_log_time_ns: int | None = None
    needed_recovery: bool = False
    kept: Path | None = None
    dropped_bytes: int = 0
    files: int = 1

    @property
    def recovered(self) -> bool:
        """Whether the bag was recovered (the same as :attr:`needed_recovery`)."""
        return self.needed_recovery

    @property
    def message_count(self) -> int:
        """Messages in the bag, all topics."""
        return sum(self.message_counts.values())

    def line(self) -> str:
        """The result in one line: messages per topic and time span."""
        counts = ", ".join(f"{t} {n}" for t, n in self.message_counts.items()) or "no topics"
        if self.first_log_time_ns is None or self.last_log_time_ns is None:
            span = "no log times"
        else:
            first, last = self.first_log_time_ns / 1e9, self.last_log_time_ns / 1e9
            span = f"log times {first:.3f} s .. {last:.3f} s ({last - first:.3f} s)"
        if self.files > 1:
            span += f"; {self.files} files"
        if not self.needed_recovery:
            return (
                f"{self.path}: complete, nothing to recover "
                f"({self.message_count} messages: {counts}; {span})"
            )
        if self.kept is None:
            what = "the MCAP file was complete, metadata.yaml written"
        elif self.dropped_bytes:
            what = (
                f"original kept as {self.kept.name}, its last {self.dropped_bytes} bytes "
                "(an incomplete record) dropped"
            )
        else:
            what = f"original kept as {self.kept.name}, it ended on a complete record"
        return f"{self.path}: recovered {self.message_count} messages ({counts}; {span}); {what}"


def recover_bag(bag_dir: Path) -> RecoveryReport:
    """Make an unfinished bag readable again; leave a complete one as it is.

    Parameters
    ----------
    bag_dir : Path
        The bag directory (``metadata.yaml`` and its ``*.mcap`` files, or
        MCAP files alone).

    Returns
    -------
    RecoveryReport
        Messages per topic, the log-time span, whether anything was done.

    Raises
    ------
    NoBagError
        If ``bag_dir`` is not a directory or holds no MCAP file.
    NotMcapError
        If the bag's file does not start with the MCAP magic.
    BagError
        If a file of the bag is an MCAP file of another profile than
        rosbag2's (``ros2msg`` schemas, ``cdr`` messages).
    OSError
        If a file cannot be read or written.
    """
    bag_dir = Path(bag_dir)
    if not bag_dir.is_dir():
        raise NoBagError(f"{bag_dir}: no bag there (not a directory)")
    try:
        info: dict[str, Any] | None = read_metadata(bag_dir)
    except BagError:
        info = None
    paths = _mcap_paths(bag_dir, info)
    for path in paths:
        _check_magic(path)
    summaries = [_summary_counts(p) for p in paths]
    if info is not None and all(c is not None for c in summaries):
        return RecoveryReport(bag_dir, *_merged(summaries), needed_recovery=False, files=len(paths))

    tmp = Path(tempfile.mkdtemp(dir=bag_dir, prefix=".recover-"))
    kept = None
    dropped = 0
    try:
        for path, complete in zip(paths, summaries, strict=True):
            if complete is not None:
                continue
            work = tmp / path.stem
            with path.open("rb") as f:
                _, good_end = _copy_records(f, work, path.name)
            dropped += path.stat().st_size - good_end
            kept = _free_name(path)
            try:
                os.link(path, kept)
            except OSError:
                shutil.copy2(path, kept)
            os.replace(work / path.name, path)
        files, topics = _files_and_topics(paths)
        text = dump_yaml({"rosbag2_bagfile_information": bagfile_information(topics, files)})
        (tmp / "metadata.yaml").write_text(text)
        os.replace(tmp / "metadata.yaml", bag_dir / "metadata.yaml")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    counts = {str(m["name"]): n for m, n in topics}
    firsts = [f.first_ns for f in files if f.first_ns is not None]
    lasts = [f.last_ns for f in files if f.last_ns is not None]
    return RecoveryReport(
        bag_dir,
        counts,
        min(firsts) if firsts else None,
        max(lasts) if lasts else None,
        needed_recovery=True,
        kept=kept,
        dropped_bytes=dropped,
        files=len(paths),
    )


def _mcap_paths(bag_dir: Path, info: dict[str, Any] | None) -> list[Path]:
    """The bag's MCAP files (named by ``metadata.yaml``, else ``*.mcap``), in order."""
    names = info.get("relative_file_paths") if info is not None else None
    if isinstance(names, list) and names:
        files = [bag_dir / Path(str(n)).name for n in names]
        missing = [p.name for p in files if not p.is_file()]
        if missing:
            raise NoBagError(f"{bag_dir}: metadata.yaml names {missing}, which do not exist")
    else:
        files = mcap_files(bag_dir)
    if not files:
        raise NoBagError(f"{bag_dir}: no bag there (no *.mcap file)")
    return files


def _merged(
    summaries: list[tuple[dict[str, int], int | None, int | None] | None],
) -> tuple[dict[str, int], int | None, int | None]:
    """Counts per topic and log-time span of several files' summaries."""
    counts: dict[str, int] = {}
    firsts, lasts = [], []
    for item in summaries:
        assert item is not None
        for topic, n in item[0].items():
            counts[topic] = counts.get(topic, 0) + n
        if item[1] is not None and item[2] is not None:
            firsts.append(item[1])
            lasts.append(item[2])
    return counts, (min(firsts) if firsts else None), (max(lasts) if lasts else None)


def _files_and_topics(
    paths: list[Path],
) -> tuple[list[BagFile], list[tuple[dict[str, Any], int]]]:
    """Each complete file's entry, and each topic's metadata and count over all files.

    Read from the files' summaries: the channels (topic, QoS text, type
    hash) and schemas (type) in channel order, the statistics.
    """
    files: list[BagFile] = []
    topics: dict[str, tuple[dict[str, Any], int]] = {}
    for path in paths:
        with path.open("rb") as f:
            summary = make_reader(f).get_summary()
        if summary is None or summary.statistics is None:
            raise BagError(f"{path}: no summary after recovery")
        stats = summary.statistics
        for channel_id, channel in sorted(summary.channels.items()):
            schema = summary.schemas.get(channel.schema_id)
            metadata, count = topics.get(channel.topic, (None, 0))
            if metadata is None:
                metadata = {
                    "name": channel.topic,
                    "type": schema.name if schema is not None else "",
                    "serialization_format": "cdr",
                    "offered_qos_profiles": channel.metadata.get("offered_qos_profiles")
                    or DEFAULT_QOS,
                    "type_description_hash": channel.metadata.get("topic_type_hash", ""),
                }
            topics[channel.topic] = (
                metadata,
                count + stats.channel_message_counts.get(channel_id, 0),
            )
        empty = stats.message_count == 0
        files.append(
            BagFile(
                path.name,
                stats.message_count,
                None if empty else stats.message_start_time,
                None if empty else stats.message_end_time,
            )
        )
    return files, list(topics.values())


def _check_magic(path: Path) -> None:
    with path.open("rb") as f:
        head = f.read(len(_MAGIC))
    # A file shorter than the magic (a recorder killed at once) is an
    # unfinished MCAP file if what it has is the start of the magic.
    if head != _MAGIC[: len(head)]:
        raise NotMcapError(f"{path}: not an MCAP file (starts with {head.hex()})")


def _summary_counts(path: Path) -> tuple[dict[str, int], int | None, int | None] | None:
    """``(messages per topic, first, last log time)`` from a complete file's summary.

    None if the file has no readable summary and footer (it is unfinished).
    """
    with path.open("rb") as f:
        try:
            f.seek(-len(_MAGIC), os.SEEK_END)
            if f.read() != _MAGIC:
                return None
            f.seek(0)
            summary = make_reader(f).get_summary()
        except Exception:  # whatever a damaged end raises: no usable summary
            return None
    if summary is None or summary.statistics is None:
        return None
    stats = summary.statistics
    counts = {c.topic: 0 for c in summary.channels.values()}
    for channel_id, n in stats.channel_message_counts.items():
        topic = summary.channels[channel_id].topic
        counts[topic] = counts.get(topic, 0) + n
    if stats.message_count == 0:
        return counts, None, None
    return counts, stats.message_start_time, stats.message_end_time


def _records(f: BinaryIO) -> Iterator[tuple[Any, int, str | None]]:
    """``(record, file offset after it, chunk compression)`` of the data section.

    Every complete record in file order; a chunk is broken up here (its CRC
    checked), so it gives its records, with its compression, only when it is
    whole. The first record that is cut short or damaged ends the
    iteration, as does the end of the data section.
    """
    records = StreamReader(f, emit_chunks=True).records
    while True:
        try:
            record = next(records)
            end = f.tell()
            inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else None
        except StopIteration:
            return
        except Exception:  # EndOfFile, struct.error, a CRC or decompression error: the end
            return
        if isinstance(record, DataEnd | Footer):
            return
        if inner is None:
            yield record, end, None
        else:
            for item in inner:
                yield item, end, record.compression


def _copy_records(f: BinaryIO, tmp: Path, file_name: str) -> tuple[BagWriter, int]:
    """Write every complete record of ``f`` to a closed bag in ``tmp``.

    Returns the closed writer and the offset of the end of the last
    complete record of ``f``.
    """
    schemas: dict[int, Schema] = {}
    channels: dict[int, tuple[str, str | None]] = {}  # id -> (topic, stranger or None)
    good_end = min(len(_MAGIC), os.fstat(f.fileno()).st_size)
    writer: BagWriter | None = None
    try:
        for record, end, compression in _records(f):
            good_end = end
            if not isinstance(record, Schema | Channel | Message):
                continue  # the header; metadata and attachments are not kept
            if writer is None:
                # The compression of the first chunk (zstd for records outside chunks).
                writer = BagWriter(
                    tmp,
                    compression=_COMPRESSIONS.get(compression or "zstd", "zstd"),
                    file_name=file_name,
                )
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = _add_channel(writer, record, schemas)
            elif record.channel_id in channels:
                topic, stranger = channels[record.channel_id]
                writer.write(
                    topic,
                    record.data,
                    log_time_ns=record.log_time,
                    publish_time_ns=record.publish_time,
                    stranger=stranger,
                )
        if writer is None:  # no schema, channel or message: an empty bag
            writer = BagWriter(tmp, file_name=file_name)
    finally:
        if writer is not None:
            writer.close()
    return writer, good_end


def _add_channel(
    writer: BagWriter, channel: Channel, schemas: dict[int, Schema]
) -> tuple[str, str | None]:
    """Register ``channel`` in ``writer``: its topic, or a stranger's channel of a topic
    registered before (``stranger_publisher`` metadata); ``(topic, stranger)``."""
    stranger = channel.metadata.get(STRANGER_KEY)
    if stranger is not None and channel.topic in writer.message_counts:
        writer.stranger_channel(channel.topic, stranger)
        return channel.topic, stranger
    schema = schemas.get(channel.schema_id)
    if schema is None or schema.encoding != "ros2msg" or channel.message_encoding != "cdr":
        what = f"schema encoding {schema.encoding!r}" if schema is not None else "no schema"
        raise BagError(
            f"channel {channel.topic!r} has {what} and message encoding "
            f"{channel.message_encoding!r}: not a rosbag2 bag (ros2msg schemas, cdr messages)"
        )
    writer.add_recorded_topic(
        channel.topic,
        schema.name,
        definition=schema.data.decode(),
        qos_text=channel.metadata.get("offered_qos_profiles") or DEFAULT_QOS,
        type_hash=channel.metadata.get("topic_type_hash", ""),
    )
    if stranger is not None:
        writer.stranger_channel(channel.topic, stranger)
    return channel.topic, stranger


def _free_name(path: Path) -> Path:
    """``<path>.unfinished``, or ``.unfinished.1``, ... whichever does not exist."""
    candidate = path.with_name(path.name + UNFINISHED_SUFFIX)
    for i in range(1, 1000):
        if not candidate.exists():
            return candidate
        candidate = path.with_name(f"{path.name}{UNFINISHED_SUFFIX}.{i}")
    raise BagError(f"{path}: too many kept originals beside it")
