"""Pure-Python decoders of the CDR payloads of the recorded message types.

Analysis code reads recorded bags (:func:`servo_axis.recording.reader.read_raw`)
where ROS may not be installed; these decoders turn the payloads of the three
types the recorder writes into frozen dataclasses, with :mod:`struct` only.

A payload is a 4-byte encapsulation header (``00 00``: big-endian CDR,
``00 01``: little-endian CDR, then two option bytes that are ignored) and the
message in plain CDR (XCDR1): every primitive is aligned to its own size,
counted from the end of the header; a string is a ``uint32`` length that counts
its NUL terminator, the bytes and the NUL; a sequence is a ``uint32`` element
count and the elements. Bytes after the message are ignored, as serialisers may
pad the buffer (``rclpy.serialization.serialize_message`` does).

Supported types: ``sensor_msgs/msg/JointState`` (:class:`JointStateData`),
``std_msgs/msg/Float64MultiArray`` (:class:`MultiArrayData`) and
``rosgraph_msgs/msg/Clock`` (:class:`ClockData`). Every malformed payload raises
:class:`~servo_axis.core.errors.SignalError`.

The checks the nodes apply to a message's content are here too, as pure
functions of plain values, so that the nodes (through
:mod:`servo_axis.wire.messages`, on rclpy messages) and the analysis (on the
decoded payloads of a bag) validate with the same code: joint names
(:func:`state_names`, :func:`motor_names`), array lengths and finiteness
(:func:`check_joint_arrays`, :func:`check_finite`), the stamp on the control
grid (:func:`step_of_stamp_ns`) and the layout of a Float64MultiArray
(:func:`check_labelled_values`, with the ``*_LABELS`` of each topic).

Every Float64MultiArray of the project has one ``MultiArrayDimension`` per
field, in order: ``label`` = the field's name with its unit (``step``,
``d_r_m_per_rad``, ``rms_m``), ``size`` = the number of values of the field
(1 for a scalar, ``n`` for a segment such as ``x_r_m`` of the friction
table), ``stride`` = ``size``; the sizes add up to ``len(data)``
(``data_offset`` is written 0). A vector that belongs to a control step carries that
step as its first field, ``step``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from servo_axis.core.errors import SignalError

__all__ = [
    "DEFORMATION_LABELS",
    "ESTIMATE_LABELS",
    "FAULT_LABELS",
    "PROGRESS_LABELS",
    "STATS_LABELS",
    "STATUS_LABELS",
    "SUPPORTED_TYPES",
    "ClockData",
    "EstimateData",
    "JointStateData",
    "MultiArrayData",
    "check_deformation_values",
    "check_estimate_values",
    "check_labelled_values",
    "clock_ns_from_cdr",
    "decode",
    "decode_clock",
    "decode_float64_multi_array",
    "decode_joint_state",
    "joint_state_step",
    "labelled_values",
    "motor_names",
    "state_names",
    "step_of_stamp_ns",
]

_NS_PER_S = 1_000_000_000
_HEADER = 4
# The smallest string on the wire: a uint32 length and the NUL.
_MIN_STRING = 5

_BIG, _LITTLE = 0x00, 0x01
_STRUCTS = {order: (struct.Struct(order + "I"), struct.Struct(order + "i")) for order in "<>"}


@dataclass(frozen=True, slots=True)
class JointStateData:
    """A decoded ``sensor_msgs/msg/JointState``.

    Attributes
    ----------
    stamp_ns : int
        ``header.stamp`` in ns (``sec * 10**9 + nanosec``).
    frame_id : str
        ``header.frame_id``.
    name, position, velocity, effort : tuple
        The joint names and the three float64 sequences, each possibly empty.
    """

    stamp_ns: int
    frame_id: str
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class MultiArrayData:
    """A decoded ``std_msgs/msg/Float64MultiArray``.

    Attributes
    ----------
    labels, sizes, strides : tuple
        ``layout.dim[i].label``, ``.size`` and ``.stride`` of every dimension.
    data_offset : int
        ``layout.data_offset``.
    data : tuple of float
        ``data``.
    """

    labels: tuple[str, ...]
    sizes: tuple[int, ...]
    strides: tuple[int, ...]
    data_offset: int
    data: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class ClockData:
    """A decoded ``rosgraph_msgs/msg/Clock``.

    Attributes
    ----------
    stamp_ns : int
        ``clock`` in ns (``sec * 10**9 + nanosec``).
    """

    stamp_ns: int


class _Cursor:
    """Reads one payload front to back; every read checks the bytes left."""

    __slots__ = ("_buf", "_end", "_int32", "_order", "_pos", "_type", "_uint32")

    def __init__(self, data: Any, type_name: str) -> None:
        self._type = type_name
        try:
            # One copy up front: slicing bytes is cheap and struct reads any buffer.
            self._buf = data if type(data) is bytes else bytes(memoryview(data))
        except TypeError:
            raise SignalError(
                f"{type_name}: expected a bytes-like CDR payload, got {type(data).__name__}"
            ) from None
        self._end = len(self._buf)
        if self._end < _HEADER:
            raise SignalError(
                f"{type_name}: payload of {self._end} bytes is shorter than the "
                f"{_HEADER}-byte encapsulation header"
            )
        kind, order = self._buf[0], self._buf[1]
        if kind != 0 or order not in (_BIG, _LITTLE):
            raise SignalError(
                f"{type_name}: unsupported encapsulation header {self._buf[:2].hex()} "
                "(expected 0000 for big-endian or 0001 for little-endian plain CDR)"
            )
        self._order = "<" if order == _LITTLE else ">"
        self._uint32, self._int32 = _STRUCTS[self._order]
        self._pos = _HEADER

    def _take(self, size: int, align: int, field: str) -> int:
        """Offset of the next ``size`` bytes aligned to ``align``; advance past them."""
        # Alignment counts from the end of the encapsulation header.
        pos = self._pos + (-(self._pos - _HEADER) % align)
        if pos + size > self._end:
            raise SignalError(
                f"{self._type}: payload truncated at {field}: needs {size} bytes at offset "
                f"{pos}, the payload has {self._end} bytes"
            )
        self._pos = pos + size
        return pos

    def uint32(self, field: str) -> int:
        value: int = self._uint32.unpack_from(self._buf, self._take(4, 4, field))[0]
        return value

    def int32(self, field: str) -> int:
        value: int = self._int32.unpack_from(self._buf, self._take(4, 4, field))[0]
        return value

    def sequence_length(self, field: str, min_element_size: int) -> int:
        """A sequence length, checked against the bytes left before anything is allocated."""
        count = self.uint32(f"{field} length")
        left = self._end - self._pos
        if count * min_element_size > left:
            raise SignalError(
                f"{self._type}: payload truncated or garbage at {field}: {count} elements "
                f"need at least {count * min_element_size} bytes, {left} are left"
            )
        return count

    def string(self, field: str) -> str:
        length = self.uint32(f"{field} length")
        if length == 0:
            # Not valid CDR, but some serialisers write an empty string so.
            return ""
        start = self._take(length, 1, field)
        stop = start + length - 1
        if self._buf[stop] != 0:
            raise SignalError(
                f"{self._type}: string {field} of length {length} at offset {start} "
                "does not end with its NUL terminator"
            )
        try:
            return self._buf[start:stop].decode("utf-8")
        except UnicodeDecodeError as err:
            raise SignalError(f"{self._type}: string {field} is not UTF-8: {err}") from None

    def strings(self, field: str) -> tuple[str, ...]:
        count = self.sequence_length(field, _MIN_STRING)
        return tuple(self.string(f"{field}[{i}]") for i in range(count))

    def float64s(self, field: str) -> tuple[float, ...]:
        count = self.sequence_length(field, 8)
        if count == 0:
            return ()
        start = self._take(8 * count, 8, field)
        return struct.unpack_from(f"{self._order}{count}d", self._buf, start)

    def stamp_ns(self, field: str) -> int:
        """A ``builtin_interfaces/msg/Time`` (int32 sec, uint32 nanosec) in ns."""
        sec = self.int32(f"{field}.sec")
        return sec * _NS_PER_S + self.uint32(f"{field}.nanosec")


def decode_joint_state(data: bytes) -> JointStateData:
    """Decode a ``sensor_msgs/msg/JointState`` CDR payload.

    Parameters
    ----------
    data : bytes
        The payload, encapsulation header included (bytes-like).

    Returns
    -------
    JointStateData
        Every field of the message.

    Raises
    ------
    SignalError
        If the payload is truncated, has an unsupported encapsulation header,
        a string without its NUL terminator or a non-UTF-8 string.
    """
    cur = _Cursor(data, "sensor_msgs/msg/JointState")
    return JointStateData(
        stamp_ns=cur.stamp_ns("header.stamp"),
        frame_id=cur.string("header.frame_id"),
        name=cur.strings("name"),
        position=cur.float64s("position"),
        velocity=cur.float64s("velocity"),
        effort=cur.float64s("effort"),
    )


def decode_float64_multi_array(data: bytes) -> MultiArrayData:
    """Decode a ``std_msgs/msg/Float64MultiArray`` CDR payload.

    Parameters
    ----------
    data : bytes
        The payload, encapsulation header included (bytes-like).

    Returns
    -------
    MultiArrayData
        The layout (labels, sizes and strides of the dimensions, data offset)
        and the data.

    Raises
    ------
    SignalError
        If the payload is truncated, has an unsupported encapsulation header,
        a string without its NUL terminator or a non-UTF-8 string.
    """
    cur = _Cursor(data, "std_msgs/msg/Float64MultiArray")
    # A dimension is at least a string and two uint32.
    count = cur.sequence_length("layout.dim", _MIN_STRING + 8)
    labels, sizes, strides = [], [], []
    for i in range(count):
        labels.append(cur.string(f"layout.dim[{i}].label"))
        sizes.append(cur.uint32(f"layout.dim[{i}].size"))
        strides.append(cur.uint32(f"layout.dim[{i}].stride"))
    return MultiArrayData(
        labels=tuple(labels),
        sizes=tuple(sizes),
        strides=tuple(strides),
        data_offset=cur.uint32("layout.data_offset"),
        data=cur.float64s("data"),
    )


def decode_clock(data: bytes) -> ClockData:
    """Decode a ``rosgraph_msgs/msg/Clock`` CDR payload.

    Parameters
    ----------
    data : bytes
        The payload, encapsulation header included (bytes-like).

    Returns
    -------
    ClockData
        The clock time in ns.

    Raises
    ------
    SignalError
        If the payload is truncated or has an unsupported encapsulation header.
    """
    return ClockData(stamp_ns=_Cursor(data, "rosgraph_msgs/msg/Clock").stamp_ns("clock"))


_TIME = {_BIG: struct.Struct(">iI"), _LITTLE: struct.Struct("<iI")}


def clock_ns_from_cdr(data: bytes) -> int:
    """``clock`` (ns) of a ``rosgraph_msgs/msg/Clock`` CDR payload, read in place.

    The two fields of the time right after the 4-byte encapsulation header
    (either byte order), like
    :func:`servo_axis.wire.messages.stamp_ns_from_cdr` for a header stamp,
    without building a :class:`ClockData`: the recorder reads it for every
    ``/clock`` message it logs.

    Raises
    ------
    SignalError
        If the payload is shorter than a header and a time, has an unsupported
        encapsulation header or a ``nanosec`` of 10**9 or more.
    """
    if len(data) < _HEADER + 8 or data[0] != 0 or data[1] not in _TIME:
        raise SignalError(
            "rosgraph_msgs/msg/Clock: expected a CDR-encapsulated payload of at least 12 bytes"
        )
    sec, nanosec = _TIME[data[1]].unpack_from(data, _HEADER)
    if nanosec >= _NS_PER_S:
        raise SignalError(f"clock.nanosec: expected 0..999999999, got {nanosec}")
    return int(sec) * _NS_PER_S + int(nanosec)


_DECODERS: dict[str, Callable[[bytes], Any]] = {
    "sensor_msgs/msg/JointState": decode_joint_state,
    "std_msgs/msg/Float64MultiArray": decode_float64_multi_array,
    "rosgraph_msgs/msg/Clock": decode_clock,
}

#: The message types :func:`decode` accepts, ``pkg/msg/Type``.
SUPPORTED_TYPES: tuple[str, ...] = tuple(_DECODERS)


def decode(type_name: str, data: bytes) -> JointStateData | MultiArrayData | ClockData:
    """Decode a CDR payload of one of the :data:`SUPPORTED_TYPES`.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type`` (as in a bag) or ``pkg/Type``.
    data : bytes
        The payload, encapsulation header included (bytes-like).

    Returns
    -------
    JointStateData or MultiArrayData or ClockData
        The decoded message.

    Raises
    ------
    SignalError
        If the type is not supported or the payload is malformed.
    """
    name = type_name
    if isinstance(name, str) and name.count("/") == 1:
        package, _, short = name.partition("/")
        name = f"{package}/msg/{short}"
    decoder = _DECODERS.get(name) if isinstance(name, str) else None
    if decoder is None:
        raise SignalError(
            f"type_name: no CDR decoder for {type_name!r}, expected one of {list(SUPPORTED_TYPES)}"
        )
    result: JointStateData | MultiArrayData | ClockData = decoder(data)
    return result


# -- checks shared by the nodes and the analysis -------------------------------

#: Field labels of the Float64MultiArray topics (one dimension per field,
#: each of size 1 unless a topic says otherwise).
STATUS_LABELS: tuple[str, ...] = (
    "step",
    "deadline_misses",
    "rejected_commands",
    "command_timeouts",
)
PROGRESS_LABELS: tuple[str, ...] = ("steps_recorded",)
FAULT_LABELS: tuple[str, ...] = (
    "step",
    "code(1=following_error;2=travel;3=current;4=input_timeout)",
    "value(m_or_A_or_s)",
)
STATS_LABELS: tuple[str, ...] = ("cycle", "rms_m", "max_m", "cycles_learned")
#: ``deformation`` (004 eqs. (5)-(7)): the control step, ``d_r`` (0 where not
#: defined), the scale's increment ``x_t[k] - x_t[k-p]``, the encoder's
#: ``th_m[k] - th_m[k-p]`` and whether ``d_r`` is defined (1/0).
DEFORMATION_LABELS: tuple[str, ...] = (
    "step",
    "d_r_m_per_rad",
    "scale_increment_m",
    "encoder_increment_rad",
    "valid",
)
#: ``identifier/estimates``: the last control sample the estimate was computed
#: from, the first it applies to, ``J, D, U, C`` (003 eq. (2)), the PE index
#: of eq. (7) and whether each parameter was updated at this RLS step (1/0).
ESTIMATE_LABELS: tuple[str, ...] = (
    "step",
    "applies_from_step",
    "inertia_kgm2",
    "damping_Nms_per_rad",
    "unbalance_Nm",
    "coulomb_Nm",
    "kappa",
    "updated_inertia",
    "updated_damping",
    "updated_unbalance",
    "updated_coulomb",
)


@dataclass(frozen=True)
class EstimateData:
    """One online estimate of the identifier (topic ``identifier/estimates``).

    Attributes
    ----------
    step : int
        The last control sample the estimate was computed from (>= 0).
    applies_from_step : int
        The first control sample whose feedforward uses it (> ``step``).
    inertia_kgm2, damping_Nms_per_rad, unbalance_Nm, coulomb_Nm : float
        ``J`` (> 0), ``D``, ``U``, ``C`` (>= 0) of 003 eq. (2).
    kappa : float
        PE index of 003 eq. (7) (0 until its window is full).
    updated : tuple of 4 bool
        Whether ``J``, ``D``, ``U`` (eq. (16)) and ``C`` (eq. (8)) were updated.
    """

    step: int
    applies_from_step: int
    inertia_kgm2: float
    damping_Nms_per_rad: float
    unbalance_Nm: float
    coulomb_Nm: float
    kappa: float
    updated: tuple[bool, bool, bool, bool]

    def values(self) -> list[float]:
        """The message's data, in :data:`ESTIMATE_LABELS` order."""
        return [
            float(self.step),
            float(self.applies_from_step),
            self.inertia_kgm2,
            self.damping_Nms_per_rad,
            self.unbalance_Nm,
            self.coulomb_Nm,
            self.kappa,
            *(1.0 if u else 0.0 for u in self.updated),
        ]


