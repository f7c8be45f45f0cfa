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

The checks of a message's content are not here: the layout of every topic
and its rules are declared once in :mod:`servo_axis.wire.layouts` and apply
to these decoded payloads and to rclpy messages alike. This module re-exports
the few names other modules and documents take from it
(:data:`PROGRESS_LABELS`, :data:`ESTIMATE_LABELS`, :class:`EstimateData`,
:func:`check_estimate_values`, :func:`check_labelled_values`).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from servo_axis.core.errors import SignalError
from servo_axis.wire.checks import check_labelled_values as check_labelled_values
from servo_axis.wire.layouts import ESTIMATES, PROGRESS
from servo_axis.wire.layouts import EstimateData as EstimateData
from servo_axis.wire.layouts import check_estimate_values as check_estimate_values

__all__ = [
    "ESTIMATE_LABELS",
    "PROGRESS_LABELS",
    "SUPPORTED_TYPES",
    "ClockData",
    "EstimateData",
    "JointStateData",
    "MultiArrayData",
    "check_estimate_values",
    "check_labelled_values",
    "clock_ns_from_cdr",
    "decode",
    "decode_clock",
    "decode_float64_multi_array",
    "decode_joint_state",
]

#: Labels of ``recorder/progress`` and ``identifier/estimates``
#: (:data:`servo_axis.wire.layouts.PROGRESS`, :data:`~servo_axis.wire.layouts.ESTIMATES`).
PROGRESS_LABELS: tuple[str, ...] = PROGRESS.labels
ESTIMATE_LABELS: tuple[str, ...] = ESTIMATES.labels

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
