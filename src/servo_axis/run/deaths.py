"""The node-death policy of a run (docs/explanation/reliability.md): restart, run on, or stop the run.

* learning unit, identifier (:data:`RESTARTED_ROLES`): started again
  (``late_join``), up to the run's ``respawn_limit`` times per axis; they
  resume from their memory files;
* feedforward generator (:data:`RUN_ON_ROLES`): the axis runs on (its
  feedback trips to zero current once the reference's publisher is gone);
* plant, feedback, recorder, or a node that refused its configuration
  (exit code :data:`NODE_BAD_CONFIG`, never restarted): the run stops.

Each death is recorded on its axis (:class:`~servo_axis.analysis.health.NodeDeath`)
for the summary's ``health``.
"""

from __future__ import annotations

import time

from servo_axis.analysis.health import NodeDeath
from servo_axis.run.processes import Proc
from servo_axis.run.start import restart_node
from servo_axis.run.state import PLANT_ROLES, AxisNodes, RunState

#: Roles the runner starts again when they die (the axis runs on meanwhile).
RESTARTED_ROLES = ("learning", "identifier")
#: Roles whose death the axis survives without a restart (the feedback trips).
RUN_ON_ROLES = ("feedforward",)
#: Exit code of a node that refused its configuration (never restarted).
NODE_BAD_CONFIG = 2


class NodeDeaths:
    """Applies the policy to the nodes of ``axes`` that exited since the last look."""

    def __init__(self, axes: list[AxisNodes], respawn_limit: int) -> None:
        self.axes = axes
        self.respawn_limit = respawn_limit

    def failure(self, state: RunState) -> str | None:
        """Why the run must stop now (a node's death and its last lines), or None."""
        for axis in self.axes:
            for p in list(axis.procs):
                code = p.popen.poll()
                if code is None or p.popen.pid in axis.seen_dead:
                    continue
                if p.role in PLANT_ROLES and code == 0:
                    continue
                if axis.plant_done:
                    continue  # the run is over; the rest are being stopped
                axis.seen_dead.add(p.popen.pid)
                after = time.monotonic() - state.t_start
                action, again = self._act(axis, p, code, state)
                if again is not None:
                    again -= after
                axis.deaths.append(
                    NodeDeath(axis.where(p.role), code, round(after, 3), state.steps, action, again)
                )
                if action == "stopped the run":
                    what = "exited with code" if p.role in PLANT_ROLES else "exited early with code"
                    return f"{axis.where(p.role)} {what} {code}:\n{p.tail()}"
        return None

    def _act(
        self, axis: AxisNodes, p: Proc, code: int, state: RunState
    ) -> tuple[str, float | None]:
        """Restart, run on or stop; with a restart, when it was started (s since the run's start)."""
        restarts = axis.restarts.get(p.role, 0)
        if p.role in RESTARTED_ROLES and code != NODE_BAD_CONFIG and restarts < self.respawn_limit:
            axis.restarts[p.role] = restarts + 1
            axis.procs.append(restart_node(axis, p.role, state, restarts + 1))
            return "restarted", time.monotonic() - state.t_start
        if p.role in RUN_ON_ROLES and code != NODE_BAD_CONFIG:
            return "ran on", None
        return "stopped the run", None
