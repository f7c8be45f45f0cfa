"""Feedforward term ``friction_table``: the data-based friction table of paper 000 (Fig. 17).

``f(|y_d - y_rev|) / K_T`` with the sign of the motion, from a table file
made by ``servo_axis friction-table`` of a ``friction_id`` run
(:class:`servo_axis.core.feedforward.terms.FrictionTableTerm`). On with
``friction_table.enabled``; ``friction_table.file`` is relative to the
scenario file.
"""

from __future__ import annotations

from servo_axis.core.errors import ParameterFileError, ServoAxisError
from servo_axis.core.feedforward.terms import FeedforwardTerm, FrictionTableTerm
from servo_axis.params.factories import NOMINAL_KEYS, term_file
from servo_axis.params.param import Param, build
from servo_axis.params.registry import FeedforwardTermEntry
from servo_axis.plugins.values import FrictionTableValues
from servo_axis.storage import load_friction_table

SCHEMA: dict[str, Param] = {
    "friction_table.enabled": Param(
        False,
        meaning="data-based friction table feedforward f(|y_d - y_rev|) / K_T with the sign "
        "of the motion (000 Fig. 17)",
    ),
    "friction_table.file": Param(
        "",
        meaning="friction table CSV (`servo_axis friction-table`); a relative path is relative "
        "to the scenario file",
    ),
}


def _file(values: FrictionTableValues) -> str | None:
    """Its table file when it is on (the check: one is named), not read."""
    keys = values.friction_table
    return term_file(keys.enabled, keys.file, "friction_table")


def _build(values: FrictionTableValues) -> FeedforwardTerm | None:
    path = _file(values)
    if path is None:
        return None
    try:
        table = load_friction_table(path)
    except (OSError, ServoAxisError) as err:
        raise ParameterFileError(f"parameter 'friction_table.file': {err}") from err
    return build(
        "",
        FrictionTableTerm,
        keys=NOMINAL_KEYS,
        table=table,
        torque_constant_Nm_per_A=values.nominal.torque_constant_Nm_per_A,
    )


#: The entry point ``servo_axis.feedforward_terms: friction_table``.
TERM = FeedforwardTermEntry(
    schema=SCHEMA,
    build=_build,
    check=_file,
    values=FrictionTableValues,
    files=("friction_table.file",),
    order=10.0,
    description="data-based friction table of a friction_id run (000 Fig. 17)",
)
