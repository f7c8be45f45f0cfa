"""Error axes in a readable unit with plain tick labels; cycle axes with integer ticks."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.analysis import plots
from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.plots import error_scale, plot_cycles, plot_rmsd_bars
from servo_axis.analysis.summary import RunSummary


@pytest.mark.parametrize(
    ("values", "unit", "factor", "label", "shown"),
    [
        ([0.587e-6, -0.2e-6], "m", 1e9, "nm", 587.0),  # 587 nm, not 0.587 um
        ([3.2e-6], "m", 1e6, "um", 3.2),
        ([1.2e-3], "m", 1e3, "mm", 1.2),
        ([1.01785e-17, 0.0], "m", 1e18, "am", 10.1785),  # a PTC on its own nominal model
        # Below the smallest prefix: its smallest, and the peak stays below 1.
        ([1e-25], "m", 1e18, "am", 1e-7),
        ([0.0, np.nan], "m", 1e6, "um", 0.0),  # nothing to go by
        ([4e-5], "rad", 1e6, "urad", 40.0),
    ],
)
def test_error_scale_puts_the_largest_error_at_1_or_more(
    values: list[float], unit: str, factor: float, label: str, shown: float
) -> None:
    got_factor, got_label = error_scale(values, unit)
    assert (got_factor, got_label) == (factor, label)
    # The peak as the axis shows it: in [1, 1000) whenever a prefix reaches it.
    assert_allclose(np.nanmax(np.abs(values)) * got_factor, shown, rtol=1e-12)


def summary(scale: float, cycles: int = 7) -> RunSummary:
    step = np.arange(250 * cycles)
    e = scale * np.sin(2 * np.pi * step / 250 + 0.3) * (1 + 0.1 * (step // 250))
    return RunSummary.from_dict(
        {
            "scenario": "demo",
            "description": "",
            "scenario_file": "demo.yaml",
            "processes": "separate processes",
            "time_mode": "lockstep",
            "control_period_s": 0.001,
            "steps": int(step.size),
            "sim_time_s": step.size * 1e-3,
            "wall_time_s": 1.0,
            "steps_per_s": 1.0,
            "realtime_factor": 1.0,
            "message_counts": {},
            "faults": [],
            "ptc": True,
            "friction_table": False,
            "reference_period_s": 0.25,
            "tracking_error": error_statistics(e, step, period_s=1e-3, cycle_s=0.25),
        }
    )


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Any]]:
    """The figures the plots close, kept open for inspection (closed after the test)."""
    kept: list[Any] = []
    plt = plots._pyplot()
    monkeypatch.setattr(plt, "close", kept.append)
    yield kept
    monkeypatch.undo()
    for fig in kept:
        plt.close(fig)


def test_cycle_axis_has_integer_ticks_and_the_error_its_unit(
    tmp_path: Path, figures: list[Any]
) -> None:
    plot_cycles([summary(3e-7)], ["a"], tmp_path / "c.png", title="t")
    (ax,) = figures[0].axes
    ticks = [t for t in ax.get_xticks() if 1 <= t <= 7]
    assert ticks and all(float(t).is_integer() for t in ticks), ticks
    assert ax.get_ylabel() == "tracking error (nm)"
    (line, _) = ax.get_lines()[:2]
    # Max of cycle 1: 300 nm times |sin| at its peak sample.
    assert_allclose(line.get_ydata()[0], 300.0, rtol=1e-3)


def test_rmsd_bars_in_nm_without_a_multiplier(tmp_path: Path, figures: list[Any]) -> None:
    # RMSDs near 0.587 um: shown as 587 nm, no multiplier above the axis.
    runs = [summary(1e-8) for _ in range(2)]
    runs = [
        RunSummary.from_dict(
            {
                **r.to_dict(),
                "tracking_error": {
                    **r.to_dict()["tracking_error"],
                    "all_samples": {"rms_m": rms, "max_m": 1e-6},
                },
            }
        )
        for r, rms in zip(runs, (0.58713e-6, 0.58714e-6), strict=True)
    ]
    plot_rmsd_bars(runs, ["a", "b"], tmp_path / "b.png", title="t")
    (ax,) = figures[0].axes
    figures[0].canvas.draw()
    assert ax.get_ylabel() == "RMSD of tracking error (nm)"
    assert ax.yaxis.get_offset_text().get_text() == ""
    assert_allclose([p.get_height() for p in ax.patches], [587.13, 587.14], rtol=1e-9)


def test_plain_axes_show_the_numbers_as_they_are() -> None:
    plt = plots._pyplot()
    fig, (default, plain) = plt.subplots(2, 1)
    t = np.linspace(0.0, 1.0, 50)
    for ax in (default, plain):
        ax.plot(t, 587.13 + 1e-4 * np.sin(2 * np.pi * t))  # nm near 587.13
    plots._plain(plain)
    fig.canvas.draw()
    assert default.yaxis.get_offset_text().get_text() != ""  # what matplotlib would do
    assert plain.yaxis.get_offset_text().get_text() == ""
    labels = [float(x.get_text().replace("\u2212", "-")) for x in plain.get_yticklabels()]
    assert all(587.12 < v < 587.14 for v in labels), labels
    plt.close(fig)


def test_runs_with_different_cycle_counts_share_one_error_axis(
    tmp_path: Path, figures: list[Any]
) -> None:
    """`compare --out` of rptc_friction_table (6 cycles) against ptc_nominal (4) crashed
    in error_scale (`setting an array element with a sequence`); the larger maximum sets
    the unit, whichever run has it."""
    long, short = summary(3e-7, cycles=7), summary(2e-6, cycles=4)
    plot_cycles([long, short], ["long", "short"], tmp_path / "c.png", title="t")
    (ax,) = figures[0].axes
    assert ax.get_ylabel() == "tracking error (um)"
    lines = ax.get_lines()
    assert [line.get_xdata().size for line in lines] == [7, 7, 4, 4]
    # Max of the short run's cycle 4: 2 um (1 + 0.3) at its peak sample.
    assert_allclose(lines[2].get_ydata()[-1], 2.0 * 1.3, rtol=1e-3)
    assert error_scale([np.ones(3) * 2e-6, np.ones(5) * 3e-9]) == (1e6, "um")
