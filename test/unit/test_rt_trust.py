"""scripts/rt_trust.py pools repeated runs and floors before it compares them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
sys.path.insert(0, str(SCRIPTS))

from rt_trust import misses_text, pooled_floor  # noqa: E402


def _summary(misses: int, ticks: int, period_ns: int = 1_000_000) -> dict:
    return {"realtime": {"misses": misses, "ticks": ticks, "period_ns": period_ns}}


def test_the_floor_and_the_runs_are_pooled_before_the_ratio() -> None:
    floors = [{1000: {"misses": 10, "ticks": 5000}}, {1000: {"misses": 30, "ticks": 5000}}]
    pooled = pooled_floor(floors)
    assert pooled == {1000: {"misses": 40, "ticks": 10000, "miss_pct": pytest.approx(0.4)}}
    # 12 + 4 misses of 4000 ticks against 0.4 % of 4000 = 16 expected: 1.00x
    misses, ratio = misses_text([_summary(12, 2000), _summary(4, 2000)], pooled)
    assert misses == "16/4000 (12 4)"
    assert ratio == "1.00x (0.40 %)"
    # One run: no per-run list; no floor at its period: no ratio.
    assert misses_text([_summary(3, 2000, 500_000)], pooled) == ("3/2000", "-")


def test_two_axes_are_pooled_each_on_its_own() -> None:
    axes = {"axes": {"x": _summary(2, 1000), "y": _summary(6, 1000)}}
    misses, _ = misses_text([axes, axes], {})
    assert misses == "4/2000 (2 2), 12/2000 (6 6)"


def test_a_bad_count_of_repeats_is_one_line() -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPTS / "rt_trust.py"), "ptc_nominal", "--reps", "0"],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].endswith("--reps: expected at least 1, got 0")
