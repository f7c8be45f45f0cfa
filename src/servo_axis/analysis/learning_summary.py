"""The learning side of a run's summary: the ILC convergence measure of a trial law (paper 001)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from servo_axis.params.factories import learning_law
from servo_axis.params.resolve import Resolved


def ilc_convergence(
    scenario: Resolved | dict[str, Any], scenario_path: Path
) -> dict[str, float] | None:
    """``{"nq", "nominal", "plant"}``: the measure of 001 eq. (7) for a trial law, else None.

    The law's registry entry computes it (``LearningLawEntry.convergence``;
    None for a law without one): ``plant`` is the plant's rigid-body part
    (``J``, ``D``, ``K_T`` of the plant section) under the same PID and ``L``.
    """
    resolved = Resolved.of(scenario, scenario_path)
    if not resolved.has("learning") or not resolved.has("plant"):
        return None
    values = resolved.learning
    convergence = learning_law(values.law).convergence
    if convergence is None:
        return None
    return convergence(values, resolved.plant)
