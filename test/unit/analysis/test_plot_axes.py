"""Every axis in the one unit of its quantity, with tick labels that say their value.

The units are those of :mod:`servo_axis.analysis.units` whatever the size of
the values (issue 43: a figure's unit no longer follows its data); the axes
are read from the matplotlib objects the plots make.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.analysis import plots
from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.plots import plain_ticks, plot_cycles, plot_rmsd_bars
from servo_axis.analysis.summary import RunSummary


def tick_values(ax: Any) -> list[float]:
    """The y tick labels as numbers (matplotlib writes a minus as U+2212)."""
    return [float(t.get_text().replace("\u2212", "-")) for t in ax.get_yticklabels()]


@pytest.mark.parametrize("peak", [1.0178e-11, 2e-5, 0.0017, 0.587, 587.13, 3e4, 5.8e7])
def test_every_tick_label_says_its_value_without_an_offset(peak: float) -> None:
    """From a PTC on its own model (1e-11 um) to a diverged run: each label is its tick."""
    plt = plots._pyplot()
    fig, ax = plt.subplots()
    ax.plot([0.0, 1.0], [0.0, peak])
    plain_ticks(ax)
    fig.canvas.draw()
    assert ax.yaxis.get_offset_text().get_text() == ""
    assert_allclose(tick_values(ax), ax.get_yticks(), rtol=1e-9, atol=1e-9 * peak)
    plt.close(fig)


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


def test_cycle_axis_has_integer_ticks_and_the_error_in_um(
    tmp_path: Path, figures: list[Any]
) -> None:
    # Errors of 0.3 um: um, not nm (the unit does not follow the data).
    plot_cycles([summary(3e-7)], ["a"], tmp_path / "c.png", title="t")
    (ax,) = figures[0].axes
    ticks = [t for t in ax.get_xticks() if 1 <= t <= 7]
    assert ticks and all(float(t).is_integer() for t in ticks), ticks
    assert ax.get_ylabel() == "tracking error (um)"
    (line, _) = ax.get_lines()[:2]
    # Max of cycle 1: 0.3 um times |sin| at its peak sample.
    assert_allclose(line.get_ydata()[0], 0.3, rtol=1e-3)
    assert_allclose(
        line.get_ydata(), 1e6 * np.array([c.max_m for c in summary(3e-7).tracking_error.cycles])
    )


def test_a_rotary_run_s_error_is_in_rad(tmp_path: Path, figures: list[Any]) -> None:
    rotary = RunSummary.from_dict({**summary(4e-5).to_dict(), "error_unit": "rad"})
    plot_cycles([rotary], ["tilt"], tmp_path / "c.png", title="t")
    plot_rmsd_bars([rotary, rotary], ["pid", "lpf2"], tmp_path / "b.png", title="t")
    cycles, bars = (fig.axes[0] for fig in figures)
    assert cycles.get_ylabel() == "tracking error (rad)"
    assert_allclose(cycles.get_lines()[0].get_ydata()[0], 4e-5, rtol=1e-3)
    assert bars.get_ylabel() == "RMSD of tracking error (rad)"
    assert_allclose([p.get_height() for p in bars.patches], [rotary.rmsd] * 2, rtol=1e-12)


def test_rmsd_bars_in_um_without_a_multiplier(tmp_path: Path, figures: list[Any]) -> None:
    # RMSDs near 0.587 um, 1e-5 um apart: the ticks say so without a multiplier.
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
    assert ax.get_ylabel() == "RMSD of tracking error (um)"
    assert ax.yaxis.get_offset_text().get_text() == ""
    assert_allclose([p.get_height() for p in ax.patches], [0.58713, 0.58714], rtol=1e-9)


def test_runs_with_different_cycle_counts_share_one_error_axis(
    tmp_path: Path, figures: list[Any]
) -> None:
    """`compare --out` of rptc_friction_table (6 cycles) against ptc_nominal (4) crashed
    (`setting an array element with a sequence`); one axis in um, whichever run is larger."""
    long, short = summary(3e-7, cycles=7), summary(2e-6, cycles=4)
    plot_cycles([long, short], ["long", "short"], tmp_path / "c.png", title="t")
    (ax,) = figures[0].axes
    assert ax.get_ylabel() == "tracking error (um)"
    lines = ax.get_lines()
    assert [line.get_xdata().size for line in lines] == [7, 7, 4, 4]
    # Max of the short run's cycle 4: 2 um (1 + 0.3) at its peak sample.
    assert_allclose(lines[2].get_ydata()[-1], 2.0 * 1.3, rtol=1e-3)
