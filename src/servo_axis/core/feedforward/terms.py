"""Feedforward terms: currents added to the model-based feedforward, per control sample.

The generator sums ``u_ff = u_PTC + sum of terms`` in the order the terms
are given. A term sees every control sample once, in order (terms may keep
state, e.g. the reversal tracking of the friction table). Later terms
(paper 003's arctan friction and unbalance compensator, paper 004's GMS
model and sigmoid law) are a class here, or a module beside it (or in an
outside package), plus their entry (schema, builder, entry point) in a module
of their own (:mod:`servo_axis.params.registry`; the suite's in
``servo_axis.plugins``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.feedforward.friction_table import FrictionFeedforward, FrictionTable

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ReferenceBlock:
    """The original reference at a run of control samples (table side).

    Attributes
    ----------
    step : ndarray of int
        Control samples ``k``.
    position_m, velocity_m_s, acceleration_m_s2 : ndarray
        Reference at ``k T_u`` (m, m/s, m/s^2).
    """

    step: NDArray[np.int64]
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray


class FeedforwardTerm(Protocol):
    """A current added to the feedforward."""

    def currents(self, block: ReferenceBlock) -> FloatArray:
        """The term's current (A) at each sample of ``block``."""
        ...


class FrictionTableTerm:
    """Data-based friction table (paper 000 Sect. VI-B, Fig. 17; paper 001).

    ``+ table(|y_d[k] - y_rev|) / K_T`` with the sign of the reference's
    direction.

    Parameters
    ----------
    table : FrictionTable
        Friction torque against displacement from the last reversal.
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    """

    def __init__(self, table: FrictionTable, *, torque_constant_Nm_per_A: float) -> None:
        self._ff = FrictionFeedforward(table, torque_constant_Nm_per_A=torque_constant_Nm_per_A)

    def currents(self, block: ReferenceBlock) -> FloatArray:
        return np.array([self._ff.current_A(float(p)) for p in block.position_m], dtype=float)
