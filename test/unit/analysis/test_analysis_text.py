"""Text tables of summaries and of several runs' per-cycle errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.summary import AxesSummary, RunSummary, cycle_errors
from servo_axis.analysis.text import (
    compare_table,
    format_any_summary,
    format_axes_summary,
    format_summary,
    last_common_cycle,
    last_cycle_table,
    rmsd_table,
)


def summary_dict(tracking_error: dict[str, Any], **over: Any) -> dict[str, Any]:
    """A single-axis ``summary.json`` mapping around ``tracking_error``."""
    out = {
        "scenario": "demo",
        "description": "a demo",
        "scenario_file": "/s/demo.yaml",
        "processes": "processes",
        "time_mode": "lockstep",
        "control_period_s": 0.001,
        "steps": 1000,
        "sim_time_s": 1.0,
        "wall_time_s": 0.5,
        "steps_per_s": 2000.0,
        "realtime_factor": 2.0,
        "message_counts": {"state": 1000, "/clock": 100, "reference": 1000},
        "faults": [{"step": 900, "code": 3, "name": "current", "value": 60.0}],
        "ptc": True,
        "friction_table": False,
        "reference_period_s": 0.25,
        "tracking_error": tracking_error,
    }
    out.update(over)
    return out


def demo_summary() -> RunSummary:
    step = np.arange(1000)
    e = 1e-6 * np.where(step < 500, 2.0, 1.0) * np.sin(2 * np.pi * step / 250 + 0.3)
    return RunSummary.from_dict(
        summary_dict(error_statistics(e, step, period_s=1e-3, cycle_s=0.25))
    )


# The text of the report module before the split, for the same summary.
DEMO_TEXT = """\
scenario          demo  (processes, lockstep)
steps             1000  (1.000 s simulated)
wall time         0.50 s  ->  2,000 steps/s, 2.00x real time
messages          /clock: 100, reference: 1000, state: 1000
faults            current at step 900

tracking error (um)          RMS            max
  all samples               1.11803        1.99988
  at T_r instants           1.11803        1.99988
  after cycle 1                   1        1.99988
  ... at T_r instants             1        1.99988

