"""``python -m servo_axis floor``: the host's realtime floor, what ``run --floor`` reads.

A short measurement (300 ticks at two periods) through the command a user
runs, in the test's ROS domain. What is checked does not depend on how
loaded the host is: the fields ``run --floor`` needs, counts that add up,
percentiles in order, and an in-time echo never later than the period. Its
two processes and its temporary ROS log directory are gone afterwards. Not
marked ``realtime``: it asserts no timing figure.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from servo_axis.run.floor import read_floor
from servo_axis.run.processes import ros_environment

pytestmark = pytest.mark.integration

TICKS = 300
PERIODS_US = (1000, 500)


def test_floor_json_is_what_run_floor_reads(ros_env: int, tmp_path: Path) -> None:
    before = set(Path(tempfile.gettempdir()).glob("servo_axis_floor_*"))
    out = tmp_path / "floor.jsonl"
    done = subprocess.run(
        [sys.executable, "-m", "servo_axis", "floor", "--period-us", *map(str, PERIODS_US),
         "--ticks", str(TICKS), "--json", "--out", str(out), "--domain-id", str(ros_env)],
        env=ros_environment(ros_env, tmp_path / "ros_log"),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    rows = [json.loads(line) for line in done.stdout.splitlines()]
    assert [r["period_us"] for r in rows] == list(PERIODS_US)
    assert out.read_text() == done.stdout  # --out holds the same lines
    for r in rows:
        assert r["ticks"] == TICKS and r["executor"] == "events"
        assert 0 <= r["misses"] <= TICKS
        assert r["miss_pct"] == round(100 * r["misses"] / TICKS, 3)
        assert r["scheduling"]["policy"] == "other"  # --priority 0
        late = r["tick_late_us"]
        assert 0 <= late["p50"] <= late["p99"] <= late["max"]
        trip = r["round_trip_us"]
        if r["misses"] < TICKS:  # an echo in time: after its send, by the next tick
            assert 0 < trip["p50"] <= trip["p99"] <= trip["p99.9"] <= trip["max"]
            assert trip["max"] <= r["period_us"]
        else:
            assert trip["p50"] is None
    floor = read_floor(out)  # run --floor's reader
    assert sorted(floor) == sorted(PERIODS_US)
    assert floor[1000] == rows[0]
    # Nothing left: no process of the pair, no temporary directory.
    pairs = subprocess.run(
        ["pgrep", "-f", "servo_axis.run.floor_pair"], capture_output=True, text=True, check=False
    )
    assert pairs.stdout == ""
    assert set(Path(tempfile.gettempdir()).glob("servo_axis_floor_*")) <= before
