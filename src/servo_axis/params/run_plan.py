"""A scenario resolved once for a run: per axis, who plays each role, with what, over which topics.

:func:`plan_run` turns a loaded scenario and the run's choices (output
directory, namespace, outside roles, composed) into a frozen
:class:`RunPlan`: per axis an :class:`AxisPlan` (namespace, directory and
files, time mode, steps, the start handshakes, the parameter file the nodes
get) with one :class:`RolePlan` per role (started by the suite or played by
an outside node, its checked values, the topics it publishes and takes and
which of them it must serve). Making the plan checks everything a run can
refuse before anything is written or started (each node's section as the
node will, the files the terms name, the outside roles); the runner
(:mod:`servo_axis.run`) then asks only the plan. Each axis's scenario is
read once (:class:`~servo_axis.params.resolve.Resolved`) and each of its
roles checked once, in start order after the plant: every later question of
the plan (handshakes, topics, steps) reads those typed values, and the
summary gets them (:attr:`AxisPlan.resolved`). Nothing here imports rclpy or
writes a file.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from dataclasses import replace as dataclass_replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.params.factories import EXTERNAL_ROLES, node_schema, plant_model, run_steps
from servo_axis.params.overrides import Override, apply_overrides, blame
from servo_axis.params.param import BUILTIN
from servo_axis.params.recorded import SCENARIO_FILE, input_copies, recorded_view
from servo_axis.params.registry import term_files
from servo_axis.params.resolve import Resolved
from servo_axis.params.run_params import (
    HANDSHAKES,
    Handshake,
    drive_setpoints,
    external_roles_of,
    handshake_overrides,
    run_params,
    single_axis_namespace,
)
from servo_axis.params.run_topics import REQUIRED_INPUTS, law_outputs, presence_topic, role_topics
from servo_axis.params.scenario import axes_of, axis_view, resolve_table, roles_of, shared
from servo_axis.params.typed import Values
from servo_axis.wire.topics import Topic


@dataclass(frozen=True)
class RolePlan:
    """One role of an axis: who plays it, with which values, over which topics.

    Attributes
    ----------
    role : str
        ``plant``, ``feedback``, ``feedforward``, ``learning``, ``identifier``
        or ``recorder``.
    outside : bool
        A node from outside the suite plays it (``--external``,
        ``external_roles``); the runner does not start it.
    values : Values
        The typed values of its section with what it copies and what the
        run adds (what the suite's node of the role checks and runs with;
        also a read-only mapping of the dotted keys).
    publishes, subscribes : tuple of Topic
        What a node playing it publishes and takes in this run
        (:func:`~servo_axis.params.run_topics.role_topics`).
    must_publish, must_take : tuple of str
        Of those, what a node playing it must serve: the output whose
        publisher shows it is there, and the inputs publishers wait for it on
        (:data:`~servo_axis.params.run_topics.REQUIRED_INPUTS`). The rest is
        optional.
    """

    role: str
    outside: bool
    values: Values
    publishes: tuple[Topic, ...]
    subscribes: tuple[Topic, ...]
    must_publish: tuple[str, ...]
    must_take: tuple[str, ...]

    @property
    def presence(self) -> str | None:
        """The topic whose publisher shows that a node playing the role is there (None: recorder)."""
        return self.must_publish[0] if self.must_publish else None

    def required(self, name: str) -> bool:
        """Whether a node playing the role must publish or take ``name`` (else it is optional)."""
        return name in self.must_publish or name in self.must_take


@dataclass(frozen=True)
class AxisPlan:
    """One axis of a run: its nodes, namespace, files, time mode and handshakes.

    Attributes
    ----------
    axis : str
        The axis's sections (``/<axis>/<node>``) in a multi-axis scenario;
        ``""`` for a single-axis one.
    namespace : str
        Its ROS namespace (``""``: the root).
    dir : Path
        Its directory (the run directory for a single axis): ``bag/``,
        ``logs/``, ``params.yaml``, ``scenario.yaml``, ``inputs/``.
    scenario : dict
        The single-axis scenario it runs, as recorded in :attr:`scenario_path`
        (for the analysis, which resolves it itself; the runner does not
        query it): its data files are the copies of :attr:`inputs`.
    scenario_path : Path
        Its recorded file, ``scenario.yaml`` in :attr:`dir`
        (:mod:`servo_axis.params.recorded`), which the runner writes.
    source_path : Path
        The scenario file the run was started from (the summary's
        ``scenario_file``).
    inputs : mapping
        ``{key: (source, copy)}``: each data file the scenario's terms read
        and its copy, relative to :attr:`dir` (``inputs/<term>/<name>``),
        which the nodes read (:func:`~servo_axis.params.recorded.input_copies`).
    remaps : tuple of str
        The ROS arguments that put its nodes in :attr:`namespace`.
    roles : tuple of RolePlan
        Every role of its scenario, in start order, outside ones included.
    handshakes : tuple of Handshake
        Whom each publisher waits for before its first message.
    params_file : mapping
        The parameter file its nodes get (:func:`~servo_axis.params.run_params.run_params`).
    mode : str
        ``lockstep`` or ``realtime`` (the plant's ``mode``).
    steps : int
        Control samples of the run.
    control_period_s : float
        ``T_u``, s.
    joint_axis : str
        The shared key ``axis``: the joints are ``<joint_axis>_motor``, ...
    sensor : str
        The feedback's controlled output: ``encoder`` or ``scale``.
    lead_m_per_rad : float
        ``R``, m/rad.
    linear : bool
        The table moves along a line (False: it turns).
    max_miss_fraction : float
        The shared key ``realtime.max_miss_fraction``: above it a realtime
        loop was not closed (:func:`~servo_axis.analysis.health.loop_not_closed`).
    resolved : Resolved or None
        :attr:`scenario` read once, with each role's checked values (those
        of its section and copies, without what the run adds): what the
        summary reads.
    """

    axis: str
    namespace: str
    dir: Path
    scenario: dict[str, Any]
    scenario_path: Path
    remaps: tuple[str, ...]
    roles: tuple[RolePlan, ...]
    handshakes: tuple[Handshake, ...]
    params_file: Mapping[str, Any]
    mode: str
    steps: int
    control_period_s: float
    joint_axis: str
    sensor: str
    lead_m_per_rad: float
    linear: bool
    max_miss_fraction: float = 0.05
    source_path: Path = Path()
    inputs: Mapping[str, tuple[Path, str]] = field(default_factory=lambda: MappingProxyType({}))
    resolved: Resolved | None = field(default=None, compare=False, repr=False)

    @property
    def logs(self) -> Path:
        """Its nodes' logs and health reports."""
        return self.dir / "logs"

    @property
    def bag(self) -> Path:
        """The bag its recorder creates."""
        return self.dir / "bag"

    @property
    def params_path(self) -> Path:
        """Where :attr:`params_file` is written."""
        return self.dir / "params.yaml"

    @property
    def realtime(self) -> bool:
        """The axis runs in realtime."""
        return self.mode == "realtime"

    @property
    def started(self) -> list[str]:
        """The roles the runner starts (those outside nodes play left out)."""
        return [r.role for r in self.roles if not r.outside]

    @property
    def outside(self) -> tuple[str, ...]:
        """The roles outside nodes play."""
        return tuple(r.role for r in self.roles if r.outside)

    @property
    def recorded(self) -> tuple[str, ...]:
        """The topics its recorder records (none without a recorder)."""
        rec = self.role("recorder")
        return tuple(rec.values["topics"]) if rec is not None else ()

    @property
    def counted(self) -> tuple[str, ...]:
        """Of :attr:`recorded`, those whose every sample the recorder acknowledges."""
        rec = self.role("recorder")
        return tuple(rec.values["counted_topics"]) if rec is not None else ()

    def summary_scenario(self) -> Resolved | dict[str, Any]:
        """What the summary reads of the axis: :attr:`resolved`, else :attr:`scenario`."""
        return self.resolved if self.resolved is not None else self.scenario

    @property
    def followed(self) -> bool:
        """The runner follows the axis's ``recorder/progress`` (a recorder or an outside node runs)."""
        return self.role("recorder") is not None or bool(self.outside)

    def role(self, name: str) -> RolePlan | None:
        """The plan of role ``name``, None if the axis has no such role."""
        return next((r for r in self.roles if r.role == name), None)

    def presence(self, role: str) -> str:
        """The topic whose publisher shows that a node playing ``role`` is there.

        Raises
        ------
        KeyError
            For a role the axis does not have or that has no such topic
            (the recorder).
        """
        plan = self.role(role)
        if plan is None or plan.presence is None:
            raise KeyError(role)
        return plan.presence

    def where(self, role: str) -> str:
        """``<axis>/<role>`` in a multi-axis run, else ``role``."""
        return f"{self.axis}/{role}" if self.axis else role


