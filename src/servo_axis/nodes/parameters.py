"""Parameter descriptors generated from the schemas, for ``ros2 param describe``.

Every key a node declares gets an ``rcl_interfaces/msg/ParameterDescriptor``
made from its :class:`~servo_axis.params.param.Param`:

* ``description``: the meaning and the unit (``[m]``);
* ``floating_point_range`` / ``integer_range`` where the schema has bounds
  (of every element, for a list of numbers). A descriptor's range is
  closed: an exclusive bound (``above=0.0``, "> 0") is given as the closed
  bound and the description says it is exclusive (the node refuses the
  bound itself); an integer's exclusive bound is exact
  (``above=0`` is ``from_value=1``). A side without a bound is
  ``-inf``/``+inf`` (the int64 limits for an integer); ``step`` is 0;
* ``additional_constraints``: the allowed strings, the range as the
  parameter reference writes it (``> 0, <= 1``);
* ``read_only``: every key, since the nodes read their values once, when
  they are made: a ``set_parameters`` while running is refused with rclpy's
  reason ("Trying to set a read-only parameter: ...") instead of being
  accepted and ignored.
"""

from __future__ import annotations

import math

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
)

from servo_axis.params.param import Param

INT64_MIN = -(2**63)
INT64_MAX = 2**63 - 1


def parameter_type(param: Param) -> int:
    """The ``ParameterType`` of a schema key (from the type of its default)."""
    default = param.default
    if isinstance(default, bool):
        return ParameterType.PARAMETER_BOOL
    if isinstance(default, int):
        return ParameterType.PARAMETER_INTEGER
    if isinstance(default, float):
        return ParameterType.PARAMETER_DOUBLE
    if isinstance(default, str):
        return ParameterType.PARAMETER_STRING
    if isinstance(default, list):
        elem = default[0] if default else 0.0
        if isinstance(elem, str):
            return ParameterType.PARAMETER_STRING_ARRAY
        if isinstance(elem, int) and not isinstance(elem, bool):
            return ParameterType.PARAMETER_INTEGER_ARRAY
        return ParameterType.PARAMETER_DOUBLE_ARRAY
    raise TypeError(f"no parameter type for a default {default!r}")


def descriptor(name: str, param: Param, *, read_only: bool = True) -> ParameterDescriptor:
    """The descriptor of schema key ``name``.

    Parameters
    ----------
    name : str
        The full (dotted) parameter name.
    param : Param
        Its schema entry.
    read_only : bool
        Whether a set while the node runs is refused.

    Returns
    -------
    rcl_interfaces.msg.ParameterDescriptor
    """
    kind = parameter_type(param)
    unit = f" [{param.unit}]" if param.unit else ""
    each = " (each element)" if isinstance(param.default, list) else ""
    constraints: list[str] = []
    if param.choices is not None:
        constraints.append("one of " + ", ".join(repr(c) for c in param.choices))
    out = ParameterDescriptor(
        name=name,
        type=kind,
        description=f"{param.meaning}{unit}".strip(),
        read_only=read_only,
    )
    numeric = {
        ParameterType.PARAMETER_DOUBLE,
        ParameterType.PARAMETER_DOUBLE_ARRAY,
        ParameterType.PARAMETER_INTEGER,
        ParameterType.PARAMETER_INTEGER_ARRAY,
    }
    bounded = any(b is not None for b in (param.minimum, param.maximum, param.above, param.below))
    if kind in numeric and bounded:
        integer = kind in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_INTEGER_ARRAY)
        if integer:
            low, high = _integer_bounds(param)
            out.integer_range = [IntegerRange(from_value=low, to_value=high, step=0)]
        else:
            lo = param.minimum if param.minimum is not None else param.above
            hi = param.maximum if param.maximum is not None else param.below
            out.floating_point_range = [
                FloatingPointRange(
                    from_value=-math.inf if lo is None else float(lo),
                    to_value=math.inf if hi is None else float(hi),
                    step=0.0,
                )
            ]
            exclusive = [
                f"{b:g}"
                for b, inclusive in ((param.above, param.minimum), (param.below, param.maximum))
                if b is not None and inclusive is None
            ]
            if exclusive:
                note = (
                    f"; range {param.range_text()}: the bound {' and '.join(exclusive)} "
                    "itself is refused (the descriptor's range is closed)"
                )
                out.description += note
        constraints.append(f"range {param.range_text()}{each}")
    elif kind in numeric:
        constraints.append(f"finite{each}")
    out.additional_constraints = "; ".join(constraints)
    return out


def _integer_bounds(param: Param) -> tuple[int, int]:
    """The closed integer range of a key (an exclusive bound made inclusive exactly)."""
    low, high = INT64_MIN, INT64_MAX
    if param.above is not None:
        low = math.floor(param.above) + 1
    if param.minimum is not None:
        low = max(low, math.ceil(param.minimum))
    if param.below is not None:
        high = math.ceil(param.below) - 1
    if param.maximum is not None:
        high = min(high, math.floor(param.maximum))
    return int(low), int(high)
