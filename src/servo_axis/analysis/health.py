"""What happened to a run besides its numbers: node deaths, restarts, fallbacks, strangers.

The runner gathers it (process exit codes, restarts, the nodes' own reports
of :mod:`servo_axis.wire.node_report`) into a :class:`RunHealth`, which goes into
``summary.json`` (``health``) and decides the exit code of ``python -m
servo_axis run``:

====  ==========================================================================
code  meaning
====  ==========================================================================
0     complete, and the deterministic result of the scenario (lockstep); in
      realtime: complete, no fallback, death or stranger (a realtime run is
      never deterministic: its deadline misses depend on the host)
1     failed: a node the run cannot do without died or stalled (the summary
      of what was recorded is written if the bag allows it)
2     bad configuration or option (nothing started, nothing written)
3     complete, but not the deterministic result: a node fell back (a peer was
      gone), a node died and was restarted, or a stranger published on the
      run's topics
4     complete with a fault: the feedback loop tripped
5     realtime: the loop was not closed: more deadline misses than
      ``realtime.max_miss_fraction`` of the ticks (commands late or never
      sent), or the plant ended the run because its clock stalled
      (``clock_stalled``) or no command came (``loop_open``); never success
130   interrupted by SIGINT (143: SIGTERM); the nodes were stopped, the bag
      closed and the summary of what was recorded written (``interrupted``)
====  ==========================================================================

Nothing here imports rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from servo_axis.analysis.serial import Serial
from servo_axis.wire.node_report import NodeHealth

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_CONFIG = 2
EXIT_NOT_DETERMINISTIC = 3
EXIT_FAULT = 4
EXIT_LOOP_NOT_CLOSED = 5

#: A plant's fallbacks that end a realtime run whose loop is not closed.
LOOP_ENDS = ("loop_open", "clock_stalled")


def loop_not_closed(
    realtime: Any, max_miss_fraction: float, reports: dict[str, NodeHealth]
) -> str | None:
    """Why a realtime loop was not closed (exit 5), or None.

    Parameters
    ----------
    realtime : Realtime or None
        The summary's ``realtime`` block (None: not a realtime run, or no
        report of the plant's clock).
    max_miss_fraction : float
        ``realtime.max_miss_fraction``, 0-1.
    reports : dict
        The nodes' reports (a plant's ``loop_open`` or ``clock_stalled``
        fallback ends the run so).
    """
    for role, report in sorted(reports.items()):
        for fb in report.fallbacks:
            if fb.kind in LOOP_ENDS:
                return (
                    f"the loop was not closed: {role} ended the run ({fb.kind}) at step {fb.step}"
                )
    if realtime is None or not realtime.ticks:
        return None
    fraction = realtime.miss_fraction
    if fraction > max_miss_fraction:
        return (
            f"the loop was not closed: {realtime.misses} of {realtime.ticks} ticks "
            f"({100 * fraction:.1f} %) missed their deadline ({realtime.commands_missing} "
            f"commands never came), over realtime.max_miss_fraction {max_miss_fraction:g}"
        )
    return None


@dataclass(frozen=True)
class NodeDeath(Serial):
    """A node process that ended before the run did.

    Attributes
    ----------
    role : str
        ``plant``, ``feedback``, ... (``<axis>/<role>`` in a multi-axis run).
    exit_code : int
        Its exit code (negative: the signal that killed it).
    after_s : float
        Wall time from the start of the nodes to when the runner saw it, s.
    step : int
        The steps recorded when the runner saw it (-1: none yet).
    action : str
        What the runner did: ``restarted``, ``ran on``, ``stopped the run``.
    restarted_after_s : float or None
        Wall time from the death to the new process, s (``restarted`` only).
    """

    role: str
    exit_code: int
    after_s: float
    step: int
    action: str
    restarted_after_s: float | None = None


@dataclass(frozen=True)
class RunHealth(Serial):
    """How the run went, as ``summary.json``'s ``health``.

    Attributes
    ----------
    outcome : str
        ``complete``; ``failed`` (the runner stopped the run: why is the first
        of ``reasons``); ``interrupted`` (SIGINT or SIGTERM stopped it: why is
        the first of ``reasons``).
    deterministic : bool
        Lockstep, and no fallback, no death, no stranger: the result is the
        scenario's. Never true of a realtime run.
    exit_code : int
        See the module's table.
    reasons : tuple of str
        Why the run is not ``0`` (one line each).
    deaths : tuple of NodeDeath
    nodes : dict
        Each node's own report (:class:`servo_axis.wire.node_report.NodeHealth` as a mapping).
    bag_recovered : bool
        The recorder died and its bag was recovered (``bag recover``).
    """

    outcome: str
    deterministic: bool
    exit_code: int
    reasons: tuple[str, ...]
    deaths: tuple[NodeDeath, ...]
    nodes: dict[str, dict[str, Any]] = field(default_factory=dict)
    bag_recovered: bool = False


def assess(
    *,
    failure: str | None,
    interrupted: str | None = None,
    deaths: list[NodeDeath],
    reports: dict[str, NodeHealth],
    faults: int,
    bag_recovered: bool = False,
    realtime: bool = False,
    open_loop: str | None = None,
) -> RunHealth:
    """The run's health from what the runner saw and the nodes reported.

    Parameters
    ----------
    failure : str or None
        Why the runner stopped the run early (None: it completed).
    interrupted : str or None
        Why a signal stopped the run (``interrupted by SIGINT at step ...``;
        None: no signal). The exit code is then ``128 + signal number``.
    deaths : list of NodeDeath
        Nodes that ended before the run did.
    reports : dict
        The nodes' reports by role (``<axis>/<role>`` in a multi-axis run).
    faults : int
        Trips of the feedback loop recorded in the bag.
    bag_recovered : bool
        Whether the bag had to be recovered.
    realtime : bool
        A realtime run: never deterministic; exit code 0 if nothing else
        went wrong.
    open_loop : str or None
        Why a realtime loop was not closed (:func:`loop_not_closed`): exit 5.
    """
    reasons: list[str] = []
    for death in deaths:
        reasons.append(
            f"{death.role} ended with code {death.exit_code} at step {death.step} ({death.action})"
        )
    for role, report in sorted(reports.items()):
        for fb in report.fallbacks:
            reasons.append(f"{role} fell back ({fb.kind}) at step {fb.step}: {fb.detail}")
        for name, who in sorted(report.strangers.items()):
            reasons.append(f"{role}: {len(who)} stranger publisher(s) on {name}: {', '.join(who)}")
    if bag_recovered:
        reasons.append("the recorder died: the bag was recovered up to its last flushed chunk")
    clean = not reasons and failure is None and interrupted is None
    deterministic = clean and not realtime
    if interrupted is not None:
        code, outcome = _signal_exit_code(interrupted), "interrupted"
        reasons.insert(0, interrupted.splitlines()[0])
    elif failure is not None:
        code, outcome = EXIT_FAILED, "failed"
        reasons.insert(0, f"stopped: {failure.splitlines()[0]}")
    elif open_loop is not None:
        code, outcome = EXIT_LOOP_NOT_CLOSED, "complete"
        reasons.insert(0, open_loop)
    elif faults:
        code, outcome = EXIT_FAULT, "complete"
        reasons.append(f"the feedback loop tripped ({faults} fault(s))")
    elif not clean:
        code, outcome = EXIT_NOT_DETERMINISTIC, "complete"
    else:
        code, outcome = EXIT_OK, "complete"
    return RunHealth(
        outcome=outcome,
        deterministic=deterministic,
        exit_code=code,
        reasons=tuple(reasons),
        deaths=tuple(deaths),
        nodes={role: report.to_dict() for role, report in sorted(reports.items())},
        bag_recovered=bag_recovered,
    )


def _signal_exit_code(interrupted: str) -> int:
    """``128 + signal number`` of the signal named in ``interrupted by SIG...`` (130 if none)."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        if sig.name in interrupted:
            return 128 + int(sig)
    return 128 + int(signal.SIGINT)
