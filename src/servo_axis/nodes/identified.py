"""Subscriptions that say which publisher sent each message.

rclpy 7.1.6 (Jazzy) hands a subscription callback the message and, at
most, a ``MessageInfo`` of timestamps and sequence numbers: the
publisher's GID, which rmw puts in ``rmw_message_info_t.publisher_gid``
for every message it takes, is not passed on (``Subscription.take_message``
of rclpy's C++ layer builds the dict without it), and the
``EventsExecutor`` cannot call a callback that takes a ``MessageInfo`` at
all (measured: ``SystemError: null argument to internal routine``). A node
that must apply only its producer's messages needs that GID.

:class:`IdentifiedSubscription` is an rclpy subscription taken by the node
itself: a :class:`rclpy.waitable.Waitable` whose rcl subscription is the
one ``Node.create_subscription`` would make (same topic, type, QoS, event
handlers), and whose messages are taken with ``rcl_take_serialized_message``
through :mod:`ctypes`, with their ``rmw_message_info_t``. Both of rclpy's
executors run Waitables (the ``SingleThreadedExecutor`` from its wait set,
the ``EventsExecutor`` from rcl's new-message callback), and the callback
gets ``(payload, gid)``: the CDR bytes as a ``raw=True`` subscription would
give them, and the publisher's GID in the hex of
:attr:`servo_axis.nodes.graph.Endpoint.gid` (what the ROS graph lists for
that publisher). Measured on one core, 5,000 queued messages: 36 us a
message with the ``EventsExecutor`` (50 us for a plain raw subscription),
136 us with the ``SingleThreadedExecutor`` (336 us).

The structures are Jazzy's (rmw 7.3, rcutils 6.7: ``RMW_GID_STORAGE_SIZE``
16); ``test/unit/nodes/test_identified_layout.py`` compiles their
``sizeof``/``offsetof`` against the installed headers, and the first
message taken checks that the GID's implementation identifier is the rmw
in use (a layout that moved would not read it).
"""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Callable
from typing import Any

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.type_support import check_is_valid_msg_type
from rclpy.waitable import NumberOfEntities, Waitable

#: ``RCL_RET_SUBSCRIPTION_TAKE_FAILED`` (rcl/types.h): nothing to take.
_TAKE_FAILED = 401
#: ``RMW_GID_STORAGE_SIZE`` (rmw/types.h, Jazzy).
GID_SIZE = 16


class Allocator(ctypes.Structure):
    """``rcutils_allocator_t``."""

    _fields_ = [
        ("allocate", ctypes.c_void_p),
        ("deallocate", ctypes.c_void_p),
        ("reallocate", ctypes.c_void_p),
        ("zero_allocate", ctypes.c_void_p),
        ("state", ctypes.c_void_p),
    ]


class Uint8Array(ctypes.Structure):
    """``rcutils_uint8_array_t`` (``rcl_serialized_message_t``)."""

    _fields_ = [
        ("buffer", ctypes.POINTER(ctypes.c_uint8)),
        ("buffer_length", ctypes.c_size_t),
        ("buffer_capacity", ctypes.c_size_t),
        ("allocator", Allocator),
    ]


class Gid(ctypes.Structure):
    """``rmw_gid_t``."""

    _fields_ = [
        ("implementation_identifier", ctypes.c_char_p),
        ("data", ctypes.c_uint8 * GID_SIZE),
    ]


class MessageInfo(ctypes.Structure):
    """``rmw_message_info_t``."""

    _fields_ = [
        ("source_timestamp", ctypes.c_int64),
        ("received_timestamp", ctypes.c_int64),
        ("publication_sequence_number", ctypes.c_uint64),
        ("reception_sequence_number", ctypes.c_uint64),
        ("publisher_gid", Gid),
        ("from_intra_process", ctypes.c_bool),
    ]


class _Rcl:
    """The rcl and rcutils functions used, loaded once (the libraries rclpy loaded)."""

    def __init__(self) -> None:
        rcl = _load("librcl.so")
        rcutils = _load("librcutils.so")
        self.take = rcl.rcl_take_serialized_message
        self.take.argtypes = [
            ctypes.c_void_p,
            ctypes.POINTER(Uint8Array),
            ctypes.POINTER(MessageInfo),
            ctypes.c_void_p,
        ]
        self.take.restype = ctypes.c_int
        self.default_allocator = rcutils.rcutils_get_default_allocator
        self.default_allocator.restype = Allocator
        self.array_init = rcutils.rcutils_uint8_array_init
        self.array_init.argtypes = [
            ctypes.POINTER(Uint8Array),
            ctypes.c_size_t,
            ctypes.POINTER(Allocator),
        ]
        self.array_init.restype = ctypes.c_int
        self.array_fini = rcutils.rcutils_uint8_array_fini
        self.array_fini.argtypes = [ctypes.POINTER(Uint8Array)]
        self.array_fini.restype = ctypes.c_int


