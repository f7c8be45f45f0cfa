"""The summary of a run (``summary.json``), typed, and its assembly.

:func:`summarise` computes a single-axis run's :class:`RunSummary` from its
bag and scenario and writes ``summary.json``; :func:`summarise_axes` does the
same for a multi-axis run (:class:`AxesSummary`: each axis and, for two axes,
the contour). ``to_json()`` writes the text layout the runs have always had
(``json.dumps(..., indent=2, allow_nan=True)``, same keys in the same order)
and ``from_json()`` / :func:`load_summary` read it back; the mappings are
made and read by the one serialiser of :mod:`servo_axis.analysis.serial`.

Each block of the summary is computed by the module of its subject, and this
module re-exports their names (``from servo_axis.analysis.summary import X``
keeps working):

* :mod:`~servo_axis.analysis.tracking`: the tracking error's statistics
  (:class:`TrackingError`) and its unit (:func:`error_unit`);
* :mod:`~servo_axis.analysis.learning_summary`: the ILC convergence measure
  of a trial law (:func:`ilc_convergence`, asked of the law's registry entry);
* :mod:`~servo_axis.analysis.identification_summary`: the online identification
  (:class:`OnlineIdentification`, paper 003);
* :mod:`~servo_axis.analysis.deformation_summary`: ``d_r`` at the stops of
  the reference (:class:`Deformation`, paper 004);
* :mod:`~servo_axis.analysis.realtime_summary`: a realtime run's deadline misses
  (:class:`Realtime`);
* :mod:`~servo_axis.analysis.contour_summary`: the contour error of two axes
  (:class:`ContourSummary`).

Every parameter (control period, lead, flags, names) is the checked value of
the scenario (:func:`servo_axis.params.resolve.node_values`), its default
where the scenario does not set it.

Units follow the plant model: the tracking error is the error of the table's
position, ``R (r - y)`` in m for a table that moves along a line (a ball
screw), ``r - y`` in rad for one that turns (a plant model whose registry
entry says ``rotary``: the tilting table of paper 003, whose position is its
angle). A rotary run's summary says ``"error_unit": "rad"`` and its
tracking-error keys are ``rms_rad``, ``max_rad`` (the attributes keep their
``rms_m``, ``max_m`` names: :func:`~servo_axis.analysis.tracking.unit_keys`).
The RMS over every sample of the run (``tracking_error.all_samples.rms_m``,
``rms_rad`` on a rotary table) is the RMSD paper 003 compares (Figs. 7, 9).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from servo_axis.analysis.contour_summary import ContourSummary
from servo_axis.analysis.deformation_summary import (
    DEFORMATION_WINDOWS_S,
    REST_TOLERANCE,
    STOP_KINDS,
    Deformation,
    DeformationStop,
    DeformationWindow,
    ReferenceStop,
    deformation_summary,
    deformation_windows,
    reference_stops,
    window_mask,
)
from servo_axis.analysis.health import RunHealth
from servo_axis.analysis.identification_summary import (
    IDENTIFIED,
    OnlineIdentification,
    ParameterValues,
    UpdateCounts,
    identification,
    summarise_estimates,
    true_parameters,
)
from servo_axis.analysis.learning_summary import ilc_convergence
from servo_axis.analysis.metrics import ContourCycle, ContourResult, contour_error, error_statistics
from servo_axis.analysis.realtime_summary import Realtime
from servo_axis.analysis.serial import Serial
from servo_axis.analysis.signals import (
    IDENTIFIER_SECTION,
    FaultRecord,
    Signals,
    learning_enabled,
    load_signals,
    tracking,
)
from servo_axis.analysis.tracking import (
    CycleStats,
    ErrorStats,
    SampleStats,
    TrackingError,
    axis_values,
    error_unit,
    position_scale,
    unit_keys,
)
from servo_axis.core.errors import ConfigError
from servo_axis.params.factories import build_reference, term_on
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.resolve import Resolved

__all__ = [
    "DEFORMATION_WINDOWS_S",
    "IDENTIFIED",
    "REST_TOLERANCE",
    "STOP_KINDS",
    "SUMMARY_FILE",
    "AxesSummary",
    "ContourCycle",
    "ContourSummary",
    "CycleStats",
    "Deformation",
    "DeformationStop",
    "DeformationWindow",
    "ErrorStats",
    "OnlineIdentification",
    "ParameterValues",
    "Realtime",
    "ReferenceStop",
    "RunSeries",
    "RunSummary",
    "SampleStats",
    "TrackingError",
    "UpdateCounts",
    "contour",
    "cycle_errors",
    "deformation_summary",
    "deformation_windows",
    "error_unit",
    "identification",
    "ilc_convergence",
    "load_summary",
    "position_scale",
    "reference_stops",
    "run_series",
    "summarise",
    "summarise_axes",
    "summarise_estimates",
    "summary_from_dict",
    "true_parameters",
    "window_mask",
]

SUMMARY_FILE = "summary.json"


def _dumps(data: dict[str, Any]) -> str:
    return json.dumps(data, indent=2, allow_nan=True)


def _read(source: str | Path) -> dict[str, Any]:
    """The mapping of a summary given as JSON text or as a file path."""
    if isinstance(source, str) and source.lstrip().startswith("{"):
        text = source
    else:
        text = Path(source).read_text()
    data = json.loads(text)
    if not isinstance(data, dict):
        raise ConfigError(f"summary: expected a JSON object, got {type(data).__name__}")
    return data


@dataclass(frozen=True)
class RunSummary(Serial):
    """Summary of a single-axis run (``summary.json``).

    Attributes
    ----------
    scenario, description : str
        The scenario's name (the file stem if it has none) and description.
    scenario_file : str
        Path of the scenario file the run was started from (what it held
        then is the run directory's ``scenario.yaml``, which every later
        command reads: :mod:`servo_axis.params.recorded`).
    processes : str
        How the nodes ran (``processes``, ``composed``, ...).
    time_mode : str
        ``lockstep`` or ``realtime``.
    control_period_s : float
        ``T_u``, s.
    steps : int
        Recorded control steps (with both state and reference).
    sim_time_s, wall_time_s : float
        Simulated and wall time of the run's steps, s: from state 0 to the
        last step (the plant's report; the runner's view of the recorder's
        progress for an outside plant).
    steps_per_s, realtime_factor : float
        Throughput (NaN when the wall time is not > 0).
    startup_s, finish_s : float or None
        Wall time before state 0 (from the start of the node processes:
        discovery and every handshake) and after the last step (the
        recorder catching up, the processes' exit), s; None (not written)
        when the plant did not report its steps.
    message_counts : dict
        Messages per recorded topic.
    faults : tuple of FaultRecord
        Trips of the feedback loop.
    ptc, friction_table : bool
        Whether the feedforward used PTC and the friction table.
    reference_period_s : float or None
        The learning cycle or the reference's period; None if not periodic.
    tracking_error : TrackingError
        Statistics of the tracking error.
    health : RunHealth or None
        Deaths, restarts, fallbacks, strangers and the exit code (the runner's
        view; None for a summary made from a bag alone).
    period_name : str or None
        ``trial`` when the periods of ``tracking_error.cycles`` are trials (a
        ``trials`` reference, paper 001); None (not written) for cycles.
    ilc_convergence : dict or None
        For a trial law (paper 001): ``nq`` and ``max |Q (1 - S L P)|`` of
        eq. (7) on the nominal model (``nominal``; the law refuses to start
        at 1 or above) and on the rigid-body part of the scenario's plant
        (``plant``); None (not written) otherwise.
    error_unit : str or None
        ``rad`` for a plant whose table turns (its model's ``rotary``): every
        ``*_m`` attribute of ``tracking_error`` is then in rad of table angle,
        and its key in ``summary.json`` ``*_rad``; None (not written): m.
    identification : OnlineIdentification or None
        With an identifier whose estimates the bag holds (paper 003); None
        (not written) otherwise.
    deformation : Deformation or None
        With the ``deformation`` topic in the bag (paper 004); None (not
        written) otherwise.
    realtime : Realtime or None
        A realtime run's deadline misses and lateness (the plant's report);
        None (not written) in lockstep or without the report.
    overrides : tuple of str or None
        The ``--set SECTION.KEY=VALUE`` overrides of the scenario's keys the
        run was given, in order (its ``params.yaml`` holds the result); None
        (not written) for none.
    numerics : str or None
        The numeric paths the run's processes took
        (:func:`servo_axis.numerics.mode`): ``portable`` (the pin: the same
        bag on any x86-64 host), ``native`` (``SERVO_AXIS_NUMERICS=native``)
        or ``host`` (started outside the pin); None (not written) for a
        summary made from a bag alone or before this was recorded.
    """

    scenario: str
    description: str
    scenario_file: str
    processes: str
    time_mode: str
    control_period_s: float
    steps: int
    sim_time_s: float
    wall_time_s: float
    steps_per_s: float
    realtime_factor: float
    message_counts: dict[str, int]
    faults: tuple[FaultRecord, ...]
    ptc: bool
    friction_table: bool
    reference_period_s: float | None
    tracking_error: TrackingError
    health: RunHealth | None = field(default=None, metadata={"omit_none": True})
    period_name: str | None = field(default=None, metadata={"omit_none": True})
    ilc_convergence: dict[str, float] | None = field(default=None, metadata={"omit_none": True})
    error_unit: str | None = field(default=None, metadata={"omit_none": True})
    identification: OnlineIdentification | None = field(default=None, metadata={"omit_none": True})
    deformation: Deformation | None = field(default=None, metadata={"omit_none": True})
    realtime: Realtime | None = field(default=None, metadata={"omit_none": True})
    startup_s: float | None = field(default=None, metadata={"omit_none": True})
    finish_s: float | None = field(default=None, metadata={"omit_none": True})
    overrides: tuple[str, ...] | None = field(default=None, metadata={"omit_none": True})
    numerics: str | None = field(default=None, metadata={"omit_none": True})

    @property
    def unit(self) -> str:
        """The unit of the tracking error: ``m``, or ``rad`` for a rotary table."""
        return self.error_unit or "m"

    def serial_out(self, data: dict[str, Any]) -> dict[str, Any]:
        """The mapping written: a rotary run's error keys named ``*_rad``."""
        data["tracking_error"] = unit_keys(data["tracking_error"], self.unit)
        return data

    @classmethod
    def serial_in(cls, data: Mapping[str, Any]) -> Mapping[str, Any]:
        """The mapping read: ``*_rad`` error keys back to the attributes' ``*_m``."""
        unit = data.get("error_unit") or "m"
        if "tracking_error" not in data:
            return data
        return {**data, "tracking_error": unit_keys(data["tracking_error"], unit, reading=True)}

    @property
    def rmsd(self) -> float:
        """RMS of the tracking error over every sample of the run (003's RMSD), in :attr:`unit`."""
        return self.tracking_error.all_samples.rms_m

    def to_json(self) -> str:
        """The text of ``summary.json``."""
        return _dumps(self.to_dict())

    @classmethod
    def from_json(cls, source: str | Path) -> RunSummary:
        """Read a summary from JSON text or from a ``summary.json`` path."""
        return cls.from_dict(_read(source))


@dataclass(frozen=True)
class AxesSummary(Serial):
    """Summary of a multi-axis run (``summary.json`` of the run directory).

    Attributes
    ----------
    scenario, description : str
        The scenario's name and description.
    wall_time_s : float
        Wall time of the run's steps, s: from the first axis's state 0 to
        the last axis's last step (the whole run where a plant did not
        report its steps).
    axes : dict
        Axis name -> :class:`RunSummary` of that axis.
    contour : ContourSummary or None
        For two axes, their contour error.
    health : RunHealth or None
        The whole run's health (each axis's summary has its own as well).
    overrides : tuple of str or None
        The run's ``--set`` overrides, as each axis's summary has them; None
        (not written) for none.
    """

    scenario: str
    description: str
    wall_time_s: float
    axes: dict[str, RunSummary]
    contour: ContourSummary | None = field(default=None, metadata={"omit_none": True})
    health: RunHealth | None = field(default=None, metadata={"omit_none": True})
    overrides: tuple[str, ...] | None = field(default=None, metadata={"omit_none": True})

    def to_json(self) -> str:
        """The text of ``summary.json``."""
        return _dumps(self.to_dict())

    @classmethod
    def from_json(cls, source: str | Path) -> AxesSummary:
        """Read a summary from JSON text or from a ``summary.json`` path."""
        return cls.from_dict(_read(source))


def summary_from_dict(data: dict[str, Any]) -> RunSummary | AxesSummary:
    """:class:`AxesSummary` for a mapping with ``axes``, else :class:`RunSummary`."""
    return AxesSummary.from_dict(data) if "axes" in data else RunSummary.from_dict(data)


def load_summary(run_dir: Path) -> RunSummary | AxesSummary:
    """The ``summary.json`` of a run directory, single- or multi-axis.

    Raises
    ------
    ConfigError
        If ``run_dir`` is not a directory with a ``summary.json``
        (``<dir>: not a run directory: no summary.json``; for a run directory
        whose runner was killed before it wrote one, what ``bag recover``
        does for it), or the file is not
        a summary this version reads (the message names the file and what is
        wrong).
    """
    path = Path(run_dir) / SUMMARY_FILE
    if not Path(run_dir).is_dir():
        raise ConfigError(f"{run_dir}: not a run directory: no such directory")
    if not path.is_file():
        raise ConfigError(f"{run_dir}: {_no_summary(Path(run_dir))}")
    try:
        return summary_from_dict(_read(path))
    except OSError as err:
        raise ConfigError(f"{path}: cannot read it: {err}") from None
    except (ValueError, KeyError, TypeError, AttributeError) as err:
        what = f"missing key {err}" if isinstance(err, KeyError) else str(err)
        raise ConfigError(f"{path}: not a servo_axis run summary: {what}") from None


def _no_summary(run_dir: Path) -> str:
    """Why ``run_dir`` has no summary, and what to do: a run killed before it wrote one."""
    bags = [run_dir / "bag"] if (run_dir / "bag").is_dir() else sorted(run_dir.glob("*/bag"))
    if not bags:
        return f"not a run directory: no {SUMMARY_FILE}"
    command = " and ".join(f"python -m servo_axis bag recover {b}" for b in bags)
    return (
        f"no {SUMMARY_FILE}: the run has not ended, or was killed before its runner wrote it; "
        f"{command} makes its bag readable and writes the summary of what was recorded"
    )


def cycle_errors(summary: RunSummary) -> dict[str, NDArray[Any]]:
    """Per-cycle tracking error of a run summary, as arrays (cycle number, m).

    Returns ``{"cycle", "max_m", "rms_m", "max_at_tr_m"}``; empty arrays when
    the reference is not periodic.
    """
    cycles = summary.tracking_error.cycles
    return {
        "cycle": np.array([c.cycle for c in cycles], dtype=int),
        "max_m": np.array([c.max_m for c in cycles], dtype=float),
        "rms_m": np.array([c.rms_m for c in cycles], dtype=float),
        "max_at_tr_m": np.array([c.reference_instants.max_m for c in cycles], dtype=float),
    }


def summarise(
    run_dir: Path,
    *,
    scenario: Resolved | dict[str, Any],
    scenario_path: Path,
    wall_time_s: float,
    mode: str,
    health: RunHealth | None = None,
    source_file: Path | None = None,
) -> RunSummary:
    """Compute the summary of a run, write ``summary.json`` and return it.

    The arguments are those of :func:`summarise_series`.
    """
    return summarise_series(
        run_dir,
        scenario=scenario,
        scenario_path=scenario_path,
        wall_time_s=wall_time_s,
        mode=mode,
        health=health,
        source_file=source_file,
    ).summary


def summarise_series(
    run_dir: Path,
    *,
    scenario: Resolved | dict[str, Any],
    scenario_path: Path,
    wall_time_s: float,
    mode: str,
    health: RunHealth | None = None,
    source_file: Path | None = None,
) -> RunSeries:
    """Compute the summary of a run, write ``summary.json``; it with the run's signals.

    What :func:`run_series` reads back from the run directory, without
    reading the bag again: a run's figures (:func:`servo_axis.analysis.plots.plot`)
    come from it (a 13,000-step run's bag takes ~1.1 s to read and check).

    Parameters
    ----------
    run_dir : Path
        The run directory (its bag is ``run_dir / "bag"``).
    scenario : Resolved or dict
        The (single-axis) scenario the run used, or it read once (the
        run's plan hands its values: :attr:`~servo_axis.params.run_plan.AxisPlan.resolved`).
    scenario_path : Path
        Its file (relative friction-table paths are relative to its
        directory): a run's ``scenario.yaml``.
    source_file : Path or None
        The scenario file the run was started from (the summary's
        ``scenario_file`` and, without ``scenario.name``, its name);
        ``scenario_path`` if None.
    wall_time_s : float
        Wall time of the run, s.
    mode : str
        How the nodes ran (``processes``, ``composed``).
    health : RunHealth or None
        What the runner saw (deaths, fallbacks, strangers, exit code).
    """
    run_dir = Path(run_dir)
    resolved = Resolved.of(scenario, scenario_path)
    common = resolved.plant
    period = common.control_period_s
    unit = error_unit(common)
    ff = resolved.feedforward
    sig = load_signals(run_dir / "bag", period, scenario=resolved)
    target, y = tracking(resolved, scenario_path, sig)
    error = position_scale(common) * (target - y)
    learning = learning_enabled(resolved)
    reference_period: float | None = None
    if resolved.has("feedforward") and (not learning or resolved.has(IDENTIFIER_SECTION)):
        reference_period = build_reference(ff).period_s
    cycle = ff.learning.cycle_s if learning else reference_period
    steps = int(sig.step.size)
    sim_time = steps * period
    source = Path(source_file) if source_file is not None else Path(scenario_path)
    summary = RunSummary(
        scenario=common.scenario.name or source.stem,
        description=common.scenario.description,
        scenario_file=str(source),
        processes=mode,
        time_mode=common.mode,
        control_period_s=period,
        steps=steps,
        sim_time_s=sim_time,
        wall_time_s=wall_time_s,
        steps_per_s=steps / wall_time_s if wall_time_s > 0 else math.nan,
        realtime_factor=sim_time / wall_time_s if wall_time_s > 0 else math.nan,
        message_counts=sig.counts,
        faults=tuple(sig.faults),
        ptc=bool(ff.ptc.enabled),
        friction_table=term_on(ff, "friction_table"),
        reference_period_s=cycle,
        tracking_error=TrackingError.from_dict(
            error_statistics(error, sig.step, period_s=period, cycle_s=cycle)
        ),
        health=health,
        period_name="trial" if ff.reference.kind == "trials" else None,
        ilc_convergence=ilc_convergence(resolved, scenario_path),
        error_unit=None if unit == "m" else unit,
        identification=identification(resolved, sig, period_s=reference_period),
        deformation=deformation_summary(resolved, scenario_path, sig),
    )
    (run_dir / SUMMARY_FILE).write_text(summary.to_json())
    return RunSeries(summary, sig, target, y, position_scale(common))


@dataclass(frozen=True, eq=False)
class RunSeries:
    """A recorded run's summary, signals, target and controlled output.

    Attributes
    ----------
    summary : RunSummary
        Its ``summary.json``.
    signals : Signals
        Its bag's signals.
    target_rad, y_rad : ndarray
        Target and controlled output per recorded step (rad), from
        :func:`~servo_axis.analysis.signals.tracking`.
    lead_m_per_rad : float
        Table position per rad: ``R`` of the axis, 1 for a rotary table
        (:func:`position_scale`; the position is then the angle, rad).
    """

    summary: RunSummary
    signals: Signals
    target_rad: NDArray[np.float64]
    y_rad: NDArray[np.float64]
    lead_m_per_rad: float

    @property
    def time_s(self) -> NDArray[np.floating[Any]]:
        """Simulation time of each recorded step, s."""
        t: NDArray[np.floating[Any]] = self.signals.step * self.summary.control_period_s
        return t

    @property
    def error_m(self) -> NDArray[np.floating[Any]]:
        """Tracking error ``R (r - y)`` per recorded step, m (rad for a rotary table)."""
        e: NDArray[np.floating[Any]] = self.lead_m_per_rad * (self.target_rad - self.y_rad)
        return e


def run_series(run_dir: Path) -> RunSeries:
    """Summary, recorded signals, target and controlled output of a run directory.

    The scenario is the run's own (:func:`~servo_axis.params.recorded.recorded_scenario`).
    """
    run_dir = Path(run_dir)
    summary = RunSummary.from_json(run_dir / SUMMARY_FILE)
    recorded = recorded_scenario(run_dir, summary.scenario_file)
    resolved = Resolved(recorded.scenario, recorded.path)
    lead = position_scale(resolved.plant)
    sig = load_signals(run_dir / "bag", summary.control_period_s, scenario=resolved)
    target, y = tracking(resolved, recorded.path, sig)
    return RunSeries(summary, sig, target, y, lead)


def contour(run_dir: Path, axes: list[str] | tuple[str, ...]) -> ContourResult:
    """Contour error of the two axes (sub-directories of ``run_dir``) of a circle run.

    Positions are ``R`` times the target and the controlled output of each
    axis at the steps both recorded; the cycle is the first axis's reference
    period (see :func:`~servo_axis.analysis.metrics.contour_error`).

    Raises
    ------
    ConfigError
        Unless there are exactly two axes.
    """
    if len(axes) != 2:
        raise ConfigError(f"axes: expected two, got {axes!r}")
    series = [run_series(Path(run_dir) / a) for a in axes]
    steps = np.intersect1d(series[0].signals.step, series[1].signals.step)
    target = np.empty((steps.size, 2))
    measured = np.empty((steps.size, 2))
    for col, s in enumerate(series):
        idx = np.searchsorted(s.signals.step, steps)
        target[:, col] = s.lead_m_per_rad * s.target_rad[idx]
        measured[:, col] = s.lead_m_per_rad * s.y_rad[idx]
    first = series[0].summary
    period = float(first.control_period_s)
    cycle_s = first.reference_period_s
    per_cycle = round(cycle_s / period) if cycle_s else None
    return contour_error(target, measured, steps, per_cycle)


def summarise_axes(
    run_dir: Path,
    *,
    scenario: dict[str, Any],
    axes: dict[str, RunSummary],
    wall_time_s: float,
    health: RunHealth | None = None,
    overrides: tuple[str, ...] | None = None,
) -> AxesSummary:
    """Summary of a multi-axis run: the axes' summaries and, for two, the contour.

    Writes ``run_dir / "summary.json"`` and returns it (``overrides``: the
    run's ``--set`` overrides).
    """
    run_dir = Path(run_dir)
    common = axis_values(scenario)
    contour_summary = None
    if len(axes) == 2:
        names = sorted(axes)
        contour_summary = ContourSummary.from_result(names, contour(run_dir, names))
    summary = AxesSummary(
        scenario=common.scenario.name,
        description=common.scenario.description,
        wall_time_s=wall_time_s,
        axes=dict(axes),
        contour=contour_summary,
        health=health,
        overrides=overrides,
    )
    (run_dir / SUMMARY_FILE).write_text(summary.to_json())
    return summary