@dataclass(frozen=True)
class RunPlan:
    """A run of a scenario: its name, directory and axes.

    Attributes
    ----------
    name : str
        The scenario's ``scenario.name`` (its file's stem if it has none).
    scenario : dict
        The scenario as loaded, with the overrides applied (for the
        analysis of a multi-axis run).
    scenario_path : Path
        Its file.
    run_dir : Path
        The run directory (not created yet).
    steps : int
        Control samples of the run (of its longest axis).
    composed : bool
        All roles of the axis in one process.
    axes : tuple of AxisPlan
        One per axis, sorted by axis; one (``axis == ""``) for a
        single-axis scenario.
    overrides : tuple of str
        The ``--set`` overrides applied, as given (the summary records them).
    """

    name: str
    scenario: dict[str, Any]
    scenario_path: Path
    run_dir: Path
    steps: int
    composed: bool
    axes: tuple[AxisPlan, ...]
    overrides: tuple[str, ...] = ()

    @property
    def multi_axis(self) -> bool:
        """The scenario has per-axis sections."""
        return self.axes[0].axis != ""

    @property
    def namespaces(self) -> list[str]:
        """Each axis's namespace."""
        return [a.namespace for a in self.axes]

    @property
    def realtime(self) -> bool:
        """An axis of the run runs in realtime (the run's discovery profile is the realtime one)."""
        return any(a.realtime for a in self.axes)


