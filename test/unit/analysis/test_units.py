"""The one table of units (analysis/units.py) and its page, docs/reference/units.md."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.analysis import units
from servo_axis.analysis.units import QUANTITIES, position, position_error, summary_quantity

PAGE = Path(__file__).resolve().parents[3] / "docs" / "reference" / "units.md"


def test_the_page_lists_every_quantity_of_the_table_as_it_is() -> None:
    rows = {}
    for line in PAGE.read_text().splitlines():
        m = re.fullmatch(r"\| `(\w+)` \| (.+) \| (.+) \| (.+) \| (.+) \|", line)
        if m:
            rows[m.group(1)] = m.groups()[1:]
    assert list(rows) == list(QUANTITIES)
    for key, (name, si, unit, factor) in rows.items():
        q = QUANTITIES[key]
        assert (name, si, unit) == (q.name, q.si, q.unit), key
        if q.decibel:
            assert factor == "level: 20 log10", key
        else:
            assert math.isclose(float(factor), q.factor, rel_tol=1e-5), key


def test_a_position_error_is_um_on_a_linear_axis_and_rad_on_a_rotary_one() -> None:
    linear, rotary = position_error("m"), position_error("rad")
    assert (linear.unit, rotary.unit) == ("um", "rad")
    assert linear.label("RMSD") == "RMSD (um)"
    assert_allclose(linear.shown(1.69678e-6), 1.69678, rtol=1e-12)
    assert linear.format(1.69678e-6) == "1.69678"
    assert rotary.format(6.983e-4) == "0.0006983"
    assert linear.format(math.nan) == "-" and linear.format(None) == "-"
    assert (position("m").unit, position("rad").unit) == ("mm", "rad")
    with pytest.raises(ValueError, match="error unit: expected 'm' or 'rad', got 'deg'"):
        position_error("deg")


def test_a_response_s_level_is_20_log10_of_its_magnitude_and_its_phase_degrees() -> None:
    response = np.array([1e-3 * np.exp(-0.5j), 10.0 + 0j])
    assert_allclose(units.FRF_MAGNITUDE.shown(response), [-60.0, 20.0], rtol=1e-12)
    assert_allclose(units.FRF_MAGNITUDE.shown(0.5), 20 * math.log10(0.5), rtol=1e-12)
    assert_allclose(units.FRF_PHASE.shown(np.angle(response)), [-28.64788975654116, 0.0])


@pytest.mark.parametrize(
    ("path", "unit"),
    [
        ("tracking_error.all_samples.max_m", "um"),
        ("tracking_error.cycles[-1].rms_rad", "rad"),
        ("contour.max_radial_m", "um"),
        ("contour.radius_m", "mm"),
        ("deformation.stops[0].windows[1].mean_d_r_m_per_rad", "um/rad"),
        ("deformation.stops[0].deceleration_m_s2", "m/s^2"),
        ("sysid.bode_db", "dB"),
        ("sysid.bode_deg", "deg"),
        ("wall_time_s", "s"),
        ("identification.final.unbalance_Nm", "N m"),
        ("identification.final_ratio.inertia_kgm2", None),
        ("sysid.keys.modes_frequency_hz_0", None),  # a relative error, not Hz
        ("steps", None),
    ],
)
def test_a_study_figure_takes_the_unit_of_its_summary_path(path: str, unit: str | None) -> None:
    q = summary_quantity(path)
    assert (q.unit if q else None) == unit
