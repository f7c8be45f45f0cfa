"""Stopping a run: every node (the recorder last), then the live view and the watchers.

The nodes get SIGINT and, after a timeout, SIGKILL
(:func:`~servo_axis.run.processes.stop_nodes`); the live view is stopped
after them (it forwards what they sent last); what a killed participant
left in shared memory is removed once the runner's own watchers are gone.
A recorder that died leaves an unfinished bag, which is made readable
(:func:`recover_bags`).
"""

from __future__ import annotations

import time

from servo_axis.run.fastdds import clean_stale_shm
from servo_axis.run.live_view import LiveView
from servo_axis.run.processes import SIGNAL_STOP_S, stop_nodes
from servo_axis.run.state import AxisNodes, RunState


def stop_axes(axes: list[AxisNodes], state: RunState) -> None:
    """Stop every node of the run; note when, and each node's exit code."""
    state.t_end = time.monotonic()
    # A signal stopped the run: every process gone within SIGNAL_STOP_S.
    total = SIGNAL_STOP_S if state.signals else None
    stop_nodes([p for axis in axes for p in axis.procs], total_s=total)
    state.exit_codes = {axis.where(p.role): p.popen.returncode for axis in axes for p in axis.procs}


def close_run(axes: list[AxisNodes], live: LiveView | None, since_epoch: float) -> None:
    """Stop the live view, close the watchers, and clean up after any killed process.

    ``since_epoch``: the run's start (``time.time()``), for the shared-memory
    clean-up (:func:`~servo_axis.run.fastdds.clean_stale_shm`).
    """
    if live is not None:
        live.stop()
    for axis in axes:
        if axis.watcher is not None:
            axis.watcher.close()
    procs = [p for axis in axes for p in axis.procs]
    if live is not None and live.proc is not None:
        procs.append(live.proc)
    if any((p.popen.returncode or 0) < 0 for p in procs):
        # Again once the watchers are closed: a killed participant never
        # lets go of the port segments it opened (the watchers' own
        # included), so their last user's clean exit leaves them behind.
        clean_stale_shm(since=since_epoch)


def recover_bags(axes: list[AxisNodes]) -> set[str]:
    """Recover the bag of each axis whose recorder died; the axes recovered."""
    recovered = set()
    for axis in axes:
        if axis.recorder_died and axis.plan.bag.is_dir():
            from servo_axis.recording.recover import recover_bag

            report = recover_bag(axis.plan.bag)
            if report.recovered:
                recovered.add(axis.plan.axis)
    return recovered