def plan_run(
    scenario: dict[str, Any],
    scenario_path: Path,
    *,
    out_dir: Path | None = None,
    namespace: str = "",
    external: Sequence[str] = (),
    composed: bool = False,
    overrides: Sequence[Override] = (),
) -> RunPlan:
    """Resolve ``scenario`` (loaded from ``scenario_path``) for a run, checking all of it.

    ``out_dir`` is the run directory (default ``runs/<name>-<time>``),
    ``namespace`` a checked ``--namespace`` (``""``: the axis's,
    :func:`single_axis_namespace`), ``external`` the roles of ``--external``
    (with the scenario's ``external_roles``), ``overrides`` the ``--set``
    overrides, applied to the scenario before anything is checked
    (:mod:`servo_axis.params.overrides`); an error they cause names the one
    at fault (``--set <its text>: ...``).

    Raises
    ------
    ConfigError
        For an ``out_dir`` that exists and is not an empty directory, a role
        outside nodes cannot play or that the scenario does not have, a
        multi-axis scenario with ``composed`` or ``namespace``, outside
        roles with ``composed``.
    ParameterFileError
        For a key of a node's section the node would refuse (naming the
        key), a term's file that does not exist, an ``axis`` that cannot
        name a namespace.
    """
    if not overrides:
        return _plan(scenario, scenario_path, out_dir, namespace, external, composed)

    def attempt(given: Sequence[Override]) -> RunPlan:
        plan = _plan(
            apply_overrides(scenario, given), scenario_path, out_dir, namespace, external, composed
        )
        return dataclass_replace(plan, overrides=tuple(o.text for o in given))

    try:
        return attempt(overrides)
    except ConfigError as err:
        raise blame(err, overrides, attempt) from None


