"""Feedforward term ``sigmoid``: the sigmoid friction compensation of paper 004 eq. (9).

``F_c`` of eq. (9) with ``d_r^ = sigma / z`` of eq. (8), ``z`` the distance
to the nearest reversal of the reference (before and after it)
(:class:`servo_axis.core.feedforward.sigmoid.SigmoidTerm`). With
``sigmoid.source: stage`` the law is the feedback loop's instead, from the
measured table position
(:class:`servo_axis.core.feedback.stage_sigmoid.StageSigmoid`).
"""

from __future__ import annotations

from servo_axis.core.feedforward.sigmoid import (
    PAPER_PRESLIDING_M,
    PAPER_SIGMA_M2_PER_RAD,
    SigmoidTerm,
    gamma_for_width,
)
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.params import schemas
from servo_axis.params.factories import NOMINAL_KEYS, build_reference, sigmoid_params
from servo_axis.params.param import Param, build
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.plugins.values import SigmoidValues

_SIGMOID_GAMMA = gamma_for_width(
    sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=PAPER_PRESLIDING_M / 2
)

SCHEMA: dict[str, Param] = {
    "sigmoid.enabled": Param(
        False,
        meaning="sigmoid friction compensation of 004 eq. (9) with d_r^ = sigma / z of eq. (8), "
        "z the distance to the nearest reversal of the reference (before and after it)",
    ),
    "sigmoid.sigma_m2_per_rad": Param(
        PAPER_SIGMA_M2_PER_RAD,
        unit="m^2/rad",
        above=0.0,
        meaning="sigma of 004 eq. (8) (0.04 with z in mm and d_r in mm/rad)",
    ),
    "sigmoid.gamma_m_per_rad": Param(
        _SIGMOID_GAMMA,
        unit="m/rad",
        above=0.0,
        meaning="gamma of 004 eq. (9); the default makes |F_c| reach 0.9 F_0 at z = x_s / 2 "
        "= 7.5 um (gamma = 0.9 sigma / (x_s / 2 sqrt(1 - 0.81)))",
    ),
    "sigmoid.coulomb_Nm": Param(
        0.43,
        unit="N m",
        above=0.0,
        meaning="F_0 of 004 eq. (9): the Coulomb level of the friction at the motor "
        "(the sliding level of the friction_id run)",
    ),
    "sigmoid.source": Param(
        "reference",
        choices=schemas.SIGMOID_SOURCES,
        meaning="where eq. (9) takes sgn(v) and z: reference (this term: the preview of the "
        "reference, F_c falls before the reversal) or stage (004's wording, the velocity of "
        "the stage: the feedback loop computes it from the measured table position, after "
        "the measured reversal; this term is then off)",
    ),
    "sigmoid.search_horizon_s": Param(
        1.0,
        unit="s",
        above=0.0,
        meaning="how far ahead the next reversal of the reference is looked for",
    ),
}


def _from_reference(values: SigmoidValues) -> bool:
    """Whether this term computes the law: on, from the reference (from the stage: the loop's)."""
    return values.sigmoid.enabled and values.sigmoid.source != "stage"


def _build(values: SigmoidValues) -> FeedforwardTerm | None:
    """The sigmoid law of 004 eq. (9), if on."""
    if not _from_reference(values):
        return None  # from the stage: the feedback loop's (factories.build_loop)
    return build(
        "sigmoid.",
        SigmoidTerm,
        keys={**NOMINAL_KEYS, "control_period_s": "control_period_s"},
        params=sigmoid_params(values.sigmoid),
        reference=build_reference(values),
        control_period_s=values.control_period_s,
        torque_constant_Nm_per_A=values.nominal.torque_constant_Nm_per_A,
        search_horizon_s=values.sigmoid.search_horizon_s,
    )


def _check(values: SigmoidValues) -> None:
    """What the term's constructor refuses (its keys' ranges cover the rest), without it."""
    if _from_reference(values):
        sigmoid_params(values.sigmoid)
        build_reference(values)


#: The entry point ``servo_axis.feedforward_terms: sigmoid``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    check=_check,
    values=SigmoidValues,
    order=40.0,
    description="sigmoid friction compensation before reversals, eq. (9) of 004",
)
