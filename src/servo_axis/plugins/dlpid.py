"""Identification methods ``dlpid`` and ``marc`` of paper 003.

``dlpid``: double-layer parameter identification, the RLS of ``J, D, U``
plus the friction layer of eq. (8), which estimates ``C``; ``marc``: the
previous MARC, the RLS of ``J, D, U`` alone, friction unmodelled (003 [11])
(:class:`servo_axis.core.identification.online.dlpid.Dlpid`, modes ``double_layer``
and ``single_layer``). The shared keys (schedule, bounds of ``J, D, U``,
forgetting, conditions) are the identifier section's own; ``dlpid`` adds
those of its friction layer.
"""

from __future__ import annotations

from typing import Any

from servo_axis.core.errors import ParameterFileError
from servo_axis.core.identification.online.base import OnlineIdentifier
from servo_axis.core.identification.online.dlpid import Dlpid, DlpidParams
from servo_axis.core.identification.online.rls import RlsParams
from servo_axis.params.factories import identifier_schedule
from servo_axis.params.param import Param, build
from servo_axis.params.registry import IdentifierEntry
from servo_axis.params.values import IdentifierValues
from servo_axis.plugins.values import DlpidValues

#: The keys of method ``dlpid`` only: the friction layer of 003 eq. (8).
DLPID_FRICTION: dict[str, Param] = {
    "initial.coulomb_Nm": Param(
        0.01, unit="N m", minimum=0.0, meaning="C_hat[0] (003 Table I: 0.01; dlpid only)"
    ),
    "bounds.coulomb_Nm": Param(
        [0.0, 1.0], unit="N m", minimum=0.0, meaning="[min, max] of C_hat (dlpid)"
    ),
    "friction.cutoff_hz": Param(
        2.0,
        unit="Hz",
        above=0.0,
        meaning="q of the friction layer's low-pass, eq. (8) (003: 2 or 100 Hz); dlpid only",
    ),
    "friction.velocity_min_rad_s": Param(
        0.2,
        unit="rad/s",
        above=0.0,
        meaning="C_hat is held while |theta'| is at or below this (dlpid)",
    ),
}


def _bounds(key: str, pair: tuple[float, ...]) -> tuple[float, float]:
    if len(pair) != 2 or not pair[0] < pair[1]:
        raise ParameterFileError(
            f"parameter '{key}': expected [min, max] with min < max, got {list(pair)!r}"
        )
    return float(pair[0]), float(pair[1])


def dlpid_params(values: IdentifierValues, mode: str) -> DlpidParams:
    """The identifier's parameters in mode ``double_layer`` (``values`` of method
    ``dlpid``) or ``single_layer`` (``marc``): also the methods' check."""
    identifier_schedule(values)
    b = values.bounds
    bounds = [
        _bounds("bounds.inertia_kgm2", b.inertia_kgm2),
        _bounds("bounds.damping_Nms_per_rad", b.damping_Nms_per_rad),
        _bounds("bounds.unbalance_Nm", b.unbalance_Nm),
    ]
    forgetting = values.forgetting
    if len(forgetting) != 3:
        raise ParameterFileError(
            f"parameter 'forgetting': expected 3 factors (J, D, U), got {list(forgetting)!r}"
        )
    initial = (
        values.nominal.inertia_kgm2,
        values.nominal.damping_Nms_per_rad,
        values.initial.unbalance_Nm,
    )
    for name, key, (lo, hi), v in zip(
        ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm"),
        ("nominal.inertia_kgm2", "nominal.damping_Nms_per_rad", "initial.unbalance_Nm"),
        bounds,
        initial,
        strict=True,
    ):
        if not lo <= v <= hi:
            raise ParameterFileError(
                f"parameter '{key}': the initial estimate must lie inside bounds.{name} "
                f"[{lo!r}, {hi!r}], got {v!r}"
            )
    rls = build(
        "",
        RlsParams,
        keys={"initial_covariance": "initial_covariance", "forgetting": "forgetting"},
        initial=initial,
        lower=tuple(b[0] for b in bounds),
        upper=tuple(b[1] for b in bounds),
        forgetting=tuple(forgetting),
        initial_covariance=values.initial_covariance,
        names=("J", "D", "U"),
    )
    friction: dict[str, Any] = {}
    if mode == "double_layer":
        assert isinstance(values, DlpidValues)
        friction = {
            "friction_cutoff_hz": values.friction.cutoff_hz,
            "initial_friction_Nm": values.initial.coulomb_Nm,
            "friction_bounds": _bounds("bounds.coulomb_Nm", values.bounds.coulomb_Nm),
            "friction_velocity_min_rad_s": values.friction.velocity_min_rad_s,
        }
    c = values.conditions
    return build(
        "",
        DlpidParams,
        keys={
            "period_s": "control_period_s",
            "friction_cutoff_hz": "friction.cutoff_hz",
            "initial_friction_Nm": "initial.coulomb_Nm",
            "friction_bounds": "bounds.coulomb_Nm",
            "friction_velocity_min_rad_s": "friction.velocity_min_rad_s",
            "angle_min_rad": "conditions.angle_min_rad",
            "velocity_min_rad_s": "conditions.velocity_min_rad_s",
            "acceleration_min_rad_s2": "conditions.acceleration_min_rad_s2",
        },
        rls=rls,
        period_s=values.control_period_s,
        rls_period_s=values.rls_period_s,
        pd_cutoff_hz=values.pd_cutoff_hz,
        angle_min_rad=c.angle_min_rad,
        velocity_min_rad_s=c.velocity_min_rad_s,
        acceleration_min_rad_s2=c.acceleration_min_rad_s2,
        pe_window=values.pe_window,
        mode=mode,
        **friction,
    )


def _dlpid(values: DlpidValues) -> OnlineIdentifier:
    return Dlpid(dlpid_params(values, "double_layer"))


def _check_dlpid(values: DlpidValues) -> None:
    dlpid_params(values, "double_layer")


def _marc(values: IdentifierValues) -> OnlineIdentifier:
    return Dlpid(dlpid_params(values, "single_layer"))


def _check_marc(values: IdentifierValues) -> None:
    dlpid_params(values, "single_layer")


#: The entry point ``servo_axis.identification_methods: dlpid``.
DLPID = IdentifierEntry(
    schema=DLPID_FRICTION,
    build=_dlpid,
    check=_check_dlpid,
    values=DlpidValues,
    estimates_friction=True,
    description="double-layer identification: RLS of J, D, U and the friction layer (003)",
)
#: The entry point ``servo_axis.identification_methods: marc``.
MARC = IdentifierEntry(
    schema={},
    build=_marc,
    check=_check_marc,
    estimates_friction=False,
    description="the previous MARC: RLS of J, D, U only, friction unmodelled (003 [11])",
)
