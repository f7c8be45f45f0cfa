"""A run's signals for the identification: from a run directory or from the plain-call loops."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.identification.offline.excitation import Excitation
from servo_axis.params.factories import term_on
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.registry import feedforward_terms
from servo_axis.params.resolve import Resolved
from servo_axis.params.scenario import load_scenario
from servo_axis.params.values import PlantValues


@dataclass(frozen=True)
class Record:
    """One run: its scenario and its signals per control sample.

    Attributes
    ----------
    source : str
        Where it came from (the run directory, or ``plain:<scenario>``).
    scenario : dict
        The run's scenario.
    scenario_path : Path
        Its file (relative data files are relative to it).
    step : ndarray of int
        Control samples, ascending and contiguous from the first.
    encoder_rad, scale_m, reference_rad : ndarray
        The sensors and the feedback's reference.
    feedforward_Nm, command_Nm : ndarray
        The torques of ``reference`` and ``command`` (N m).
    resolved : Resolved or None
        The scenario read once (None: read from :attr:`scenario` now).
    """

    source: str
    scenario: dict[str, Any]
    scenario_path: Path
    step: np.ndarray
    encoder_rad: np.ndarray
    scale_m: np.ndarray
    reference_rad: np.ndarray
    feedforward_Nm: np.ndarray
    command_Nm: np.ndarray
    resolved: Resolved | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.resolved is None:
            object.__setattr__(self, "resolved", Resolved(self.scenario, self.scenario_path))

    @property
    def checked(self) -> Resolved:
        """The run's scenario read once: its nodes' checked values (``checked.plant``, ...)."""
        assert self.resolved is not None
        return self.resolved

    @property
    def period_s(self) -> float:
        """The control period ``T_u``, s."""
        return float(self.checked.plant.control_period_s)

    @property
    def lead_m_per_rad(self) -> float:
        """The lead ``R``, m/rad."""
        return float(self.checked.plant.lead_m_per_rad)

    def plant_values(self) -> PlantValues:
        """The run's checked plant values (its plant section: for a real axis only a template)."""
        return self.checked.plant

    def excitation(self) -> Excitation | None:
        """The run's excitation (the ``excitation`` feedforward term), or None when it is off."""
        if not self.checked.has("feedforward"):
            return None
        values = self.checked.feedforward
        if not term_on(values, "excitation"):
            return None
        term = dict(feedforward_terms())["excitation"].build(values)
        excitation = getattr(term, "excitation", None)
        return excitation if isinstance(excitation, Excitation) else None

    def window(self, first: int, stop: int) -> slice:
        """The samples of control steps ``first .. stop - 1``; SignalError if the run lacks any."""
        start = int(self.step[0]) if self.step.size else 0
        lo, hi = first - start, stop - start
        if (
            lo < 0
            or hi > self.step.size
            or not np.array_equal(self.step[lo:hi], np.arange(first, stop))
        ):
            raise SignalError(
                f"{self.source}: expected every control step {first} .. {stop - 1} of the "
                f"excitation recorded, got steps {start} .. {start + self.step.size - 1}"
                + (" with gaps" if self.step.size else "")
            )
        return slice(lo, hi)


def from_run(run_dir: Path) -> Record:
    """The :class:`Record` of a recorded single-axis run directory.

    Its scenario is the one the run recorded (``scenario.yaml`` of the run
    directory, :func:`~servo_axis.params.recorded.recorded_scenario`).
    """
    from servo_axis.analysis.signals import load_signals
    from servo_axis.analysis.summary import RunSummary, load_summary

    run_dir = Path(run_dir)
    summary = load_summary(run_dir)
    if not isinstance(summary, RunSummary):
        axes = ", ".join(str(run_dir / a) for a in summary.axes)
        raise ConfigError(f"{run_dir}: a multi-axis run; give one of its axes: {axes}")
    # What the run ran, from its directory: never the scenario file as it is now.
    recorded = recorded_scenario(run_dir, summary.scenario_file)
    scenario, path = recorded.scenario, recorded.path
    resolved = Resolved(scenario, path)
    period = float(resolved.plant.control_period_s)
    sig = load_signals(run_dir / "bag", period, scenario=resolved)
    if sig.step.size < 3:
        raise SignalError(
            f"{run_dir / 'bag'}: expected a recorded run, got {sig.step.size} samples"
        )
    command = sig.command_Nm
    if np.isnan(command).any():
        # A missing command sample: the torque held, as the plant does.
        idx = np.where(np.isnan(command), 0, np.arange(command.size))
        np.maximum.accumulate(idx, out=idx)
        command = command[idx]
    return Record(
        source=str(run_dir),
        scenario=scenario,
        scenario_path=path,
        step=sig.step,
        encoder_rad=sig.encoder_rad,
        scale_m=sig.scale_m,
        reference_rad=sig.reference_rad,
        feedforward_Nm=sig.feedforward_Nm,
        command_Nm=command,
        resolved=resolved,
    )


def from_simulation(scenario_path: Path) -> Record:
    """The :class:`Record` of the plain-call loop of a scenario file (what a run records)."""
    from servo_axis.simulate import simulate

    traj = simulate(Path(scenario_path))
    return Record(
        source=f"plain:{scenario_path}",
        scenario=load_scenario(Path(scenario_path)),
        scenario_path=Path(scenario_path),
        step=np.arange(traj.encoder_rad.size),
        encoder_rad=traj.encoder_rad,
        scale_m=traj.scale_m,
        reference_rad=traj.reference_rad,
        feedforward_Nm=traj.feedforward_Nm,
        command_Nm=traj.command_Nm,
    )
