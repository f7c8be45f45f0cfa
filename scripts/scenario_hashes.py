#!/usr/bin/env python3
"""SHA-256 of every recorded topic's payloads, for every scenario in config/.

Runs each scenario end to end in lockstep through the runner a user calls
(``python -m servo_axis run``, as separate processes unless ``--composed``),
reads each bag back with rosbags (an independent reader) and prints one line
per recorded topic::

    <scenario> <topic> <message count> <sha256 of the CDR payloads in recorded order>

A multi-axis scenario's topics carry their axis namespace (``/x/state``); a
single-axis run's topics are named relative to its namespace (``/x/state`` of
a run is ``/state`` here), so that the lines compare the payloads, whatever
the namespace the run puts its nodes in. The output of the
commit before a restructure is kept in ``test/data/scenario_hashes.txt``;
``--check`` compares a fresh run against it and exits 1 on any difference:

    .venv/bin/python scripts/scenario_hashes.py --check test/data/scenario_hashes.txt
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import os
import sys
import tempfile
from pathlib import Path

from servo_axis import numerics
from servo_axis.numerics import MASKS

REPO = Path(__file__).resolve().parents[1]


def bag_hashes(bag_dir: Path) -> dict[str, tuple[int, str]]:
    """``{topic: (count, sha256)}`` of a bag, read with rosbags."""
    from rosbags.highlevel import AnyReader

    digests: dict[str, hashlib._Hash] = {}
    counts: dict[str, int] = {}
    with AnyReader([bag_dir]) as reader:
        for conn in reader.connections:
            digests.setdefault(conn.topic, hashlib.sha256())
            counts.setdefault(conn.topic, 0)
        for conn, _time, raw in reader.messages():
            # Length-prefixed so that two payload lists cannot hash alike by
            # where they split.
            digests[conn.topic].update(len(raw).to_bytes(8, "little"))
            digests[conn.topic].update(raw)
            counts[conn.topic] += 1
    return {t: (counts[t], digests[t].hexdigest()) for t in sorted(digests)}


def run_dirs_with_bags(run_dir: Path) -> list[Path]:
    """The bag directories of a run (one, or one per axis)."""
    return sorted(p.parent for p in run_dir.rglob("metadata.yaml") if p.parent.name == "bag")


def scenario_lines(scenario: Path, work: Path, domain_id: int, composed: bool) -> list[str]:
    from servo_axis.__main__ import main as cli

    out = work / scenario.stem
    args = ["run", str(scenario), "--out", str(out), "--domain-id", str(domain_id), "--no-plots"]
    if composed:
        args.append("--composed")
    with contextlib.redirect_stdout(sys.stderr):  # the run's own table is not output
        code = cli(args)
    if code != 0:
        raise SystemExit(f"{scenario.name}: run exited {code}")
    lines = []
    for bag in run_dirs_with_bags(out):
        # A single-axis run is namespaced (/x/state); its lines name the
        # topics relative to that namespace (/state), as they always have.
        ns = single_axis_ns(scenario) if bag == out / "bag" else ""
        for topic, (count, digest) in bag_hashes(bag).items():
            if ns and topic.startswith(ns + "/"):
                topic = topic[len(ns) :]
            lines.append(f"{scenario.stem} {topic} {count} {digest}")
    return lines


def single_axis_ns(scenario: Path) -> str:
    """The namespace a single-axis run of ``scenario`` puts its nodes in (``/<axis>``)."""
    from servo_axis.params.run_params import single_axis_namespace
    from servo_axis.params.scenario import load_scenario

    return single_axis_namespace(load_scenario(scenario))


def main() -> int:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("scenarios", nargs="*", help="scenario files (default: config/*.yaml)")
    parser.add_argument("--composed", action="store_true", help="single-axis runs in one process")
    parser.add_argument("--check", metavar="FILE", help="compare with a committed output")
    parser.add_argument("--domain-id", type=int, default=150 + os.getpid() % 80)
    parser.add_argument(
        "--mask",
        action="append",
        default=[],
        choices=[*MASKS, "all"],
        help="run as if on another CPU (servo_axis.numerics.MASKS); repeatable",
    )
    args = parser.parse_args()
    for name in MASKS if "all" in args.mask else args.mask:
        # Set before the runner starts any node: they inherit it.
        for key, value in MASKS[name].items():
            if key == "GLIBC_TUNABLES" and os.environ.get(key):
                value = f"{os.environ[key]}:{value}"
            os.environ[key] = value
    scenarios = [Path(s) for s in args.scenarios] or sorted((REPO / "config").glob("*.yaml"))
    lines: list[str] = []
    with tempfile.TemporaryDirectory(prefix="servo_axis_hashes_") as tmp:
        for scenario in scenarios:
            multi = "/x/" in scenario.read_text() or "/y/" in scenario.read_text()
            new = scenario_lines(scenario, Path(tmp), args.domain_id, args.composed and not multi)
            lines += new
            print("\n".join(new), flush=True)
    if not args.check:
        return 0
    expected = [ln for ln in Path(args.check).read_text().splitlines() if ln and ln[0] != "#"]
    wanted = {ln.split()[0] for ln in lines}
    expected = [ln for ln in expected if ln.split()[0] in wanted]
    if sorted(lines) == sorted(expected):  # one line per topic; the order is not the point
        print(f"identical: {len(lines)} topics of {len(wanted)} scenarios", file=sys.stderr)
        return 0
    for ln in sorted(set(expected) ^ set(lines)):
        print(("expected " if ln in expected else "got      ") + ln, file=sys.stderr)
    return 1


if __name__ == "__main__":
    raise SystemExit(main())
