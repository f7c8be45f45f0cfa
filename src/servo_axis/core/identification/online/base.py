"""What the identifier node asks of an online identifier (paper 003 Fig. 3).

An implementation takes one control sample at a time (the measured angle
and the applied torque) and, once per its own period, returns an
:class:`~servo_axis.core.identification.online.dlpid.Estimate`; its whole state can
be saved and restored so that a restarted node resumes bit-identically.
:class:`~servo_axis.core.identification.online.dlpid.Dlpid` is one (both of its
modes); a new method is a class like it plus its entry (schema, builder,
entry point ``servo_axis.identification_methods``) in a module of its own
(:mod:`servo_axis.params.registry`; the suite's in ``servo_axis.plugins``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from servo_axis.core.identification.online.dlpid import Estimate


class OnlineIdentifier(Protocol):
    """An online identifier of ``J, D, U, C`` (003 eq. (2))."""

    @property
    def ratio(self) -> int:
        """Control samples per estimate (``T_RLS / T_u``)."""
        ...

    @property
    def last_step(self) -> int | None:
        """The last control sample taken (None before the first)."""
        ...

    def update(self, step: int, angle_rad: float, torque_Nm: float) -> Estimate | None:
        """Take control sample ``step`` (consecutive); an estimate at the end of each period."""
        ...

    def state(self) -> dict[str, Any]:
        """Everything needed to resume bit-identically (JSON-able)."""
        ...

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output."""
        ...
