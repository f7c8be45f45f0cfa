#!/usr/bin/env python3
"""Speed of the suite's CDR decoders against rosbags' on a bag's JointState payloads.

The measurement behind keeping ``wire/cdr.py`` and ``wire/sample_cdr.py``
(issue 39, docs/architecture.md "Why the CDR decoders are the suite's own").
Every ``JointState`` payload of the bag (``state``, ``reference``,
``command``) is decoded three ways, and the bag read two ways:

    codec         wire/sample_cdr.JointCodec.decode: the per-sample path of the
                  nodes and of the analysis (one struct call, layout checked)
    generic       wire/cdr.decode_joint_state: the fallback for any other payload
    rosbags       rosbags' Typestore.deserialize_cdr (the oracle of the tests)
    read_raw      recording/reader.read_raw: every message of the bag, undecoded
    AnyReader     rosbags.highlevel.AnyReader: the same
    load_signals  analysis/signals.load_signals: the whole analysis reader

Each is run ``--repeat`` times, interleaved (a loaded host slows them
alike); the table has the best and the median, and us per message for the
decoders. rosbags is a test dependency (``pip install -e .[test]``).

    .venv/bin/python scripts/cdr_speed.py RUN_DIR/bag [--repeat 15] [--axis x]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from servo_axis.analysis.signals import load_signals
from servo_axis.recording.reader import read_raw
from servo_axis.wire import cdr
from servo_axis.wire.streams import joint_codec

JOINT_STATE = "sensor_msgs/msg/JointState"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="a run's bag directory")
    parser.add_argument("--repeat", type=int, default=15, help="runs of each, interleaved")
    parser.add_argument("--axis", default="x", help="the run's axis (joint names)")
    parser.add_argument("--period-s", type=float, default=0.001, help="the run's T_u, s")
    args = parser.parse_args()
    bag: Path = args.bag
    store = get_typestore(Stores.ROS2_JAZZY)
    payloads: dict[str, list[bytes]] = {}
    for m in read_raw(bag):
        if m.type_name == JOINT_STATE:
            payloads.setdefault(m.topic.rsplit("/", 1)[-1], []).append(m.data)
    count = sum(len(v) for v in payloads.values())
    period_ns = round(args.period_s * 1e9)
    codecs = {name: joint_codec(name, args.axis, period_ns) for name in payloads}

    def codec() -> None:
        for name, datas in payloads.items():
            decode = codecs[name].decode
            for data in datas:
                decode(data)

    def generic() -> None:
        for datas in payloads.values():
            for data in datas:
                cdr.decode_joint_state(data)

    def rosbags() -> None:
        for datas in payloads.values():
            for data in datas:
                store.deserialize_cdr(data, JOINT_STATE)

    def ours_read() -> None:
        for _ in read_raw(bag):
            pass

    def rosbags_read() -> None:
        with AnyReader([bag], default_typestore=store) as reader:
            for _ in reader.messages():
                pass

    def signals() -> None:
        load_signals(bag, args.period_s)

    runs: dict[str, Callable[[], None]] = {
        "codec": codec,
        "generic": generic,
        "rosbags": rosbags,
        "read_raw": ours_read,
        "AnyReader": rosbags_read,
        "load_signals": signals,
    }
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(args.repeat):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    print(
        f"{count} JointState payloads ({', '.join(f'{k} {len(v)}' for k, v in payloads.items())})"
    )
    print(f"{'':14s} {'best ms':>9s} {'median ms':>10s} {'us/msg':>8s}")
    for name, ts in times.items():
        per = f"{min(ts) / count * 1e6:8.2f}" if name in ("codec", "generic", "rosbags") else ""
        print(f"{name:14s} {min(ts) * 1e3:9.1f} {statistics.median(ts) * 1e3:10.1f} {per}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