def _load(name: str) -> ctypes.CDLL:
    """A ROS library: the one the process has (found on the wheels' library path), else the venv's."""
    try:
        return ctypes.CDLL(name)
    except OSError:
        return ctypes.CDLL(os.path.join(sys.prefix, "lib", name))


_RCL: _Rcl | None = None


def _rcl() -> _Rcl:
    global _RCL
    if _RCL is None:
        _RCL = _Rcl()
    return _RCL


class IdentifiedSubscription(Waitable):  # type: ignore[misc]
    """A subscription whose callback gets each message's CDR bytes and its publisher's GID.

    Parameters
    ----------
    node : rclpy.node.Node
        The node it belongs to (its namespace resolves ``topic``; its default
        callback group).
    msg_type : type
        The message class.
    topic : str
        The topic, as for ``create_subscription``.
    qos_profile : QoSProfile
        The profile asked for.
    callback : callable
        ``callback(data, gid)``: the payload (``bytes``, as a ``raw=True``
        subscription gives it) and the publisher's GID (hex).
    event_callbacks : SubscriptionEventCallbacks or None
        As for ``create_subscription`` (liveliness, and rclpy's default
        handler of an incompatible QoS).
    """

    def __init__(
        self,
        node: Node,
        msg_type: Any,
        topic: str,
        qos_profile: QoSProfile,
        callback: Callable[[bytes, str], None],
        *,
        event_callbacks: SubscriptionEventCallbacks | None = None,
    ) -> None:
        group = node.default_callback_group
        super().__init__(group)
        self._rcl = _rcl()
        self._node = node
        self.topic = topic
        self.callback = callback
        check_is_valid_msg_type(msg_type)  # imports the type support, as rclpy does
        with node.handle:
            self.handle = _rclpy.Subscription(
                node.handle, msg_type, topic, qos_profile.get_c_qos_profile()
            )
        self._buffer = Uint8Array()
        allocator = self._rcl.default_allocator()
        if self._rcl.array_init(ctypes.byref(self._buffer), 0, ctypes.byref(allocator)) != 0:
            self.handle.destroy_when_not_in_use()
            raise MemoryError(f"cannot make a message buffer for {topic}")
        self._info = MessageInfo()
        self._index: int | None = None
        self._checked = False
        self._destroyed = False
        callbacks = event_callbacks or SubscriptionEventCallbacks()
        self.event_handlers = callbacks.create_event_handlers(group, self.handle, topic)
        for handler in self.event_handlers:
            node.add_waitable(handler)
        node.add_waitable(self)

    # -- what rclpy's executors ask of a Waitable ----------------------------------------
    def __enter__(self) -> None:
        self.handle.__enter__()

    def __exit__(self, t: Any, v: Any, tb: Any) -> None:
        self.handle.__exit__(t, v, tb)

    def get_num_entities(self) -> NumberOfEntities:
        return NumberOfEntities(num_subs=1)

    def add_to_wait_set(self, wait_set: Any) -> None:
        self._index = wait_set.add_subscription(self.handle)

    def is_ready(self, wait_set: Any) -> bool:
        return self._index is not None and bool(wait_set.is_ready("subscription", self._index))

    def take_data(self) -> tuple[bytes, str] | None:
        """One message and its publisher's GID (None: nothing to take)."""
        if self._destroyed:
            return None
        ret = self._rcl.take(
            self.handle.pointer, ctypes.byref(self._buffer), ctypes.byref(self._info), None
        )
        if ret == _TAKE_FAILED:
            return None
        if ret != 0:
            raise RuntimeError(f"rcl_take_serialized_message on {self.topic} failed ({ret})")
        gid = self._info.publisher_gid
        if not self._checked:
            self._check(gid)
        data = ctypes.string_at(self._buffer.buffer, self._buffer.buffer_length)
        return data, bytes(gid.data).hex()

    async def execute(self, taken_data: tuple[bytes, str] | None) -> None:
        if taken_data is not None:
            self.callback(*taken_data)

    def _check(self, gid: Gid) -> None:
        """The first GID names the rmw in use: the structures are laid out as rmw's."""
        import rclpy

        expected = rclpy.get_rmw_implementation_identifier()
        got = gid.implementation_identifier
        if got is None or got.decode(errors="replace") != expected:
            raise RuntimeError(
                f"rmw_message_info_t as read here names rmw {got!r}, not {expected!r}: "
                "the structure's layout is not Jazzy's (servo_axis.nodes.identified)"
            )
        self._checked = True

    # -- what a subscription offers ------------------------------------------------------
    def get_publisher_count(self) -> int:
        """Publishers matched with this subscription."""
        with self.handle:
            return int(self.handle.get_publisher_count())

    def destroy(self) -> None:
        """Remove it from its node and free the rcl subscription and the buffer (idempotent)."""
        if self._destroyed:
            return
        self._destroyed = True
        for waitable in (self, *self.event_handlers):
            try:
                self._node.remove_waitable(waitable)
            except ValueError:
                pass
        for handler in self.event_handlers:
            handler.destroy()
        self.handle.destroy_when_not_in_use()
        self._rcl.array_fini(ctypes.byref(self._buffer))
