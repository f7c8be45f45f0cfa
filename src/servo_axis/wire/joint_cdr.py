"""The per-sample JointState topics as CDR bytes, with one :mod:`struct` call each way.

On the per-sample path a node spends more on rclpy's message handling than
on its own work: a reliable ``publish()`` of a JointState message object
costs its conversion to C and its serialisation, and a subscription that
hands over message objects costs their deserialisation and the Python
objects rclpy builds (measured: 4 us to serialise, 8 us to deserialise and
2 us to check a state, against 1-2 us here). Every sample of a topic of a
layout (:class:`~servo_axis.wire.layouts.JointLayout`) on one axis has the
same size and the same bytes but for its stamp and its values, so
:class:`JointCodec` packs and unpacks it with one precompiled
:class:`struct.Struct`:

* :meth:`JointCodec.encode` gives the bytes rclpy's serialiser gives for
  the message of :mod:`servo_axis.wire.messages` (little-endian CDR, empty
  ``frame_id``), byte for byte (``test_joint_cdr`` compares them); a
  publisher sends them as they are (``publish(bytes)``), so a bag records
  the same payloads as before.
* :meth:`JointCodec.decode` takes a payload of a ``raw=True``
  subscription. A payload of exactly that shape (the topic's names, the
  arrays' lengths, little-endian, empty ``frame_id``) is read in one call
  and checked as every subscriber checks (finite values, a stamp on the
  control grid); anything else, a junk message or another publisher's
  shape (big-endian, a ``frame_id``, padding), takes the general decoder
  (:func:`servo_axis.wire.cdr.decode_joint_state` and
  :meth:`~servo_axis.wire.layouts.JointLayout.decode`), which accepts and
  refuses exactly what it did before, with the same error.

Nothing here imports rclpy.
"""

from __future__ import annotations

import struct
from typing import Any, Generic, TypeVar

from servo_axis.wire import cdr
from servo_axis.wire.checks import check_finite
from servo_axis.wire.layouts import JointLayout

__all__ = ["JointCodec"]

S = TypeVar("S")

_NS_PER_S = 1_000_000_000
#: Encapsulation header of little-endian plain CDR; the last two bytes are
#: options, which a reader ignores.
_LITTLE_CDR = b"\x00\x01"
_OPTIONS = b"\x00\x00"


class JointCodec(Generic[S]):
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
        "_struct",
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
        # The message after the encapsulation header, as struct fields: the
        # stamp, then constant runs of bytes (frame_id, names, lengths,
        # alignment) between the arrays' values. CDR aligns each primitive
        # to its size, counted from the end of the header.
        fmt = ["<2s2siI"]
        constant = bytearray()
        constants: list[bytes] = []
        size = 8  # the stamp

        def put(data: bytes, align: int = 1) -> None:
            nonlocal size
            pad = -size % align
            constant.extend(b"\x00" * pad + data)
            size += pad + len(data)

        put(struct.pack("<I", 1) + b"\x00")  # frame_id: "" (its NUL)
        put(struct.pack("<I", n), 4)
        for name in names:
            raw = name.encode()
            put(struct.pack("<I", len(raw) + 1) + raw + b"\x00", 4)
        for array in ("position", "velocity", "effort"):
            used = array in layout.arrays
            put(struct.pack("<I", n if used else 0), 4)
            if used:
                put(b"", 8)
                fmt.append(f"{len(constant)}s{n}d")
                constants.append(bytes(constant))
                constant.clear()
                size += 8 * n
        if constant:
            fmt.append(f"{len(constant)}s")
            constants.append(bytes(constant))
        self._struct = struct.Struct("".join(fmt))
        self._constants = tuple(constants)

    @property
    def size(self) -> int:
        """Bytes of an encoded sample, encapsulation header included."""
        return self._struct.size

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
        if len(data) == self._struct.size and data[:2] == _LITTLE_CDR:
            fields = self._struct.unpack(data)
            n, k = self._n, 4
            values: list[float] = []
            for constant in self._constants:
                if fields[k] != constant:
                    return self._general(data)
                values.extend(fields[k + 1 : k + 1 + n])
                k += 1 + n
            ns = fields[2] * _NS_PER_S + fields[3]
            step, rest = divmod(ns, self._period_ns)
            total = sum(values)
            if total - total == 0.0 and rest == 0 and ns >= 0:
                return self._layout.sample(step, *values)
        return self._general(data)

    def _general(self, data: Any) -> S:
        msg = cdr.decode_joint_state(data)
        return self._layout.decode(msg.name, msg, msg.stamp_ns, self._axis, self._period_ns)
