"""Learning laws ``silc``, ``pilc_bf`` and ``pilc_bfft``: the trial laws of paper 001.

Standard ILC and projection-based ILC with basis functions, without and with
the data-based friction table (:mod:`servo_axis.core.learning.ilc`,
:mod:`servo_axis.core.learning.pilc`): trial laws with input-side
corrections. The learning filter ``L`` is the ZPETC of ``S_n P_n`` of the
feedback loop, whose bandwidth the resolver copies from the feedback section
(``feedback.bandwidth_hz``). A run of one of them gets the summary's
``ilc_convergence`` block (001 eq. (7)).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from servo_axis.core.errors import ParameterFileError, ServoAxisError
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.models.base import NominalModel
from servo_axis.params import schemas
from servo_axis.params.factories import (
    NOMINAL_KEYS,
    build_reference,
    check_trial_period,
    grid,
    nominal_model,
)
from servo_axis.params.param import Param, build
from servo_axis.params.registry import LearningLawEntry
from servo_axis.params.values import PlantValues
from servo_axis.plugins.values import PilcBfValues, SilcValues

#: The values of a section with a trial law: the keys of ``silc``, or of ``pilc_bf``/``pilc_bfft``.
TrialValues = SilcValues | PilcBfValues

#: Keys of the trial laws of paper 001 (``silc``, ``pilc_bf``, ``pilc_bfft``).
ILC: dict[str, Param] = {
    "feedback.bandwidth_hz": Param(
        schemas.FEEDBACK["bandwidth_hz"].default,
        unit="Hz",
        above=0.0,
        meaning="bandwidth of the feedback section's PID (the runner copies it): the learning "
        "filter L is the ZPETC of S_n P_n of that loop (001 Sect. IV-A-3)",
    ),
}

#: Keys of the projection-based laws (001 Sect. III-B/C).
PILC: dict[str, Param] = {
    "x_mu_m": Param(
        5e-6,
        unit="m",
        above=0.0,
        meaning="x_mu of the friction basis b_rf, eq. (13) (001: 5 um)",
    ),
    "threshold_m": Param(
        1e-4,
        unit="m",
        above=0.0,
        meaning="displacement from a reversal beyond which W = 1 (eq. (27)) and below which the "
        "friction table is used (001: 100 um)",
    ),
}


def ilc_params(values: TrialValues) -> Any:
    """The :class:`~servo_axis.core.learning.ilc.IlcParams` of checked values of a trial law."""
    from servo_axis.core.learning.ilc import IlcParams

    g = grid(values)
    check_trial_period("cycle_s", values.cycle_s, values)
    n = build("", g.steps_per, period_s=values.cycle_s, name="cycle_s")
    nominal = nominal_model(values)
    pid = build(
        "feedback.",
        design_pid_pole_placement,
        keys=NOMINAL_KEYS,
        inertia_kgm2=nominal.inertia_kgm2,
        damping_Nms_per_rad=nominal.damping_Nms_per_rad,
        torque_constant_Nm_per_A=nominal.torque_constant_Nm_per_A,
        bandwidth_hz=values.feedback.bandwidth_hz,
    )
    return build(
        "",
        IlcParams,
        keys={"samples_per_trial": "cycle_s", "period_s": "control_period_s"},
        samples_per_trial=n,
        nq=values.nq,
        period_s=g.control_period_s,
        lead_m_per_rad=values.lead_m_per_rad,
        nominal=nominal,
        pid=pid,
    )


def _converging(values: TrialValues) -> Any:
    """:func:`ilc_params`, with the nominal loop's eq. (7) met (every trial law's check)."""
    from servo_axis.core.learning.ilc import require_convergence

    params = ilc_params(values)
    build("", require_convergence, params=params)
    return params


def _silc(values: SilcValues) -> LearningLaw:
    from servo_axis.core.learning.ilc import StandardIlc

    law: LearningLaw = build("", StandardIlc, params=ilc_params(values))
    return law


def _trial_reference(values: PilcBfValues) -> Callable[[int], tuple[Any, Any, Any]]:
    """``reference_of(trial)``: the reference of 1-based trial ``trial`` at its control samples (m)."""
    reference = build_reference(values)
    g = grid(values)
    n = g.steps_per(values.cycle_s, name="cycle_s")
    k = np.arange(n)

    def reference_of(trial: int) -> tuple[Any, Any, Any]:
        return reference.sample(((trial - 1) * n + k) * g.control_period_s)

    return reference_of


def _projection(values: PilcBfValues) -> Any:
    from servo_axis.core.learning.pilc import ProjectionParams

    return build("", ProjectionParams, x_mu_m=values.x_mu_m, threshold_m=values.threshold_m)


def _check_weights(values: PilcBfValues) -> None:
    """W of eq. (27) has data in every trajectory: refused before anything moves, not at
    the end of a trial."""
    from servo_axis.core.learning.pilc import reversal_displacement, weighting

    reference_of = _trial_reference(values)
    firsts = getattr(build_reference(values), "first_trials", (1,))
    for trial in firsts:
        pos, vel, _ = reference_of(trial)
        x_r = reversal_displacement(pos, vel)
        try:
            weighting(x_r, threshold_m=values.threshold_m, velocity_m_s=vel)
        except ServoAxisError as err:
            detail = str(err).partition(": ")[2]
            raise ParameterFileError(
                f"parameter 'threshold_m': trial {trial} (its reference): {detail}"
            ) from err


def _pilc(friction_table: bool) -> Callable[[PilcBfValues], LearningLaw]:
    def make(values: PilcBfValues) -> LearningLaw:
        from servo_axis.core.learning.pilc import ProjectionIlc

        projection = _projection(values)
        reference_of = _trial_reference(values)
        law: LearningLaw = build(
            "",
            ProjectionIlc,
            ilc=ilc_params(values),
            projection=projection,
            reference_of=reference_of,
            friction_table=friction_table,
        )
        if friction_table:
            _check_weights(values)
        return law

    return make


def _pilc_check(friction_table: bool) -> Callable[[PilcBfValues], None]:
    def check(values: PilcBfValues) -> None:
        _projection(values)
        _trial_reference(values)
        _converging(values)
        if friction_table:
            _check_weights(values)

    return check


@runtime_checkable
class RigidBody(Protocol):
    """A plant section whose model has a rigid body's ``J``, ``D`` and ``K_T`` keys."""

    @property
    def inertia_kgm2(self) -> float: ...

    @property
    def damping_Nms_per_rad(self) -> float: ...

    @property
    def torque_constant_Nm_per_A(self) -> float: ...


