"""Starting a run: the runner's progress watchers, each axis's nodes, a dead node's restart.

The live view, if asked for, is started before the nodes
(:class:`~servo_axis.run.live_view.LiveView`); the runner starts the nodes
of the roles no outside node plays, in start order, with their time mode's
CPU pinning (:func:`~servo_axis.run.processes.start_nodes`). A restarted
node (:func:`restart_node`) gets a Fast DDS participant id that no
participant of the run has had.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from servo_axis.run.fastdds import clean_stale_shm, free_participant_id, with_participant_id
from servo_axis.run.options import RunOptions
from servo_axis.run.processes import Launch, Proc, start_node, start_nodes
from servo_axis.run.progress import ProgressWatcher
from servo_axis.run.state import AxisNodes, RunState


def open_watchers(axes: list[AxisNodes], domain_id: int, settings: Mapping[str, str]) -> None:
    """The runner's watcher of ``recorder/progress`` for each axis that has one to follow."""
    for axis in axes:
        if axis.plan.followed:
            axis.watcher = ProgressWatcher(
                axis.plan.namespace or "/",
                domain_id=domain_id,
                environ=settings,
                steps=axis.plan.steps,
            )


def start_axes(axes: list[AxisNodes], env: dict[str, str], options: RunOptions) -> None:
    """Start the nodes the runner plays on each axis; then ``options.on_started`` with them all."""
    for axis in axes:
        plan = axis.plan
        axis.launch = Launch(
            plan.params_path,
            (*plan.remaps, *options.extra_args),
            {**env, "ROS_LOG_DIR": str(plan.logs)},
            plan.logs,
            realtime=plan.realtime,
        )
        axis.procs = start_nodes(axis.launch, plan.started, options.composed)
    if options.on_started is not None:
        options.on_started([p for axis in axes for p in axis.procs])


def restart_node(axis: AxisNodes, role: str, state: RunState, number: int) -> Proc:
    """Start ``role`` of ``axis`` again (its ``number``-th restart), to join late from its memory.

    What dead participants left in shared memory goes first. Not the dead
    one's participant id: the others still write to its receive segment.
    Past the 20 ids (a node that keeps dying under a large
    ``--respawn-limit``), Fast DDS's choice.
    """
    assert axis.launch is not None
    clean_stale_shm(since=state.t_start_epoch, dead_owners_only=True)
    log_name = f"{role}.restart{number}"
    env = axis.launch.env
    try:
        pid = free_participant_id(int(env["ROS_DOMAIN_ID"]), taken=state.participant_ids)
        env = with_participant_id(env, pid, axis.plan.logs / f"{log_name}.fastdds.xml")
        state.participant_ids.add(pid)
    except RuntimeError:
        pass
    again = replace(axis.launch, args=(*axis.launch.args, "-p", "late_join:=true"), env=env)
    return start_node(again, role, log_name=log_name)
