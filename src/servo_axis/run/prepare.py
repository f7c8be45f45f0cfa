"""Preparing a run: the options checked, the scenario planned, the run directory written.

:func:`prepare` checks the options, loads the scenario and resolves it once
(:func:`~servo_axis.params.run_plan.plan_run`, which checks every node's
section as the node will), and only then creates the run directory and
writes each axis's ``params.yaml``, its ``scenario.yaml`` (the scenario as
it runs) and the copies of its data files (``inputs/``): nothing is written
for a bad option or scenario.
:func:`announce` prints what the run says before it starts: the header,
how to reach its ROS graph, and what each outside node must serve.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from servo_axis import numerics
from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.params.names import check_domain_id, check_namespace
from servo_axis.params.recorded import header
from servo_axis.params.registry import report_broken
from servo_axis.params.run_plan import AxisPlan, RunPlan, plan_run
from servo_axis.params.scenario import dump_params, find_scenario, load_scenario
from servo_axis.run.live_view import check_live
from servo_axis.run.options import RunOptions
from servo_axis.run.processes import default_domain_id, discovery_settings, run_header
from servo_axis.wire.topics import Topic


@dataclass(frozen=True)
class PreparedRun:
    """A run ready to start: its plan, its ROS domain and its options."""

    plan: RunPlan
    domain_id: int
    options: RunOptions


def prepare(scenario: str | Path, options: RunOptions) -> PreparedRun:
    """Check ``options``, plan ``scenario`` (a file or a shipped name) and write the run directory.

    Raises
    ------
    ConfigError
        For a bad option (a ``namespace`` ROS would reject, a domain outside
        0..232, also from ROS_DOMAIN_ID, a negative ``respawn_limit``, a
        live port that cannot be served), a scenario that cannot be found or
        planned (:func:`~servo_axis.params.run_plan.plan_run`), or a run
        directory that cannot be created: before anything is written.
    ParameterFileError
        For a node section the node would refuse.
    """
    namespace = check_namespace(options.namespace) if options.namespace else ""
    domain = (
        default_domain_id() if options.domain_id is None else check_domain_id(options.domain_id)
    )
    if options.respawn_limit < 0:
        raise ConfigError(f"--respawn-limit {options.respawn_limit}: expected an integer >= 0")
    path = find_scenario(scenario).resolve()
    data = load_scenario(path)
    if options.live_port is not None:
        check_live(options.live_port)
    try:
        plan = plan_run(
            data,
            path,
            out_dir=options.out_dir,
            namespace=namespace,
            external=options.external,
            composed=options.composed,
            overrides=options.overrides,
        )
    except ParameterFileError as err:
        if str(err).startswith("--set "):
            raise
        # A key of the file: name the file (as given: a shipped name or a path).
        raise ParameterFileError(f"scenario {scenario}: {err}") from None
    _write(plan)
    # The plan selects no broken plugin (it would have been refused): name the
    # others now, before the run's output, not after it.
    report_broken()
    return PreparedRun(plan, domain, options)


def _write(plan: RunPlan) -> None:
    """Create the run directory and each axis's logs; write its scenario, data files and parameter file.

    Each axis's directory gets the scenario as it runs (``scenario.yaml``)
    and a copy of each data file it names (``inputs/``), which its nodes
    read and every later command reads (:mod:`servo_axis.params.recorded`).
    """
    created = not plan.run_dir.exists()
    try:
        plan.run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"--out {plan.run_dir}: cannot create it: {err}") from None
    for axis in plan.axes:
        axis.logs.mkdir(parents=True, exist_ok=True)
        for key, (source, copy) in axis.inputs.items():
            target = axis.dir / copy
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                shutil.copyfile(source, target)
            except OSError as err:
                if created:  # nothing left behind for what the run cannot start with
                    shutil.rmtree(plan.run_dir, ignore_errors=True)
                raise ConfigError(f"parameter '{key}': cannot copy {source}: {err}") from None
        head = header(axis.source_path, axis=axis.axis)
        _write_whole(axis.scenario_path, head + dump_params(axis.scenario))
        _write_whole(axis.params_path, dump_params(dict(axis.params_file)))


def _write_whole(path: Path, text: str) -> None:
    """Write ``path`` so that whoever reads it (a user starting an outside node from the
    run's ``params.yaml``) finds it whole or not at all."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def announce(run: PreparedRun) -> None:
    """Print the run's header, how to reach its ROS graph, and each outside role's contract."""
    out, plan = run.options.progress, run.plan
    if out is None:
        return
    print(f"servo_axis run {plan.name}: {plan.steps} steps, run directory {plan.run_dir}", file=out)
    settings = discovery_settings(plan.axes[0].logs, realtime=plan.realtime)
    header = run_header(run.domain_id, plan.namespaces, settings)
    # What the node processes get (ros_environment), said as they will compute.
    header.append(numerics.describe(numerics.portable_environment(os.environ)))
    print("\n".join(header), file=out, flush=True)
    for axis in plan.axes:
        for role in axis.outside:
            out.write(describe_external(axis, role))
    out.flush()


def describe_external(axis: AxisPlan, role: str) -> str:
    """What the outside node of ``role`` must serve: topics, types, QoS (printed by the run)."""
    played = axis.role(role)
    assert played is not None
    ns = axis.namespace.rstrip("/") if axis.namespace not in ("", "/") else ""

    def full(name: str) -> str:
        return name if name.startswith("/") else f"{ns}/{name}"

    plant = axis.role("plant")
    setpoints = plant is not None and plant.values.command_source == "drive_setpoint"

    def row(kind: str, t: Topic) -> str:
        optional = "" if played.required(t.name) else "(optional) "
        meaning = t.meaning
        if t.name == "command" and setpoints:
            meaning = (
                "a drive's set-point: effort of the motor joint (N m), any stamp, NaN = none "
                "(command_source: drive_setpoint; docs/how-to/ros2-control.md)"
            )
        return f"  {kind:11} {full(t.name):32} {t.type_name:30} {optional}{meaning}"

    lines = [
        f"outside {axis.where(role)}: any node name, default QoS accepted (docs/interfaces.md)"
    ]
    lines += [row("publishes", t) for t in played.publishes]
    lines += [row("subscribes", t) for t in played.subscribes]
    return "\n".join(lines) + "\n"
