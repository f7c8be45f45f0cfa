"""Learning law ``rptc``: repetitive PTC with the n-times learning filter (paper 000).

A cycle law with target-side corrections
(:class:`servo_axis.core.learning.rptc.PeriodicSignalGenerator`): the
correction of each cycle is learned from the error of the cycle before,
filtered by ``Q~n = I - (I - Q)^n``. Its keys (``nq``, ``n``, ``cycle_s``)
are the learning section's own.
"""

from __future__ import annotations

from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.learning.rptc import LearningParams, PeriodicSignalGenerator
from servo_axis.params.factories import PERIOD_KEYS, cycle_instants, grid
from servo_axis.params.param import build
from servo_axis.params.registry import LearningLawEntry
from servo_axis.params.values import LearningValues


def rptc_params(values: LearningValues) -> LearningParams:
    """The memory's and the filter's parameters (the law's check: ``n N_q + 2 < N_d``, ...)."""
    g = grid(values)
    nd = build("", g.instants_per, period_s=values.cycle_s, name="cycle_s", minimum=4)
    nd = cycle_instants("cycle_s", values.cycle_s, nd)
    return build(
        "",
        LearningParams,
        keys={**PERIOD_KEYS, "samples_per_cycle": "cycle_s"},
        samples_per_cycle=nd,
        nq=values.nq,
        n=values.n,
        period_s=g.reference_period_s,
    )


def _rptc(values: LearningValues) -> LearningLaw:
    return PeriodicSignalGenerator(rptc_params(values))


#: The entry point ``servo_axis.learning_laws: rptc``.
LAW = LearningLawEntry(
    schema={},
    period="cycle",
    side="target",
    build=_rptc,
    check=rptc_params,
    description="repetitive PTC with the n-times learning filter (000)",
)