def convergence(values: TrialValues, plant_values: PlantValues) -> dict[str, float]:
    """``{"nq", "nominal", "plant"}``: the measure of 001 eq. (7).

    ``plant`` is the plant's rigid-body part (``J``, ``D``, ``K_T`` of the
    plant section) under the same PID and ``L``.

    Raises
    ------
    ParameterFileError
        Naming ``plant.model`` when its model has no such keys.
    """
    from servo_axis.core.learning.ilc import convergence_measure

    if not isinstance(plant_values, RigidBody):
        raise ParameterFileError(
            f"parameter 'plant.model': the convergence of eq. (7) needs a rigid body's "
            f"inertia_kgm2, damping_Nms_per_rad and torque_constant_Nm_per_A, which model "
            f"{plant_values.model!r} has not"
        )
    params = ilc_params(values)
    plant = NominalModel(
        inertia_kgm2=plant_values.inertia_kgm2,
        damping_Nms_per_rad=plant_values.damping_Nms_per_rad,
        torque_constant_Nm_per_A=plant_values.torque_constant_Nm_per_A,
    )
    return {
        "nq": params.nq,
        "nominal": convergence_measure(params=params),
        "plant": convergence_measure(params=params, plant=plant),
    }


#: The entry point ``servo_axis.learning_laws: silc``.
SILC = LearningLawEntry(
    schema=ILC,
    period="trial",
    side="input",
    build=_silc,
    check=_converging,
    values=SilcValues,
    convergence=convergence,
    description="standard ILC with the ZPETC learning filter (001)",
)
#: The entry point ``servo_axis.learning_laws: pilc_bf``.
PILC_BF = LearningLawEntry(
    schema={**ILC, **PILC},
    period="trial",
    side="input",
    build=_pilc(False),
    check=_pilc_check(False),
    values=PilcBfValues,
    identifies=("learning/parameters",),
    convergence=convergence,
    description="projection-based ILC with friction basis functions (001)",
)
#: The entry point ``servo_axis.learning_laws: pilc_bfft``.
PILC_BFFT = LearningLawEntry(
    schema={**ILC, **PILC},
    period="trial",
    side="input",
    build=_pilc(True),
    check=_pilc_check(True),
    values=PilcBfValues,
    identifies=("learning/parameters", "learning/friction_table"),
    convergence=convergence,
    description="projection-based ILC with basis functions and the data-based friction table (001)",
)
