"""How a scenario is run: the options of :func:`~servo_axis.run.runner.run_scenario`."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from servo_axis.params.overrides import Override
    from servo_axis.run.processes import Proc

#: Restarts per role and axis by default.
RESPAWN_LIMIT = 3
#: Seconds a run waits for its outside nodes before the first step, by default.
EXTERNAL_TIMEOUT_S = 120.0
#: Seconds without progress after which a run is stopped, by default.
STALL_TIMEOUT_S = 60.0


@dataclass(frozen=True)
class RunOptions:
    """The options of a run (``python -m servo_axis run``'s, and a few for tests and scripts).

    Attributes
    ----------
    out_dir : Path or None
        The run directory, which must be empty or not exist (None:
        ``runs/<scenario name>-<time>``).
    composed : bool
        Every node of the axis in one process.
    domain_id : int or None
        The ROS domain, 0..232 (None: ``ROS_DOMAIN_ID``, else one derived
        from the pid).
    namespace : str
        The ROS namespace of a single-axis run (``""``: ``/<axis>``; ``"/"``:
        the root).
    progress : TextIO or None
        Where the header, the outside roles' contract and the progress line
        go (None: nowhere).
    stall_timeout_s : float
        Seconds without progress after which the run is stopped, > 0.
    plots : bool
        Write the figures of the run.
    extra_args : tuple of str
        ROS arguments given to every node after the run's own.
    on_started : callable or None
        Called with the node processes once they are started (tests).
    respawn_limit : int
        Restarts per restarted role and axis, >= 0.
    external : tuple of str
        Roles nodes from outside the suite play (with the scenario's
        ``external_roles``).
    external_timeout_s : float
        Seconds the run waits for its outside nodes before the first step,
        counted from when the run's own nodes are up
        (:class:`~servo_axis.run.watch.OutsideWait`).
    live_port : int or None
        Serve the run to Foxglove / Lichtblick on this port
        (:mod:`servo_axis.run.live`); None: no live view.
    floor : dict or None
        ``python -m servo_axis floor --json`` results by period in us
        (:mod:`servo_axis.run.floor`): a realtime run's summary shows the
        host's floor at its period.
    overrides : tuple of Override
        ``--set SECTION.KEY=VALUE`` overrides of the scenario's keys
        (:mod:`servo_axis.params.overrides`), applied in order.
    """

    out_dir: Path | None = None
    composed: bool = False
    domain_id: int | None = None
    namespace: str = ""
    progress: TextIO | None = sys.stdout
    stall_timeout_s: float = STALL_TIMEOUT_S
    plots: bool = True
    extra_args: tuple[str, ...] = ()
    on_started: Callable[[list[Proc]], object] | None = None
    respawn_limit: int = RESPAWN_LIMIT
    external: tuple[str, ...] = ()
    external_timeout_s: float = EXTERNAL_TIMEOUT_S
    live_port: int | None = None
    floor: dict[int, dict[str, Any]] | None = None
    overrides: tuple[Override, ...] = ()