def check_estimate_values(values: Sequence[float]) -> EstimateData:
    """An :class:`EstimateData` of the values of an ``identifier/estimates`` message.

    The values are in :data:`ESTIMATE_LABELS` order (:func:`check_labelled_values`
    checks the layout); ``kappa``, an eigenvalue, may be a rounding below 0.

    Raises
    ------
    SignalError
        A value that is not finite, a step that is not whole and >= 0, an
        application step not after it,
        ``J <= 0``, a negative ``D``, ``U`` or ``C``, or a flag not 0 or 1.
    """
    if len(values) != len(ESTIMATE_LABELS):
        raise SignalError(f"data: expected {len(ESTIMATE_LABELS)} values, got {len(values)}")
    check_finite("data", values)
    step, applies, j, d, u, c, kappa = (float(v) for v in values[:7])
    if step != int(step) or step < 0:
        raise SignalError(f"step: expected a whole number >= 0, got {step!r}")
    if applies != int(applies) or applies <= step:
        raise SignalError(
            f"applies_from_step: expected a whole number after step {int(step)}, got {applies!r}"
        )
    if not j > 0.0:
        raise SignalError(f"inertia_kgm2: expected a value > 0, got {j!r}")
    for name, v in (("damping_Nms_per_rad", d), ("unbalance_Nm", u), ("coulomb_Nm", c)):
        if v < 0.0:
            raise SignalError(f"{name}: expected a value >= 0, got {v!r}")
    flags = [float(v) for v in values[7:]]
    for label, f in zip(ESTIMATE_LABELS[7:], flags, strict=True):
        if f not in (0.0, 1.0):
            raise SignalError(f"{label}: expected 0 or 1, got {f!r}")
    return EstimateData(
        step=int(step),
        applies_from_step=int(applies),
        inertia_kgm2=j,
        damping_Nms_per_rad=d,
        unbalance_Nm=u,
        coulomb_Nm=c,
        kappa=kappa,
        updated=(flags[0] == 1.0, flags[1] == 1.0, flags[2] == 1.0, flags[3] == 1.0),
    )