cycle   RMS (um)       max (um)       max at T_r (um)
    1      1.41421        1.99988            1.99988
    2      1.41421        1.99988            1.99988
    3     0.707107        0.99994            0.99994
    4     0.707107        0.99994            0.99994"""

CONTOUR_TEXT = """\
== contour: circle of radius 10.000 mm (target off the circle by 1.25e-06 um)
circular deviation 2.5 um, max radial error 1.5 um
cycle   circular deviation (um)   max radial error (um)
    1                       2.5                     1.5
    2                       0.5                       -"""


def test_format_summary_text_is_unchanged() -> None:
    assert format_summary(demo_summary()) == DEMO_TEXT
    assert format_any_summary(demo_summary()) == DEMO_TEXT


def test_the_wall_time_line_says_what_the_steps_left_out() -> None:
    summary = RunSummary.from_dict(
        {**demo_summary().to_dict(), "startup_s": 0.8125, "finish_s": 0.146}
    )
    line = next(x for x in format_summary(summary).splitlines() if x.startswith("wall time"))
    assert line == (
        "wall time         0.50 s  ->  2,000 steps/s, 2.00x real time "
        "(steps only; start-up 0.81 s, end 0.15 s)"
    )
    assert RunSummary.from_json(summary.to_json()) == summary
    # Without them (an outside plant, an older summary) the line is as before.
    assert "steps only" not in format_summary(demo_summary())
    assert "startup_s" not in demo_summary().to_dict()


def test_format_summary_without_cycles_or_faults() -> None:
    step = np.arange(10)
    s = RunSummary.from_dict(
        summary_dict(
            error_statistics(np.zeros(10), step, period_s=1e-3, cycle_s=None),
            faults=[],
            reference_period_s=None,
            steps_per_s=math.nan,
        )
    )
    lines = format_summary(s).splitlines()
    assert lines[4] == "faults            none"
    assert lines[-1] == "  at T_r instants                 0              0"
    assert "nan steps/s" in lines[2]


def test_format_axes_summary_text_is_unchanged() -> None:
    axes = AxesSummary.from_dict(
        {
            "scenario": "xy",
            "description": "",
            "wall_time_s": 3.0,
            "axes": {"x": demo_summary().to_dict()},
            "contour": {
                "axes": ["x", "y"],
                "centre_m": [0.01, 0.0],
                "radius_m": 0.01,
                "target_radial_deviation_m": 1.25e-12,
                "circular_deviation_m": 2.5e-6,
                "max_radial_m": 1.5e-6,
                "cycles": [
                    {"cycle": 1, "circular_deviation_m": 2.5e-6, "max_radial_m": 1.5e-6},
                    {"cycle": 2, "circular_deviation_m": 0.5e-6, "max_radial_m": math.nan},
                ],
            },
        }
    )
    expected = "\n".join(
        ["scenario          xy  (axes x)", "", "== axis x", DEMO_TEXT, "", CONTOUR_TEXT]
    )
    assert format_axes_summary(axes) == expected
    assert format_any_summary(axes) == expected


def decaying_runs(*decays: float, cycles: int = 4) -> list[RunSummary]:
    """Runs whose error falls by ``decay`` per cycle of 0.25 s (1 ms samples)."""
    runs = []
    for decay in decays:
        step = np.arange(250 * cycles)
        e = decay ** (step // 250) * 1e-6 * np.sin(2 * np.pi * step / 250 + 0.3)
        stats = error_statistics(e, step, period_s=1e-3, cycle_s=0.25)
        runs.append(RunSummary.from_dict(summary_dict(stats)))
    return runs


def numbers(row: str) -> list[float]:
    return [float(x) for x in row.split()]


def test_compare_table_lines_up_the_cycles_with_each_run_s_reduction() -> None:
    runs = decaying_runs(0.5, 0.2)  # per cycle: the second run's error falls faster
    step = np.arange(1000)
    e = 1e-6 * np.sin(2 * np.pi * step / 250 + 0.3)
    assert_allclose(
        cycle_errors(runs[1])["max_m"],
        [0.2**k * np.max(np.abs(e[:250])) for k in range(4)],
        rtol=1e-12,
    )
    max_block, rms_block = compare_table(runs, ["Q", "Q~5"]).split("\n\n")
    for block, key, title in ((max_block, "max_m", "max"), (rms_block, "rms_m", "RMS")):
        rows = block.splitlines()
        assert rows[0] == (
            f"{title} tracking error per cycle (um); reduction (%) = 100 (1 - run / Q) "
            "in the same cycle"
        )
        assert rows[1].split() == ["cycle", "Q", "Q~5", "reduction", "(%)"]
        table = np.array([numbers(row) for row in rows[2:]])
        assert_allclose(table[:, 0], [1, 2, 3, 4], rtol=0)
        assert_allclose(table[:, 2], 1e6 * cycle_errors(runs[1])[key], rtol=1e-5)
        assert_allclose(table[:, 1] / table[:, 2], [2.5**k for k in range(4)], rtol=1e-5)
        # The reduction in each cycle, 100 (1 - 0.2^k / 0.5^k), to the 2 decimals shown.
        assert_allclose(table[:, 3], [100 * (1 - 0.4**k) for k in range(4)], atol=0.006)
    assert_allclose(numbers(rms_block.splitlines()[2])[1], 1 / np.sqrt(2), rtol=1e-5)


def test_the_headline_is_each_run_s_last_cycle_against_the_first_run_s_last() -> None:
    """compare's headline (issue 43): each run's last cycle, not the max over every
    cycle after the first, which cycle 2 sets while learning has barely acted."""
    base, faster = decaying_runs(0.9, 0.5, cycles=6)
    shorter = decaying_runs(0.3, cycles=4)[0]
    lines = last_cycle_table([base, faster, shorter], ["base", "fast", "short"]).splitlines()
    assert lines[0] == (
        "last cycle of each run (base cycle 6, fast cycle 6, short cycle 4); reduction (%) = "
        "100 (1 - run / base), each against the last cycle of base"
    )
    assert lines[1].split() == [
        "run", "cycle", "max", "(um)", "reduction", "(%)", "RMS", "(um)", "reduction", "(%)"
    ]  # fmt: skip
    rows = {line.split()[0]: line.split()[1:] for line in lines[2:]}
    assert rows["base"][0] == "6" and rows["base"][2] == rows["base"][4] == "base"
    # Independently: the last cycle's max and RMS of each run's own error.
    last = {
        label: s.tracking_error.cycles[-1]
        for label, s in (("base", base), ("fast", faster), ("short", shorter))
    }
    for label, row in rows.items():
        assert int(row[0]) == last[label].cycle
        assert_allclose(float(row[1]), 1e6 * last[label].max_m, rtol=1e-5)
        assert_allclose(float(row[3]), 1e6 * last[label].rms_m, rtol=1e-5)
        if label != "base":
            assert_allclose(
                float(row[2]), 100 * (1 - last[label].max_m / last["base"].max_m), atol=0.006
            )
            assert_allclose(
                float(row[4]), 100 * (1 - last[label].rms_m / last["base"].rms_m), atol=0.006
            )
    # Runs that end on the same cycle name it once.
    same = last_cycle_table([base, faster], ["a", "b"]).splitlines()[0]
    assert same.startswith("last cycle of each run (cycle 6 of every run); ")
    assert last_common_cycle([base, faster, shorter]) == 4


def test_a_rotary_run_s_summary_and_comparison_are_in_rad() -> None:
    step = np.arange(1000)
    e = 6.983e-4 * np.sin(2 * np.pi * step / 250 + 0.3)
    stats = error_statistics(e, step, period_s=1e-3, cycle_s=0.25)
    tilt = RunSummary.from_dict(summary_dict(stats, error_unit="rad"))
    text = format_summary(tilt)
    assert "tracking error (rad)         RMS            max" in text
    assert "cycle   RMS (rad)      max (rad)      max at T_r (rad)" in text
    assert "urad" not in text and "(um)" not in text
    row = next(x for x in text.splitlines() if x.startswith("  all samples"))
    assert_allclose(numbers(row.removeprefix("  all samples")), [
        np.sqrt(np.mean(e**2)), np.max(np.abs(e))
    ], rtol=1e-5)  # fmt: skip
    table = rmsd_table([tilt, tilt], ["pid", "lpf2"]).splitlines()
    assert table[0] == (
        "RMSD of the tracking error over the whole run (rad); reduction against pid"
    )
    assert table[1].split()[:3] == ["run", "RMSD", "(rad)"]
    assert_allclose(float(table[2].split()[1]), tilt.rmsd, rtol=1e-5)
    for head in compare_table([tilt], ["a"]).split("\n\n"):
        assert "(rad)" in head.splitlines()[0]
    with pytest.raises(ValueError, match=r"different units \(m, rad\)"):
        compare_table([tilt, demo_summary()], ["a", "b"])


def test_cycle_errors_of_a_run_without_cycles_are_empty() -> None:
    step = np.arange(10)
    s = RunSummary.from_dict(
        summary_dict(error_statistics(np.ones(10), step, period_s=1e-3, cycle_s=None))
    )
    c = cycle_errors(s)
    assert {k: v.size for k, v in c.items()} == {
        "cycle": 0,
        "max_m": 0,
        "rms_m": 0,
        "max_at_tr_m": 0,
    }
    assert compare_table([s], ["a"]).splitlines()[1].split() == ["cycle", "a"]
    assert (
        last_cycle_table([s], ["a"])
        .splitlines()[0]
        .startswith("last cycle of each run (no complete cycle)")
    )


REALTIME = {
    "period_ns": 1_000_000,
    "ticks": 1000,
    "misses": 7,
    "commands_missing": 2,
    "commands_late": 5,
    "timer_rate": 0.9996,
    "tick_late_us": {"p50": 3.1, "p99": 240.0, "max": 1800.0},
    "command_late_us": {"p50": 310.0, "p99": 980.0, "max": 4200.0},
}


def test_a_realtime_summary_reports_misses_and_lateness_and_is_never_deterministic() -> None:
    from servo_axis.analysis.health import assess
    from servo_axis.analysis.summary import Realtime

    base = demo_summary().to_dict()
    floor = {"period_us": 1000, "executor": "events", "miss_pct": 0.25, "ticks": 10000,
             "misses": 25, "round_trip_us": {"p50": 140.0, "p99": 279.0, "max": 900.0}}  # fmt: skip
    health = assess(failure=None, deaths=[], reports={}, faults=0, realtime=True)
    assert not health.deterministic and health.exit_code == 0
    data = dict(
        base, time_mode="realtime", faults=[], realtime=dict(REALTIME, floor=floor),
        health=health.to_dict(),
    )  # fmt: skip
    s = RunSummary.from_dict(data)
    assert s.realtime == Realtime.from_dict(dict(REALTIME, floor=floor))
    assert RunSummary.from_json(s.to_json()) == s
    rt = s.realtime
    assert rt is not None
    assert rt.misses == rt.commands_late + rt.commands_missing
    assert_allclose(rt.miss_fraction, 0.007, rtol=1e-12)
    text = format_summary(s)
    assert "deterministic" not in text.replace("not deterministic", "")
    assert "realtime, not deterministic (exit 0)" in text
    assert "deadline misses   7 of 1000 ticks (0.70 %), 2 command(s) never came" in text
    assert "tick late (us)    p50 3  p99 240  max 1800" in text
    assert "command late (us) p50 310  p99 980  max 4200" in text
    assert "floor             0.25 % misses at 1000 us (events)" in text
    assert "late inputs" not in text  # nothing reported by the feedback or the generator
    late = {"references_held": 5, "late_estimates": 12, "late_corrections": 0}
    s2 = RunSummary.from_dict(dict(data, realtime=dict(REALTIME, **late)))
    assert RunSummary.from_json(s2.to_json()) == s2
    assert s2.realtime is not None and s2.realtime.late_estimates == 12
    assert (
        "late inputs       5 state(s) answered with the last reference; applied late: "
        "12 estimate(s), 0 correction(s)"
    ) in format_summary(s2)
    assert "set-points" not in format_summary(s2)
    points = {"period_ns": 2_000_000, "received": 990, "unset": 40, "quiet_ticks": 0}
    s3 = RunSummary.from_dict(dict(data, realtime=dict(REALTIME, setpoints=points)))
    assert RunSummary.from_json(s3.to_json()) == s3
    assert (
        "set-points        990 received every 2000 us (a miss: none for 1.5 of that), "
        "40 NaN (no command yet, not applied), 0 tick(s) held on a silent commander"
    ) in format_summary(s3)
    assert "command late (us) p50 310  p99 980  max 4200  (after the newest state's tick)" in (
        format_summary(s3)
    )
    # A lockstep summary has no realtime entry and says nothing of one.
    assert "realtime" not in demo_summary().to_dict()
    assert "deadline misses" not in format_summary(demo_summary())