def _plan(
    scenario: dict[str, Any],
    scenario_path: Path,
    out_dir: Path | None,
    namespace: str,
    external: Sequence[str],
    composed: bool,
) -> RunPlan:
    """:func:`plan_run` of a scenario with its overrides applied."""
    name = shared(scenario).get("scenario", {}).get("name") or scenario_path.stem
    axes = axes_of(scenario)
    views = [(axis, axis_view(scenario, axis, scenario_path.parent)) for axis in axes] or [
        ("", scenario)
    ]
    read = [(axis, Resolved(view, scenario_path)) for axis, view in views]
    for _, resolved in read:
        resolved.values("plant")  # first: the run's length, its mode, its outside roles
    run_dir = run_directory(out_dir, name)
    outside = external_roles_of(read[0][1], tuple(external))
    if axes and (composed or namespace):
        raise ConfigError(
            f"scenario {scenario_path}: a multi-axis scenario runs as separate processes, "
            "each axis in its own namespace (no --composed, no --namespace)"
        )
    if outside and composed:
        raise ConfigError("--external: a run with outside nodes runs as separate processes")
    plans = tuple(
        _axis_plan(
            resolved,
            scenario_path,
            axis=axis,
            namespace=f"/{axis}" if axis else namespace,
            axis_dir=run_dir / axis if axis else run_dir,
            outside=outside,
        )
        for axis, resolved in read
    )
    steps = max(p.steps for p in plans)
    return RunPlan(name, scenario, scenario_path, run_dir, steps, composed, plans)


def _axis_plan(
    resolved: Resolved,
    scenario_path: Path,
    *,
    axis: str,
    namespace: str,
    axis_dir: Path,
    outside: tuple[str, ...],
) -> AxisPlan:
    """The plan of one axis (``resolved``: its single-axis scenario, read once).

    Its roles are checked once each, in start order. Its data files are
    read from their copies in the axis's directory (``inputs/``, written
    with ``scenario.yaml`` before any node starts): the view the plan keeps,
    its values and the nodes' parameter file name them.
    """
    roles = roles_of(dict(resolved.scenario))
    for role in outside:
        if role not in roles:
            raise ConfigError(
                f"--external {role}: the scenario has no {role} section (its roles: "
                f"{', '.join(roles)})"
            )
    if "identifier" in roles and drive_setpoints(resolved):
        raise ConfigError(
            "plant command_source: drive_setpoint: the identifier pairs each command with its "
            "state by stamp, which a drive's set-point does not carry (run without the "
            "identifier section)"
        )
    for role in roles:
        resolved.values(role)
    recorded = _recorded(resolved, scenario_path, axis_dir)
    # Relative files are the copies, relative to the axis's directory (the others absolute).
    overrides = handshake_overrides(recorded, roles, axis_dir / "bag", axis_dir, outside)
    plans = tuple(_role_plan(recorded, roles, role, overrides, outside) for role in roles)
    if axis:
        remaps: tuple[str, ...] = ("-r", f"__ns:={namespace}", "-r", f"/clock:={namespace}/clock")
    else:
        namespace = single_axis_namespace(recorded, namespace)
        remaps = ("-r", f"__ns:={namespace}") if namespace else ()
    values = {r.role: r.values for r in plans}
    shakes = tuple(
        Handshake(role, key, name or law_outputs(recorded)[0], values[role][key])
        for role, key, name in HANDSHAKES
        if role in values
    )
    plant, feedback = recorded.plant, recorded.feedback
    return AxisPlan(
        axis=axis,
        namespace=namespace,
        dir=axis_dir,
        scenario=dict(recorded.scenario),
        scenario_path=axis_dir / SCENARIO_FILE,
        remaps=remaps,
        roles=plans,
        handshakes=shakes,
        params_file=MappingProxyType(run_params(recorded, overrides)),
        mode=plant.mode,
        steps=run_steps(plant),
        control_period_s=plant.control_period_s,
        joint_axis=plant.axis,
        sensor=feedback.sensor,
        lead_m_per_rad=feedback.lead_m_per_rad,
        linear=not plant_model(plant.model, "plant.model").rotary,
        max_miss_fraction=plant.realtime.max_miss_fraction,
        source_path=scenario_path,
        inputs=MappingProxyType(recorded.inputs),
        resolved=recorded,
    )