def state_names(axis: str) -> list[str]:
    """Joint names of the ``state`` topic: ``[<axis>_motor, <axis>_table]``."""
    return [f"{axis}_motor", f"{axis}_table"]


def motor_names(axis: str) -> list[str]:
    """Joint names of the ``command``, ``reference`` and ``learning/correction`` topics."""
    return [f"{axis}_motor"]


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


def check_deformation_values(values: Sequence[float]) -> int:
    """The step of the values of a ``deformation`` message (:data:`DEFORMATION_LABELS` order).

    Raises
    ------
    SignalError
        A step that is not a whole number >= 0, or ``valid`` neither 0 nor 1
        (:func:`check_labelled_values` checks the layout and finiteness).
    """
    step, valid = values[0], values[4]
    if step != int(step) or step < 0:
        raise SignalError(f"step: expected a whole number >= 0, got {step!r}")
    if valid not in (0.0, 1.0):
        raise SignalError(f"valid: expected 0 or 1, got {valid!r}")
    return int(step)


def joint_state_step(
    msg: JointStateData, names: Sequence[str], fields: Sequence[str], period_ns: int
) -> int:
    """The control step of a decoded JointState that passes the subscribers' checks.

    ``names`` are the joint names the topic must carry (:func:`state_names`,
    :func:`motor_names`) and ``fields`` the arrays it uses (one finite value
    per name each); the stamp must be on the grid of ``period_ns``.

    Raises
    ------
    SignalError
        Naming what is wrong (as :mod:`servo_axis.wire.messages` does).
    """
    check_joint_arrays(msg.name, names, ((f, getattr(msg, f)) for f in fields))
    return step_of_stamp_ns(msg.stamp_ns, period_ns)


def labelled_values(
    msg: MultiArrayData, labels: Sequence[str], *, sizes: Sequence[int | None] | None = None
) -> list[float]:
    """The values of a decoded labelled Float64MultiArray (:func:`check_labelled_values`)."""
    return check_labelled_values(
        msg.labels, msg.sizes, msg.data, labels, dim_strides=msg.strides, sizes=sizes
    )
