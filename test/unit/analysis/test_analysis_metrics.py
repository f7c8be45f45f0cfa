"""Tracking-error statistics and the contour error: pure arithmetic on arrays."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.analysis.metrics import _stats, contour_error, error_statistics


def _rms_max(x: np.ndarray) -> tuple[float, float]:
    """Independent RMS and max |x| (NaN, NaN when empty)."""
    if len(x) == 0:
        return math.nan, math.nan
    return math.sqrt(sum(v * v for v in x) / len(x)), max(abs(v) for v in x)


def _pair(stats: dict[str, float]) -> tuple[float, float]:
    return stats["rms_m"], stats["max_m"]


def test_stats_of_nothing_is_nan() -> None:
    assert all(math.isnan(v) for v in _pair(_stats(np.array([]))))
    assert_allclose(_pair(_stats(np.array([3.0, -4.0]))), (math.sqrt(12.5), 4.0), rtol=1e-15)


def test_error_statistics_per_cycle() -> None:
    step = np.arange(1000)
    e = np.where(step < 500, 2.0, 1.0) * np.sin(2 * np.pi * step / 250)
    stats = error_statistics(e, step, period_s=1e-3, cycle_s=0.25)
    assert [c["cycle"] for c in stats["cycles"]] == [1, 2, 3, 4]
    assert_allclose(
        [c["rms_m"] for c in stats["cycles"]],
        [2 / math.sqrt(2)] * 2 + [1 / math.sqrt(2)] * 2,
        rtol=1e-9,
    )
    assert_allclose(stats["reference_instants"]["max_m"], np.max(np.abs(e[::2])), rtol=0)
    assert_allclose(
        stats["after_first_cycle"]["all_samples"]["max_m"], np.max(np.abs(e[250:])), rtol=0
    )


@pytest.mark.parametrize("ratio", [2, 3])
def test_error_statistics_equal_an_independent_computation(ratio: int) -> None:
    """Random error on steps 7..1234 with a gap: cycles 1, 3 and 7 are incomplete, skipped."""
    rng = np.random.default_rng(7)
    step = np.arange(7, 1235)
    step = np.delete(step, [500, 501, 502])  # a gap in cycle 3 (steps 507..509)
    e = rng.normal(scale=1e-6, size=step.size)
    period, cycle_s, per_cycle = 1e-3, 0.2, 200
    stats = error_statistics(e, step, period_s=period, cycle_s=cycle_s, ratio=ratio)

    samples = dict(zip(step.tolist(), e.tolist(), strict=True))
    at_tr = [v for k, v in samples.items() if k % ratio == 0]
    assert_allclose(_pair(stats["all_samples"]), _rms_max(list(samples.values())), rtol=1e-12)
    assert_allclose(_pair(stats["reference_instants"]), _rms_max(at_tr), rtol=1e-12)
    expected_cycles = []
    for c in range(7):
        inside = {k: v for k, v in samples.items() if c * per_cycle <= k < (c + 1) * per_cycle}
        if len(inside) == per_cycle:
            expected_cycles.append((c + 1, inside))
    assert [c["cycle"] for c in stats["cycles"]] == [n for n, _ in expected_cycles]
    assert [n for n, _ in expected_cycles] == [2, 4, 5, 6]
    for row, (_n, inside) in zip(stats["cycles"], expected_cycles, strict=True):
        assert_allclose(_pair(row), _rms_max(list(inside.values())), rtol=1e-12)
        tr = [v for k, v in inside.items() if k % ratio == 0]
        assert_allclose(_pair(row["reference_instants"]), _rms_max(tr), rtol=1e-12)
    later = {k: v for k, v in samples.items() if k >= per_cycle}
    after = stats["after_first_cycle"]
    assert_allclose(_pair(after["all_samples"]), _rms_max(list(later.values())), rtol=1e-12)
    assert_allclose(
        _pair(after["reference_instants"]),
        _rms_max([v for k, v in later.items() if k % ratio == 0]),
        rtol=1e-12,
    )


def test_error_statistics_without_a_period_has_no_cycles() -> None:
    step = np.arange(10)
    stats = error_statistics(np.ones(10), step, period_s=1e-3, cycle_s=None)
    assert list(stats) == ["all_samples", "reference_instants", "cycles"]
    assert stats["cycles"] == []
    empty = error_statistics(np.array([]), np.array([], dtype=int), period_s=1e-3, cycle_s=0.1)
    assert empty["cycles"] == []
    assert math.isnan(empty["after_first_cycle"]["all_samples"]["rms_m"])


def _circle(centre: tuple[float, float], radius: float, angle: np.ndarray) -> np.ndarray:
    return np.column_stack((centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)))


def test_contour_error_recovers_a_known_circle_exactly() -> None:
    """Irregularly sampled points on a circle: the fitted circle is the circle."""
    rng = np.random.default_rng(3)
    angle = np.sort(rng.uniform(0, 1.7 * np.pi, size=300))  # not even a whole turn
    target = _circle((0.012, -0.004), 0.01, angle)
    steps = np.arange(300)
    result = contour_error(target, target.copy(), steps, None)
    assert_allclose(result.centre_m, (0.012, -0.004), rtol=0, atol=1e-15)
    assert_allclose(result.radius_m, 0.01, rtol=1e-12)
    assert_allclose(result.radial, 0.0, rtol=0, atol=1e-15)
    assert result.target_radial_deviation_m < 1e-15
    assert result.cycles == ()
    summary = result.to_summary()
    assert list(summary) == [
        "centre_m",
        "radius_m",
        "target_radial_deviation_m",
        "circular_deviation_m",
        "max_radial_m",
        "cycles",
    ]
    assert not any(k.startswith("_") for k in summary)
    assert isinstance(summary["centre_m"], list)


def test_contour_error_measures_the_radial_deviation_of_a_perturbed_circle() -> None:
    """Two cycles of 400 steps; the measured radius is R + d(step), d known."""
    n, per_cycle, radius, centre = 800, 400, 0.01, (0.01, 0.0)
    steps = np.arange(n)
    angle = 2 * np.pi * steps / per_cycle
    d = np.where(steps < per_cycle, 2e-6, 0.5e-6) * np.sin(3 * angle) + 1e-7
    target = _circle(centre, radius, angle)
    measured = centre + (radius + d)[:, None] * np.column_stack((np.cos(angle), np.sin(angle)))
    result = contour_error(target, measured, steps, per_cycle)
    assert_allclose(result.radial, d, rtol=0, atol=1e-15)
    assert_allclose(result.circular_deviation_m, d.max() - d.min(), rtol=0, atol=2e-15)
    assert_allclose(result.max_radial_m, np.max(np.abs(d)), rtol=0, atol=1e-15)
    assert [c.cycle for c in result.cycles] == [1, 2]
    for c, sel in zip(result.cycles, (steps < per_cycle, steps >= per_cycle), strict=True):
        assert_allclose(c.circular_deviation_m, np.ptp(d[sel]), rtol=0, atol=2e-15)
        assert_allclose(c.max_radial_m, np.max(np.abs(d[sel])), rtol=0, atol=1e-15)
    assert_allclose(result.measured, measured, rtol=0, atol=0)
    assert_allclose(result.target, target, rtol=0, atol=0)
    assert result.steps is steps or np.array_equal(result.steps, steps)
    rows = result.to_summary()["cycles"]
    assert rows[0] == {
        "cycle": 1,
        "circular_deviation_m": result.cycles[0].circular_deviation_m,
        "max_radial_m": result.cycles[0].max_radial_m,
    }