class _Recorded(Resolved):
    """The view an axis records (its data files named as their copies), with the values of
    the view it was made from: read once, not checked again; and the copies."""

    inputs: dict[str, tuple[Path, str]]


def _recorded(resolved: Resolved, scenario_path: Path, axis_dir: Path) -> _Recorded:
    """``resolved``'s view as the axis records it: its data files named as their copies.

    Its values are ``resolved``'s (the feedforward's files the copies' absolute
    paths in ``axis_dir``, what the nodes read): nothing is checked again.
    """
    inputs = input_copies(resolved, scenario_path.parent)
    view = recorded_view(dict(resolved.scenario), inputs, scenario_path.parent)
    known = resolved.known()
    if "feedforward" in known:
        given = _Recorded(view).given("feedforward")
        known["feedforward"] = known["feedforward"].with_keys(
            {key: resolve_table(given.get(key, ""), axis_dir) for key in term_files()}
        )
    recorded = _Recorded(view, axis_dir / SCENARIO_FILE, roles=resolved.roles, known=known)
    recorded.inputs = inputs
    return recorded


def _role_plan(
    recorded: _Recorded,
    roles: list[str],
    role: str,
    overrides: dict[str, dict[str, Any]],
    outside: tuple[str, ...],
) -> RolePlan:
    """One role's plan: its checked values with what the run adds (each added key checked).

    A data file among the copies exists (its copy is written before the nodes start).
    """
    values = _with_additions(recorded, role, overrides.get(role, {}))
    for key in term_files() if role == "feedforward" else ():
        on = values.get(f"{key.rpartition('.')[0]}.enabled", True) and key not in recorded.inputs
        table = values[key] if on else None
        if table and not Path(table).is_file():
            raise ParameterFileError(f"parameter '{key}': no such file {table}")
    publishes, subscribes = role_topics(recorded, roles, role)
    return RolePlan(
        role=role,
        outside=role in outside,
        values=values,
        publishes=tuple(publishes),
        subscribes=tuple(subscribes),
        must_publish=(presence_topic(recorded, role),) if role in EXTERNAL_ROLES else (),
        must_take=REQUIRED_INPUTS.get(role, ()),
    )


def _with_additions(recorded: Resolved, role: str, additions: Mapping[str, Any]) -> Values:
    """The role's checked values with the keys the run adds (rclpy's own left out), each
    checked against its key's schema; what depends on several keys was checked with the
    section (the run's additions are counts, paths and the topics it derives)."""
    values: Values = recorded.values(role)
    schema = node_schema(role, recorded.given(role))
    return values.with_keys(
        {key: schema[key].check(key, v) for key, v in additions.items() if key not in BUILTIN}
    )


def run_directory(out_dir: Path | None, name: str) -> Path:
    """The run directory (``runs/<name>-<time>`` by default); it must not hold anything yet.

    Raises
    ------
    ConfigError
        Naming ``--out`` for a path that exists and is not an empty directory.
    """
    if out_dir is None:
        out_dir = Path("runs") / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    out_dir = out_dir.resolve()
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(f"--out {out_dir}: exists and is not a directory")
    if out_dir.exists() and any(out_dir.iterdir()):
        raise ConfigError(f"--out {out_dir}: exists and is not empty")
    return out_dir
