"""The per-sample topics as CDR bytes, with one :mod:`struct` call each way.

On the per-sample path a node spends more on rclpy's message handling than
on its own work: a reliable ``publish()`` of a message object costs its
conversion to C and its serialisation, and a subscription that hands over
message objects costs their deserialisation and the Python objects rclpy
builds (measured for a state: 4 us to serialise, 8 us to deserialise and
2 us to check it, against 1-2 us here). Every sample of a per-sample topic
on one axis has the same size and the same bytes but for its stamp and its
values, so a codec packs and unpacks it with one precompiled
:class:`struct.Struct`:

* :class:`JointCodec`: a JointState topic
  (:class:`~servo_axis.wire.layouts.JointLayout`: ``state``, ``command``,
  ``reference``, the learning corrections);
* :class:`ArrayCodec`: a per-step labelled Float64MultiArray of scalars
  (:class:`~servo_axis.wire.layouts.ArrayLayout` with ``per_step``:
  ``deformation``).

``encode`` gives the bytes a publisher of the message of
:mod:`servo_axis.wire.messages` sends (little-endian CDR, empty
``frame_id``, zero padding), byte for byte (``test_sample_cdr`` compares
them with rosbags' serialiser and with a bag); a publisher sends them as
they are (``publish(bytes)``), so a bag records the same payloads as before.
``decode`` takes a payload of a ``raw=True`` subscription. A payload of
exactly that shape is read in one call and checked as every subscriber
checks (finite values, a stamp on the control grid, each field's rule);
anything else, junk or another publisher's shape (big-endian, a
``frame_id``, padding), takes the general decoder
(:mod:`servo_axis.wire.cdr` and the layout's checks), which accepts and
refuses exactly what it did before, with the same error.

Nothing here imports rclpy.
"""

from __future__ import annotations

import struct
from typing import Any, Generic, TypeVar

from servo_axis.wire import cdr
from servo_axis.wire.checks import check_finite
from servo_axis.wire.layouts import ArrayLayout, JointLayout

__all__ = ["ArrayCodec", "JointCodec"]

S = TypeVar("S")

_NS_PER_S = 1_000_000_000
#: Encapsulation header of little-endian plain CDR; the last two bytes are
#: options, which a reader ignores.
_LITTLE_CDR = b"\x00\x01"
_OPTIONS = b"\x00\x00"


class _Shape:
    """A message of fixed shape as :mod:`struct` fields: header, constant runs and float64 runs.

    CDR aligns each primitive to its size, counted from the end of the
    4-byte encapsulation header; :meth:`put` writes constant bytes at an
    alignment, :meth:`values` leaves room for ``n`` float64s (8-aligned).
    """

    def __init__(self, head: str = "") -> None:
        self.fmt = ["<2s2s" + head]
        self.size = struct.calcsize("<" + head)  # bytes after the header
        self.constant = bytearray()
        self.constants: list[bytes] = []

    def put(self, data: bytes, align: int = 1) -> None:
        pad = -self.size % align
        self.constant.extend(b"\x00" * pad + data)
        self.size += pad + len(data)

    def uint32(self, value: int) -> None:
        self.put(struct.pack("<I", value), 4)

    def string(self, text: str) -> None:
        raw = text.encode()
        self.put(struct.pack("<I", len(raw) + 1) + raw + b"\x00", 4)

    def values(self, n: int) -> None:
        self.put(b"", 8)
        self.fmt.append(f"{len(self.constant)}s{n}d")
        self.constants.append(bytes(self.constant))
        self.constant.clear()
        self.size += 8 * n

    def done(self) -> tuple[struct.Struct, tuple[bytes, ...]]:
        if self.constant:
            self.fmt.append(f"{len(self.constant)}s")
            self.constants.append(bytes(self.constant))
        return struct.Struct("".join(self.fmt)), tuple(self.constants)


def _unpacked(
    codec: struct.Struct, constants: tuple[bytes, ...], n: int, head: int, data: Any
) -> tuple[tuple[Any, ...], list[float]] | None:
    """``(fields, values)`` of a payload of the codec's shape (constants equal); None otherwise."""
    if len(data) != codec.size or data[:2] != _LITTLE_CDR:
        return None
    fields = codec.unpack(data)
    k = 2 + head
    values: list[float] = []
    for constant in constants:
        if fields[k] != constant:
            return None
        values.extend(fields[k + 1 : k + 1 + n])
        k += 1 + n
    return fields, values


class _Codec:
    """What both codecs have: their precompiled :class:`struct.Struct`."""

    __slots__ = ("_struct",)
    _struct: struct.Struct

    @property
    def size(self) -> int:
        """Bytes of an encoded sample, encapsulation header included."""
        return self._struct.size


