"""Feedforward term ``mnc``: the multirate nonlinearity compensator of paper 003.

Unbalance ``U sin(theta_d)`` and, with ``mnc.friction``, the arctan friction
model of eq. (14), at ``T_r`` (eqs. (12)-(15); eq. (17) without friction:
the previous MARC) (:class:`servo_axis.core.feedforward.mnc.NonlinearityCompensator`).
Its ``U`` and ``C`` follow the online estimates when ``adaptive.enabled``;
with an identifier the resolver copies its initial ``U``, ``C`` and whether
it estimates ``C`` (:func:`servo_axis.params.resolve.adaptive_overrides`).
"""

from __future__ import annotations

from servo_axis.core.feedforward.mnc import MncParams, NonlinearityCompensator
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.params.factories import build_reference, grid
from servo_axis.params.param import Param, build
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.plugins.values import MncValues

SCHEMA: dict[str, Param] = {
    "mnc.enabled": Param(
        False,
        meaning="multirate nonlinearity compensator (003 eqs. (12)-(15)): unbalance U sin(theta_d) "
        "and, with mnc.friction, the arctan friction model of eq. (14), at T_r",
    ),
    "mnc.friction": Param(
        True,
        meaning="compensate friction with eq. (14) (the proposal); false = unbalance only, the "
        "previous MARC of eq. (17) (with an identifier the runner sets it from its method)",
    ),
    "mnc.unbalance_Nm": Param(
        0.1,
        unit="N m",
        minimum=0.0,
        meaning="U until the first online estimate applies (003 Table I initial estimate 0.1; "
        "with an identifier the runner copies its initial.unbalance_Nm)",
    ),
    "mnc.coulomb_Nm": Param(
        0.01,
        unit="N m",
        minimum=0.0,
        meaning="C until the first online estimate applies (003 Table I initial estimate 0.01; "
        "with an identifier the runner copies its initial.coulomb_Nm)",
    ),
    "mnc.alpha_s_per_rad": Param(
        1e4, unit="s/rad", above=0.0, meaning="alpha of the friction model, eq. (14) (003: 1e4)"
    ),
    "mnc.omega_th_rad_s": Param(
        0.05, unit="rad/s", minimum=0.0, meaning="w_th, the dead zone of eq. (14) (003: 0.05)"
    ),
}


def mnc_params(values: MncValues) -> MncParams:
    """The compensator's constants (its check: what depends on several keys, not built)."""
    mnc = values.mnc
    return build(
        "mnc.",
        MncParams,
        keys={
            "alpha": "mnc.alpha_s_per_rad",
            "torque_constant_Nm_per_A": "nominal.torque_constant_Nm_per_A",
            "lead_m_per_rad": "lead_m_per_rad",
            "ratio": "control_period_s",
            "control_period_s": "control_period_s",
        },
        unbalance_Nm=mnc.unbalance_Nm,
        coulomb_Nm=mnc.coulomb_Nm,
        friction=mnc.friction,
        alpha=mnc.alpha_s_per_rad,
        omega_th_rad_s=mnc.omega_th_rad_s,
        torque_constant_Nm_per_A=values.nominal.torque_constant_Nm_per_A,
        lead_m_per_rad=values.lead_m_per_rad,
        ratio=grid(values).ratio,
        control_period_s=values.control_period_s,
    )


def _check(values: MncValues) -> None:
    if values.mnc.enabled:
        mnc_params(values)


def _build(values: MncValues) -> FeedforwardTerm | None:
    """The multirate nonlinearity compensator of 003 eqs. (12)-(15) / (17), if on."""
    if not values.mnc.enabled:
        return None
    # Its U and C follow the online estimates when adaptive.enabled.
    return NonlinearityCompensator(mnc_params(values), reference=build_reference(values))


#: The entry point ``servo_axis.feedforward_terms: mnc``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    check=_check,
    values=MncValues,
    order=20.0,
    description="multirate nonlinearity compensator: unbalance and arctan friction (003)",
)
