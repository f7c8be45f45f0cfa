"""Watching a run: its progress, its nodes, its outside nodes, its stalls, until it ends.

:meth:`Watch.run` spins each axis's progress watcher for a short while
(:data:`POLL_S` per pass, shared by the axes), shows the progress, then asks
in turn: the node-death policy (:class:`~servo_axis.run.deaths.NodeDeaths`);
whether every plant is done; the wait for the outside nodes
(:class:`OutsideWait`: before the first step, with its own timeout from
when the run's own nodes are up); and
the checks of a running run (:attr:`Watch.checks`: the stall check
:class:`StallCheck` first). The first answer that is not None is why the
run stops (:attr:`~servo_axis.run.state.RunState.failure`); a SIGINT or
SIGTERM stops it too. A check is anything with ``failure(state) -> str |
None``: a realtime supervisor (a watchdog on the plant's clock, on the
loop's commands) joins the run as one more.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, TextIO

from servo_axis.run.deaths import NodeDeaths
from servo_axis.run.progress import ProgressLine
from servo_axis.run.state import AxisNodes, RunState

#: Seconds the watch loop waits per pass (shared by the axes).
POLL_S = 0.05


class Check(Protocol):
    """Something the watch asks on every pass whether the run must stop."""

    def failure(self, state: RunState) -> str | None:
        """Why the run must stop now, or None."""
        ...


class StallCheck:
    """The run stops when the recorded steps do not move for ``timeout_s``."""

    def __init__(self, timeout_s: float, run_dir: Path) -> None:
        self.timeout_s = timeout_s
        self.run_dir = run_dir
        self.last_change = time.monotonic()

    def moved(self) -> None:
        """The run moved (or may not move yet): the wait starts again."""
        self.last_change = time.monotonic()

    def failure(self, state: RunState) -> str | None:
        """``no progress for N s`` once the steps stood still that long."""
        if time.monotonic() - self.last_change > self.timeout_s:
            return f"no progress for {self.timeout_s:.0f} s (see {self.run_dir})"
        return None


class OvertimeCheck:
    """Realtime: the run stops when it has lasted far longer than its simulated time.

    The last resort of a run that must end by itself (the plant ends a run
    whose clock stalled or whose loop is open on its own: ``clock_stalled``,
    ``loop_open``): from its first step, at most ``factor`` times its
    simulated time plus ``margin_s`` of wall time.
    """

    def __init__(self, simulated_s: float, *, factor: float = 3.0, margin_s: float = 60.0) -> None:
        self.limit_s = factor * simulated_s + margin_s
        self.simulated_s = simulated_s

    def failure(self, state: RunState) -> str | None:
        """``overtime`` once the run has lasted :attr:`limit_s` since its first step."""
        if state.t_first is None:
            return None
        lasted = time.monotonic() - state.t_first
        if lasted > self.limit_s:
            return (
                f"overtime: a realtime run of {self.simulated_s:.3g} s simulated still ran "
                f"after {lasted:.0f} s of wall time (limit {self.limit_s:.0f} s)"
            )
        return None


class OutsideWait:
    """The wait for the nodes of the roles outside nodes play, before the first step.

    ``--external-timeout`` counts from when the run's own nodes are up
    (:attr:`t0`): every node the runner started has reported on
    ``/diagnostics`` (its first status comes once it is built and spinning;
    the recorder's once its bag is open), so the run's start-up on a slow
    host is not taken from the outside node's time, and the run never ends
    before its bag exists. Until then the wait is the stall check's (a node
    that never comes up is no outside node's fault).
    """

    def __init__(self, axes: list[AxisNodes], timeout_s: float, out: TextIO | None) -> None:
        self.missing = [(axis, role) for axis in axes for role in axis.plan.outside]
        self.own = [
            (axis, role) for axis in axes if axis.plan.outside for role in axis.plan.started
        ]
        self.timeout_s = timeout_s
        self.out = out
        self.t0: float | None = None
        self.told = 0.0

    @staticmethod
    def _up(axis: AxisNodes, role: str) -> bool:
        assert axis.watcher is not None
        return f"{axis.plan.namespace.rstrip('/')}/{role}" in axis.watcher.reported

    @property
    def counting(self) -> bool:
        """Whether the run's own nodes are up, so that ``--external-timeout`` runs (from :attr:`t0`)."""
        if self.t0 is None:
            self.own = [(a, role) for a, role in self.own if not self._up(a, role)]
            if not self.own:
                self.t0 = time.monotonic()
        return self.t0 is not None

    @staticmethod
    def _present(axis: AxisNodes, role: str) -> bool:
        assert axis.watcher is not None
        publishers, _ = axis.watcher.endpoints(axis.plan.presence(role))
        return publishers > 0

    def arrived(self) -> bool:
        """Whether every outside node is there (its main output has a publisher)."""
        self.missing = [(a, role) for a, role in self.missing if not self._present(a, role)]
        if self.missing and self.out is not None and time.monotonic() - self.told >= 5.0:
            self.told = time.monotonic()
            if self.counting:
                assert self.t0 is not None
                waited = f"{self.told - self.t0:.0f} s of {self.timeout_s:.0f} s"
            else:
                waited = "the run's own nodes still starting"
            for axis, role in self.missing:
                self.out.write(
                    f"waiting for the outside {axis.where(role)} ({waited}): "
                    f"no publisher on {axis.plan.presence(role)} yet\n"
                )
            self.out.flush()
        return not self.missing

    def failure(self) -> str | None:
        """Why the run stops (the timeout passed since the run's own nodes were up), or None."""
        if not self.counting:
            return None
        assert self.t0 is not None
        if time.monotonic() - self.t0 <= self.timeout_s:
            return None
        names = ", ".join(
            f"{axis.where(role)} (no publisher on {axis.plan.presence(role)})"
            for axis, role in self.missing
        )
        return (
            f"the outside node did not come within --external-timeout {self.timeout_s:g} s: {names}"
        )


#: Seconds an outside plant's ``state`` publisher may be gone before the run
#: stops (the recorder's last acknowledgement of a plant that exited at the end).
OUTSIDE_PLANT_GRACE_S = 2.0


class OutsidePlantGone:
    """The run stops when an outside plant that was there has left the graph before the end.

    Nothing can stand in for the plant: without it no step comes (an outside
    feedback that goes is the plant's fallback instead). A crashed node
    leaves the graph when its participant's lease ends (5 s with the run's
    Fast DDS profile, 20 s with Fast DDS's default); the bag holds every
    step it had sent.
    """

    def __init__(self, axes: list[AxisNodes], grace_s: float = OUTSIDE_PLANT_GRACE_S) -> None:
        self.axes = [axis for axis in axes if "plant" in axis.plan.outside]
        self.grace_s = grace_s
        self.seen: set[int] = set()
        self.gone_since: dict[int, float] = {}

    def failure(self, state: RunState) -> str | None:
        """``the outside plant is gone ...`` once its ``state`` publisher left, else None.

        Only after :attr:`grace_s`: a plant that exits right after its last
        state leaves before the recorder has acknowledged it.
        """
        now = time.monotonic()
        for i, axis in enumerate(self.axes):
            if axis.watcher is None or axis.plant_done:
                continue
            present = axis.watcher.endpoints(axis.plan.presence("plant"))[0] > 0
            if present:
                self.seen.add(i)
                self.gone_since.pop(i, None)
            elif i in self.seen and now - self.gone_since.setdefault(i, now) > self.grace_s:
                return (
                    f"the outside {axis.where('plant')} is gone (no publisher on "
                    f"{axis.plan.presence('plant')}) at step {max(state.steps, 0)}"
                )
        return None


@dataclass
class Watch:
    """The watch of a run's axes: what it asks, in order, on every pass."""

    axes: list[AxisNodes]
    state: RunState
    line: ProgressLine | None
    deaths: NodeDeaths
    outside: OutsideWait
    stall: StallCheck
    checks: list[Check] = field(default_factory=list)  # after the stall check

    def run(self) -> None:
        """Follow the run until the plants are done, a check fails, or a signal came."""
        state = self.state
        self.stall.moved()
        while not state.signals:
            self._spin()
            if self.line is not None and state.t_first is not None:
                self.line.show(state.steps, time.monotonic() - state.t_first)
            state.failure = self.deaths.failure(state)
            if state.failure is not None or all(axis.plant_done for axis in self.axes):
                return
            if not self.outside.arrived() and self.outside.counting:
                # The wait for an outside node has its own timeout, not the stall's
                # (from when the run's own nodes are up; before, the stall check's).
                state.failure = self.outside.failure()
                if state.failure is not None:
                    return
                self.stall.moved()
                continue
            for check in [self.stall, *self.checks]:
                state.failure = check.failure(state)
                if state.failure is not None:
                    return

    def _spin(self) -> None:
        """Take what arrived for each axis's watcher; the slowest axis's steps."""
        state = self.state
        for axis in self.axes:
            if axis.watcher is not None:
                axis.watcher.spin(POLL_S / len(self.axes))
            else:
                time.sleep(POLL_S / len(self.axes))
        watched = [axis.watcher.steps for axis in self.axes if axis.watcher is not None]
        slowest = min(watched) if watched else -1
        if slowest != state.steps:
            state.steps = slowest
            self.stall.moved()
            if slowest >= 0 and state.t_first is None:
                state.t_first = time.monotonic()