class JointCodec(_Codec, Generic[S]):
    """CDR bytes of one JointState topic on one axis, and back.

    Parameters
    ----------
    layout : JointLayout
        The topic's layout: joints, arrays in use, sample type.
    axis : str
        The axis of the joint names (``x``: ``x_motor``, ``x_table``).
    period_ns : int
        Control period ``T_u``, ns (> 0): sample ``k`` is stamped ``k * T_u``.

    Raises
    ------
    ValueError
        For a ``period_ns`` that is not a positive whole number.
    """

    __slots__ = (
        "_arrays",
        "_axis",
        "_constants",
        "_layout",
        "_n",
        "_period_ns",
        "_values_of",
    )

    def __init__(self, layout: JointLayout[S], *, axis: str, period_ns: int) -> None:
        if isinstance(period_ns, bool) or not isinstance(period_ns, int) or period_ns <= 0:
            raise ValueError(f"period_ns: expected a whole number of ns > 0, got {period_ns!r}")
        self._layout, self._axis, self._period_ns = layout, axis, period_ns
        self._values_of = layout.value_getter()
        names = layout.names(axis)
        n = len(names)
        self._n, self._arrays = n, layout.arrays
        shape = _Shape("iI")  # header.stamp
        shape.string("")  # header.frame_id
        shape.uint32(n)
        for name in names:
            shape.string(name)
        for array in ("position", "velocity", "effort"):
            used = array in layout.arrays
            shape.uint32(n if used else 0)
            if used:
                shape.values(n)
        self._struct, self._constants = shape.done()

    def encode(self, sample: S) -> bytes:
        """The CDR payload of ``sample`` (what ``publish(bytes)`` sends).

        Raises
        ------
        SignalError
            For a value that is not finite (naming the array and index, as
            :func:`servo_axis.wire.messages.write_state` and the others do).
        """
        values = self._values_of(sample)
        total = sum(values)
        if total - total != 0.0:
            n = self._n
            for i, array in enumerate(self._arrays):
                check_finite(array, values[i * n : (i + 1) * n])
            check_finite("values", values)
        ns = sample.step * self._period_ns  # type: ignore[attr-defined]
        fields: list[Any] = [_LITTLE_CDR, _OPTIONS, ns // _NS_PER_S, ns % _NS_PER_S]
        n = self._n
        for i, constant in enumerate(self._constants):
            fields.append(constant)
            fields.extend(values[i * n : (i + 1) * n])
        return self._struct.pack(*fields)

    def decode(self, data: Any) -> S:
        """The sample of a payload, after the checks every subscriber makes.

        Raises
        ------
        SignalError
            As :meth:`~servo_axis.wire.layouts.JointLayout.decode` of the
            payload decoded by :func:`servo_axis.wire.cdr.decode_joint_state`:
            a payload that does not decode, the wrong names or lengths, a
            value that is not finite, a stamp off the control grid.
        """
        got = _unpacked(self._struct, self._constants, self._n, 2, data)
        if got is not None:
            fields, values = got
            ns = fields[2] * _NS_PER_S + fields[3]
            step, rest = divmod(ns, self._period_ns)
            total = sum(values)
            if total - total == 0.0 and rest == 0 and ns >= 0:
                return self._layout.sample(step, *values)
        msg = cdr.decode_joint_state(data)
        return self._layout.decode(msg.name, msg, msg.stamp_ns, self._axis, self._period_ns)


class ArrayCodec(_Codec, Generic[S]):
    """CDR bytes of one per-step labelled Float64MultiArray topic of scalars, and back.

    Parameters
    ----------
    layout : ArrayLayout
        The topic's layout: a per-step vector (``per_step``, the step
        first) whose fields are scalars, with a sample class.

    Raises
    ------
    ValueError
        For a layout that is not per-step, has a field of other than one
        value, or no sample class.
    """

    __slots__ = ("_constants", "_layout", "_n")

    def __init__(self, layout: ArrayLayout[S]) -> None:
        if not layout.per_step or layout.sample is None or set(layout.sizes) != {1}:
            raise ValueError(
                f"layout: expected a per-step vector of scalars with a sample class, got "
                f"{layout.topic} (per_step={layout.per_step}, sizes {list(layout.sizes)})"
            )
        self._layout = layout
        n = self._n = len(layout.fields)
        shape = _Shape()
        shape.uint32(n)  # layout.dim
        for label in layout.labels:
            shape.string(label)
            shape.uint32(1)  # size
            shape.uint32(1)  # stride
        shape.uint32(0)  # layout.data_offset
        shape.uint32(n)
        shape.values(n)
        self._struct, self._constants = shape.done()

    def encode(self, sample: S) -> bytes:
        """The CDR payload of ``sample`` (the message of :func:`servo_axis.wire.messages.labelled_array`).

        Raises
        ------
        SignalError
            For a value that is not finite (``data[i]``, as
            :func:`servo_axis.wire.messages.write_deformation`).
        """
        values = check_finite("data", self._layout.values_of(sample))
        return self._struct.pack(_LITTLE_CDR, _OPTIONS, self._constants[0], *values)

    def decode(self, data: Any) -> S:
        """The sample of a payload, after the checks every subscriber makes.

        Raises
        ------
        SignalError
            As :meth:`~servo_axis.wire.layouts.ArrayLayout.values` of the
            payload decoded by :func:`servo_axis.wire.cdr.decode_float64_multi_array`:
            a payload that does not decode, other fields or sizes, a value
            that is not finite or that breaks its field's rule.
        """
        layout = self._layout
        got = _unpacked(self._struct, self._constants, self._n, 0, data)
        if got is not None:
            values = got[1]
            total = sum(values)
            if total - total == 0.0:
                for f, v in zip(layout.fields, values, strict=True):
                    f.check(v)
                return layout.sample_of(values)
        msg = cdr.decode_float64_multi_array(data)
        return layout.sample_of(layout.values(msg.labels, msg.sizes, msg.data, msg.strides))
