"""Feedforward term ``gms``: GMS-model friction compensation (004 Sect. II-C).

The generalized Maxwell-slip model (Al-Bender et al. 2005) driven by the
reference's motion, with the parameters of a ``servo_axis gms-fit`` file
(:class:`servo_axis.core.feedforward.gms_compensation.GmsTerm`). The file carries the
fingerprint of the plant it was identified on; ``gms.plant`` is that of this
run's plant section (:func:`servo_axis.params.resolve.plant_fingerprint`)
and a file of another plant is refused.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from servo_axis.core.errors import ParameterFileError, ServoAxisError
from servo_axis.core.feedforward.gms_compensation import GmsTerm
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.params.factories import NOMINAL_KEYS, PERIOD_KEYS, term_file
from servo_axis.params.param import Param, build
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.params.resolve import Resolved, plant_fingerprint
from servo_axis.plugins.values import GmsValues
from servo_axis.storage import load_gms_parameters

SCHEMA: dict[str, Param] = {
    "gms.enabled": Param(
        False,
        meaning="GMS-model friction compensation (Al-Bender et al. 2005; the conventional "
        "method of 004 Sect. II-C) on the reference's motion",
    ),
    "gms.file": Param(
        "",
        meaning="GMS parameter file (`servo_axis gms-fit` of a friction_id run); a relative "
        "path is relative to the scenario file",
    ),
    "gms.plant": Param(
        "",
        meaning="the plant the file must have been identified on (`<model>:<hash>` of the "
        "plant section); the runner sets it from the scenario; empty: not checked",
    ),
}


def _file(values: GmsValues) -> str | None:
    """Its parameter file when it is on (the check: one is named), not read."""
    return term_file(values.gms.enabled, values.gms.file, "gms")


def _build(values: GmsValues) -> FeedforwardTerm | None:
    """The GMS-model compensation (004 Sect. II-C), if on: its file read and checked."""
    path = _file(values)
    if path is None:
        return None
    try:
        params, _, fingerprint = load_gms_parameters(path)
    except (OSError, ServoAxisError) as err:
        raise ParameterFileError(f"parameter 'gms.file': {err}") from err
    expected = values.gms.plant
    if expected and fingerprint != expected:
        raise ParameterFileError(
            f"parameter 'gms.file': {path} was identified on plant {fingerprint!r}, "
            f"this run's plant is {expected!r}: fit it again on a friction_id run of this plant"
        )
    return build(
        "",
        GmsTerm,
        keys={**NOMINAL_KEYS, **PERIOD_KEYS},
        params=params,
        torque_constant_Nm_per_A=values.nominal.torque_constant_Nm_per_A,
        control_period_s=values.control_period_s,
    )


def _overrides(resolved: Resolved, given: Mapping[str, Any]) -> dict[str, Any]:
    """``gms.plant``: the plant a GMS file must come from, when the term is on (and its
    section does not name one): from the plant's checked values."""
    if given.get("gms.enabled", False) and "gms.plant" not in given:
        return {"gms.plant": plant_fingerprint(resolved)}
    return {}


#: The entry point ``servo_axis.feedforward_terms: gms``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    check=_file,
    values=GmsValues,
    files=("gms.file",),
    order=30.0,
    overrides=_overrides,
    description="GMS-model friction compensation from a gms-fit file (004 Sect. II-C)",
)
