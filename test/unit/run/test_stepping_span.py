"""The run's wall time is its steps': the plant's report, checked against the runner's own times."""

from __future__ import annotations

import pytest

from servo_axis.run.summarise import stepping_span
from servo_axis.wire.node_report import NodeHealth


def _plant(**stepping: object) -> NodeHealth:
    return NodeHealth("plant", stepping=dict(stepping))


def test_the_span_is_the_plant_s_first_and_last_step() -> None:
    plant = _plant(steps=1000, first_s=100.8, last_s=101.1)
    assert stepping_span(plant, 100.0, 101.3) == (100.8, 101.1)
    # A run whose one step is state 0: first and last may coincide.
    assert stepping_span(_plant(steps=1, first_s=100.5, last_s=100.5), 100.0, 101.0) == (
        100.5,
        100.5,
    )


@pytest.mark.parametrize(
    "plant",
    [
        None,  # an outside plant: no report
        NodeHealth("plant"),  # stopped before its last step: nothing reported
        _plant(steps=10, first_s=0.0, last_s=100.5),  # state 0 never went out
        _plant(steps=10, first_s=100.5),  # half a report
        _plant(steps=10, first_s="soon", last_s=100.5),
        _plant(steps=10, first_s=100.9, last_s=100.5),  # backwards
        _plant(steps=10, first_s=99.0, last_s=100.5),  # before the nodes started
        _plant(steps=10, first_s=100.5, last_s=102.0),  # after they stopped
    ],
)
def test_a_missing_or_inconsistent_report_leaves_the_runner_s_view(
    plant: NodeHealth | None,
) -> None:
    assert stepping_span(plant, 100.0, 101.0) is None
