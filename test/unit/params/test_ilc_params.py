"""The trial laws' parameters: refused by name before a node moves anything (issue 8, item 6)."""

from __future__ import annotations

from typing import Any

import pytest

from servo_axis.core.errors import ParameterFileError
from servo_axis.params.factories import build_learning_law, checked_values

TRIALS: dict[str, Any] = {
    "law": "pilc_bfft",
    "reference.kind": "trials",
    "reference.trial_s": 1.0,
    "cycle_s": 1.0,
    "feedback.bandwidth_hz": 30.0,
}


def test_the_scenario_values_build_the_three_laws() -> None:
    for law in ("silc", "pilc_bf", "pilc_bfft"):
        values = checked_values("learning", {**TRIALS, "law": law})
        built = build_learning_law(values)
        assert (built.period, built.side, built.samples_per_period) == ("trial", "input", 1000)


@pytest.mark.parametrize(
    ("given", "match"),
    [
        ({"x_mu_m": 0.0}, r"parameter 'x_mu_m': expected a value > 0"),
        ({"threshold_m": -1e-4}, r"parameter 'threshold_m': expected a value > 0"),
        ({"nq": 300}, r"parameter 'nq': Nq too large for the trial"),
        ({"cycle_s": 0.5}, r"parameter 'cycle_s': expected one trial, reference.trial_s = 1.0 s"),
        (
            {"reference.amplitudes_m": [0.002, 5e-5]},
            r"parameter 'threshold_m': trial 6 \(its reference\): .*W of eq. \(27\) is all zero",
        ),
        (
            {"reference.start_times_s": [0.5, 0.2]},
            r"parameter 'reference.move_times_s': a trajectory must start and end at rest",
        ),
        ({"feedback.bandwidth_hz": 0.0}, r"parameter 'feedback.bandwidth_hz'"),
    ],
)
def test_bad_trial_law_values_are_refused_by_name(given: dict[str, Any], match: str) -> None:
    with pytest.raises(ParameterFileError, match=match):
        checked_values("learning", {**TRIALS, **given})


def test_the_feedforward_learning_period_is_one_trial() -> None:
    given = {
        "reference.kind": "trials",
        "learning.enabled": True,
        "learning.law": "silc",
        "ptc.enabled": False,
        "learning.cycle_s": 0.8,
    }
    with pytest.raises(
        ParameterFileError, match=r"parameter 'learning.cycle_s': expected one trial"
    ):
        checked_values("feedforward", given)
    assert (
        checked_values("feedforward", {**given, "learning.cycle_s": 1.0})["learning.cycle_s"] == 1.0
    )
