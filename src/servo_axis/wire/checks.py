"""Pure checks of a message's content, shared by the nodes and the analysis.

The nodes apply them to rclpy messages (:mod:`servo_axis.wire.messages`) and
the analysis to the decoded payloads of a bag (:mod:`servo_axis.wire.cdr`),
through the topic layouts of :mod:`servo_axis.wire.layouts`: one rule for
both. Array lengths and finiteness (:func:`check_joint_arrays`,
:func:`check_finite`), the stamp on the control grid
(:func:`step_of_stamp_ns`) and the layout of a labelled Float64MultiArray
(:func:`check_labelled_values`). Each raises
:class:`~servo_axis.core.errors.SignalError` naming what is wrong. Nothing
here imports rclpy.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from servo_axis.core.errors import SignalError

__all__ = ["check_finite", "check_joint_arrays", "check_labelled_values", "step_of_stamp_ns"]


def check_finite(name: str, values: Sequence[float]) -> Sequence[float]:
    """``values`` if every one is finite, else :class:`SignalError` naming ``name[i]``.

    Sums beyond 1e308 are no physical signal either and are refused too.
    """
    # Fast path: the sum of finite values is finite.
    total = sum(values)
    if total - total == 0.0:
        return values
    for i, v in enumerate(values):
        if not math.isfinite(v):
            raise SignalError(f"{name}[{i}]: expected a finite number, got {v!r}")
    raise SignalError(f"{name}: values too large to be a physical signal, got {list(values)}")


def check_joint_arrays(
    got_names: Sequence[str],
    names: Sequence[str],
    arrays: Iterable[tuple[str, Sequence[float]]],
) -> None:
    """Check a JointState's names and arrays as every subscriber does.

    Parameters
    ----------
    got_names : sequence of str
        The message's ``name``.
    names : sequence of str
        The names it must have, in order.
    arrays : iterable of (field, values)
        The arrays the topic uses (``position``, ...): each must hold one
        finite value per name.

    Raises
    ------
    SignalError
        Naming the first field that is wrong.
    """
    if list(got_names) != list(names):
        raise SignalError(f"name: expected {list(names)}, got {list(got_names)}")
    for field, values in arrays:
        if len(values) != len(names):
            raise SignalError(f"{field}: expected {len(names)} values, got {len(values)}")
        check_finite(field, values)


def step_of_stamp_ns(ns: int, period_ns: int) -> int:
    """Control sample of a stamp of ``ns`` nanoseconds; :class:`SignalError` off the grid."""
    step, rem = divmod(ns, period_ns)
    if rem != 0 or ns < 0:
        raise SignalError(f"header.stamp: {ns} ns is not on the control grid of {period_ns} ns")
    return int(step)


def check_labelled_values(
    dim_labels: Sequence[str],
    dim_sizes: Sequence[int],
    data: Sequence[float],
    labels: Sequence[str],
    *,
    dim_strides: Sequence[int] | None = None,
    sizes: Sequence[int | None] | None = None,
) -> list[float]:
    """The values of a labelled Float64MultiArray after checking its layout.

    The layout has one dimension per field, in order: ``label`` = the
    field's name, ``size`` = its number of values, ``stride`` = ``size``;
    the sizes add up to ``len(data)``.

    Parameters
    ----------
    dim_labels, dim_sizes : sequence
        ``layout.dim[i].label`` and ``.size`` of the message.
    data : sequence of float
        ``data``.
    labels : sequence of str
        The fields the topic has, in order.
    dim_strides : sequence of int or None
        ``layout.dim[i].stride`` (checked equal to the sizes); None: not checked.
    sizes : sequence of (int or None) or None
        The size each field must have (None for a segment of any length);
        None: every field is a scalar (size 1).

    Returns
    -------
    list of float
        ``data``, every value finite.

    Raises
    ------
    SignalError
        Naming what is wrong: the fields, a size, a stride, the total length
        or a value that is not finite.
    """
    if list(dim_labels) != list(labels):
        raise SignalError(
            f"layout.dim: expected one dimension per field {list(labels)}, got {list(dim_labels)}"
        )
    want = [1] * len(labels) if sizes is None else list(sizes)
    for label, got, expected in zip(labels, dim_sizes, want, strict=True):
        if expected is not None and got != expected:
            raise SignalError(f"layout.dim {label!r}: expected size {expected}, got {got}")
    if dim_strides is not None and list(dim_strides) != list(dim_sizes):
        raise SignalError(
            f"layout.dim: expected strides equal to the sizes {list(dim_sizes)}, "
            f"got {list(dim_strides)}"
        )
    if sum(dim_sizes) != len(data):
        raise SignalError(
            f"data: expected {sum(dim_sizes)} values (sizes {list(dim_sizes)} of "
            f"{list(labels)}), got {len(data)}"
        )
    return [float(v) for v in check_finite("data", data)]
