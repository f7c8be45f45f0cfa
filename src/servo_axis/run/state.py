"""What a run holds while it runs: each axis's processes, and what the watch has seen.

The plan (:class:`~servo_axis.params.run_plan.AxisPlan`) says what an axis
is; :class:`AxisNodes` is what became of it: its node processes (restarted
ones appended), the runner's watcher of its ``recorder/progress``, the
deaths and restarts so far. :class:`RunState` is the run's: its times, its
progress, why it stopped, the signals that reached it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from servo_axis.analysis.health import NodeDeath
from servo_axis.params.run_plan import AxisPlan
from servo_axis.run.processes import Launch, Proc

if TYPE_CHECKING:
    from servo_axis.run.progress import ProgressWatcher

#: The roles whose clean exit means "the run is complete".
PLANT_ROLES = ("plant", "composed")


@dataclass
class AxisNodes:
    """The nodes of one axis in a run."""

    plan: AxisPlan
    procs: list[Proc] = field(default_factory=list)
    watcher: ProgressWatcher | None = None
    launch: Launch | None = None  # how its nodes were started
    deaths: list[NodeDeath] = field(default_factory=list)
    restarts: dict[str, int] = field(default_factory=dict)
    seen_dead: set[int] = field(default_factory=set)  # pids already handled

    @property
    def plant_done(self) -> bool:
        """The plant has run every step (an outside plant: the recorder has them all)."""
        if "plant" in self.plan.outside:
            return self.watcher is not None and self.watcher.steps >= self.plan.steps
        plant = next((p for p in self.procs if p.role in PLANT_ROLES), None)
        return plant is not None and plant.popen.poll() == 0

    @property
    def recorder_died(self) -> bool:
        """The recorder exited with an error or a signal."""
        rec = [p for p in self.procs if p.role == "recorder"]
        return bool(rec) and rec[-1].popen.returncode not in (0, None)

    def where(self, role: str) -> str:
        """``<axis>/<role>`` in a multi-axis run, else ``role``."""
        return self.plan.where(role)


@dataclass
class RunState:
    """What the watch saw: progress, times, why the run stopped."""

    steps: int = -1  # the slowest axis's recorded steps
    t_start: float = field(default_factory=time.monotonic)
    t_start_epoch: float = field(default_factory=time.time)  # for the shared-memory clean-up
    t_first: float | None = None  # the first recorded step
    t_end: float = 0.0
    failure: str | None = None
    interrupted: str | None = None  # why, when a signal stopped the run
    signals: list[int] = field(default_factory=list)
    exit_codes: dict[str, int] = field(default_factory=dict)
    participant_ids: set[int] = field(default_factory=set)  # given to restarted nodes

    @property
    def wall_time_s(self) -> float:
        """Wall time from the first recorded step (the start if none) to the stop."""
        return self.t_end - (self.t_first or self.t_start)
