"""Errors of :mod:`servo_axis.recording`.

Each is a subclass of the :mod:`servo_axis.core.errors` class that the bag code
raised before these existed, so that ``except ConfigError`` and
``except SignalError`` written against the old code still catch them.
"""

from __future__ import annotations

from servo_axis.core.errors import ConfigError, SignalError

__all__ = ["BagError", "BagWriteError", "NoBagError", "NotMcapError"]


class BagError(ConfigError):
    """A bag, its ``metadata.yaml``, a message type name or a writer setting is invalid."""


class BagWriteError(SignalError):
    """A :meth:`~servo_axis.recording.writer.BagWriter.write` call is invalid.

    The topic is not registered, the bag is closed, or a time is not an
    int >= 0.
    """


class NoBagError(BagError):
    """There is no bag to read or recover: no such directory, or no MCAP file in it."""


class NotMcapError(BagError):
    """A bag's data file is not an MCAP file (it does not start with the MCAP magic)."""
