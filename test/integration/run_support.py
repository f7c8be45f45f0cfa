"""Helpers of the integration tests: the processes of a run, shortened paper-001 scenarios."""

from __future__ import annotations

import subprocess
from pathlib import Path

import yaml

from servo_axis.params.scenario import load_scenario

CONFIG = Path(__file__).resolve().parents[2] / "config"
#: Trials of 0.5 s; Ref. 1 for trials 1-5, Ref. 2 from trial 6; 7 trials.
TRIAL_S = 0.5
SWITCH = 6
TRIALS = 7


def short_trials(law: str, path: Path) -> Path:
    """``pilc_ref_change_<law>`` with trials of 0.5 s and the switch at trial 6, written to ``path``."""
    data = load_scenario(CONFIG / f"pilc_ref_change_{law}.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = TRIAL_S * TRIALS
    ff = data["feedforward"]["ros__parameters"]
    ff["reference"].update(
        trial_s=TRIAL_S,
        amplitudes_m=[0.002, 0.003],
        move_times_s=[0.35, 0.3],
        start_times_s=[0.05, 0.1],
        first_trials=[1, SWITCH],
    )
    ff["learning"]["cycle_s"] = TRIAL_S
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def pids_of(run_dir: Path, role: str) -> list[int]:
    """Processes of ``role`` started for this run (their command line names its params file)."""
    out = subprocess.run(
        ["pgrep", "-f", f"servo_axis.nodes.{role} .*{run_dir}/params.yaml"],
        capture_output=True,
        text=True,
        check=False,
    )
    return [int(p) for p in out.stdout.split()]
