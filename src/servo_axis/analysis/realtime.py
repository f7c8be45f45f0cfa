"""How the plant's clock kept time in a realtime run (``summary.json``'s ``realtime``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from servo_axis.analysis.serial import Serial


@dataclass(frozen=True)
class Realtime(Serial):
    """How the plant's clock kept time in a realtime run (its report, ``health.realtime``).

    A realtime run is never deterministic: which commands miss their
    deadline depends on the host. These figures say how far it was from
    the lockstep result (:mod:`servo_axis.core.deadlines`).

    Attributes
    ----------
    period_ns : int
        ``T_u``, ns.
    ticks : int
        Ticks of the clock (one step each).
    misses : int
        Ticks whose command had not arrived by the tick's deadline (the last
        current was held).
    commands_missing : int
        Steps whose command never arrived (counted in ``misses``).
    commands_late : int
        Commands that arrived more than a period after their state's tick
        (``misses = commands_late + commands_missing``).
    timer_rate : float
        Ticks per period of wall time from the start to the last tick (1.0:
        the clock kept time).
    tick_late_us, command_late_us : dict or None
        ``p50``, ``p99`` and ``max`` in us of the ticks' lateness (when the
        plant stepped after the deadline) and of the commands' (arrival after
        the tick of the state they answer: more than one period is a miss).
    floor : dict or None
        The floor of the host at this period (a result of ``python -m
        servo_axis floor --json``, ``run --floor FILE``); None (not written)
        if not given.
    scheduling : dict or None
        The plant process's scheduling: ``policy`` (``fifo`` or ``other``),
        ``priority`` and, where the system refused ``thread_priority``,
        ``refused`` (why); None from a plant that did not report it.
    references_held : int or None
        States the feedback answered without their reference, with the last
        one (the feedforward generator was late); None if not reported.
    late_estimates, late_corrections : int or None
        Online estimates (paper 003) and learning corrections that came after
        the samples they were for had gone out: applied from the next sample
        not yet published (the feedforward generator's report); None if not
        reported.
    clock_slips, slipped_periods : int or None
        Times the plant's clock woke so late that it re-based its deadlines
        rather than run the missed ticks back to back, and the periods it
        skipped so (:class:`~servo_axis.nodes.realtime.ClockThread`).
    states_skipped : int or None
        States the feedback never took: its stream jumped after it fell
        behind (:class:`~servo_axis.wire.streams.StreamGate`).
    answers_skipped : int or None
        States the feedback took but did not answer, to catch up with the
        clock (:class:`~servo_axis.nodes.realtime.CatchUp`).
    identifier_samples_held : int or None
        Steps the identifier ran with the last angle or torque held (a
        sample that never came).
    setpoints : dict or None
        ``command_source: drive_setpoint`` (a drive's set-points, of no
        step): ``period_ns`` (the commander's period the misses are judged
        by), ``received`` (finite set-points taken), ``unset`` (NaN ones:
        no command yet, never applied), ``quiet_ticks`` (ticks without a
        fresh set-point that were no miss: the commander quiet by design);
        ``misses`` are then the ticks whose newest set-point was older than
        1.5 periods (``commands_missing`` the same, ``commands_late`` 0);
        None otherwise.
    measured_from : str or None
        Where the figures come from when the plant is not the suite's (an
        outside plant: the feedback's arrival and send times,
        :func:`servo_axis.core.deadlines.loop_from_times`); None: the suite's
        plant's clock.
    """

    period_ns: int
    ticks: int
    misses: int
    commands_missing: int
    commands_late: int = field(metadata={"missing": 0})
    timer_rate: float
    tick_late_us: dict[str, float] | None = field(metadata={"missing": None})
    command_late_us: dict[str, float] | None = field(metadata={"missing": None})
    floor: dict[str, Any] | None = field(default=None, metadata={"omit_none": True})
    scheduling: dict[str, Any] | None = field(default=None, metadata={"omit_none": True})
    references_held: int | None = field(default=None, metadata={"omit_none": True})
    late_estimates: int | None = field(default=None, metadata={"omit_none": True})
    late_corrections: int | None = field(default=None, metadata={"omit_none": True})
    clock_slips: int | None = field(default=None, metadata={"omit_none": True})
    slipped_periods: int | None = field(default=None, metadata={"omit_none": True})
    states_skipped: int | None = field(default=None, metadata={"omit_none": True})
    answers_skipped: int | None = field(default=None, metadata={"omit_none": True})
    identifier_samples_held: int | None = field(default=None, metadata={"omit_none": True})
    setpoints: dict[str, int] | None = field(default=None, metadata={"omit_none": True})
    measured_from: str | None = field(default=None, metadata={"omit_none": True})

    @property
    def miss_fraction(self) -> float:
        """``misses / ticks`` (0 without ticks)."""
        return self.misses / self.ticks if self.ticks else 0.0
