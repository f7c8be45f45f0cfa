"""Feedforward term ``viscous_ff``: the current that cancels a viscous friction ``b theta_d'``.

``i_ff = b theta_d' / K_T,n`` with ``theta_d' = v_d / R`` the motor velocity of
the reference and ``K_T,n`` the nominal torque constant; on with
``viscous_ff.enabled``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock
from servo_axis.params.param import Param
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.params.typed import Group
from servo_axis.params.values import FeedforwardValues

SCHEMA: dict[str, Param] = {
    "viscous_ff.enabled": Param(False, meaning="add the viscous-friction feedforward b v / R K_T"),
    "viscous_ff.coefficient_Nms_per_rad": Param(
        0.2, unit="N m s/rad", minimum=0.0, meaning="b: the viscous friction it cancels"
    ),
}


@dataclass(frozen=True, kw_only=True, eq=False)
class ViscousFfKeys(Group):
    """The ``viscous_ff.*`` keys."""

    enabled: bool = field(metadata={"unit": "", "range": ""})
    coefficient_Nms_per_rad: float = field(metadata={"unit": "N m s/rad", "range": ">= 0"})


@dataclass(frozen=True, kw_only=True, eq=False)
class ViscousFfValues(FeedforwardValues):
    """The feedforward section's values with this term's keys (mypy checks the names)."""

    viscous_ff: ViscousFfKeys


class ViscousTerm:
    """``b v_d / (R K_T)`` at each sample of a reference block, A."""

    def __init__(self, *, coefficient: float, lead_m_per_rad: float, torque_constant: float):
        self._gain = coefficient / (lead_m_per_rad * torque_constant)

    def currents(self, block: ReferenceBlock) -> NDArray[np.float64]:
        """The term's current (A) at each sample of ``block``."""
        return np.asarray(self._gain * block.velocity_m_s, dtype=float)


def _build(values: ViscousFfValues) -> FeedforwardTerm | None:
    own = values.viscous_ff
    if not own.enabled:
        return None
    return ViscousTerm(
        coefficient=own.coefficient_Nms_per_rad,
        lead_m_per_rad=values.lead_m_per_rad,
        torque_constant=values.nominal.torque_constant_Nm_per_A,
    )


#: The entry point ``servo_axis.feedforward_terms: viscous_ff``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    values=ViscousFfValues,
    order=50.0,
    description="viscous-friction feedforward b v / (R K_T) (an outside package)",
)
