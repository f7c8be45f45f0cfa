#!/usr/bin/env python3
"""S-ILC after a reversed Ref. 2 (paper 001 Sect. IV-B), before and after the fix, into docs/figures/.

The 001 scenario ``pilc_ref_change_silc`` with Ref. 2 of the opposite
direction (A = -3 mm: out in -x, back in +x) for 20 trials, and the same
Ref. 2 learned from trial 1, run by the plain-call loop
(:func:`servo_axis.simulate.simulate_learning`, which the node graph
reproduces exactly). "Before" is eq. (3) applied to the absolute input,
``f_{j+1} = Q (f_j + L e_j)``, as :class:`StandardIlc` did until the fix;
"after" is the law as shipped (eq. (3) on the input relative to the level
the trial starts from, see :mod:`servo_axis.core.learning.ilc`). Prints the
RMS per trial and writes docs/figures/silc_relearning.png.

    .venv/bin/python scripts/silc_relearning.py
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import yaml

from servo_axis import numerics
from servo_axis.core.learning.ilc import StandardIlc, check_trial_signal, trial_q
from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import simulate_learning

REPO = Path(__file__).resolve().parents[1]
TRIALS = 20
KT = 0.715  # the nominal K_T of the scenario, N m/A
SHOWN = (9, 10, 11)  # trials whose input and error are plotted


def _absolute_learn(self: StandardIlc, error: Any, *, period: int | None = None) -> np.ndarray:
    """Eq. (3) on the absolute input: the law before the fix."""
    e = check_trial_signal("error", error, self.params.samples_per_trial)
    self._feedforward = trial_q(self._feedforward + self.learning_filter.apply(e), self.params.nq)
    self._trials_learned += 1
    return self._feedforward.copy()


@contextmanager
def _before_the_fix() -> Iterator[None]:
    with mock.patch.object(StandardIlc, "learn", _absolute_learn):
        yield


def _variant(folder: Path, name: str, reference: dict[str, Any]) -> Path:
    data = load_scenario(REPO / "config" / "pilc_ref_change_silc.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = float(TRIALS + 1)  # the last is not learned
    data["feedforward"]["ros__parameters"]["reference"].update(reference)
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _run(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    run = simulate_learning(path)
    e = run.error_m
    f = run.trajectory.feedforward_Nm[: e.size].reshape(e.shape) / KT
    return np.sqrt(np.mean(e**2, axis=1)), e, f


def main() -> None:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        reversed_ref = _variant(folder, "reversed", {"amplitudes_m": [0.002, -0.003]})
        scratch = _variant(
            folder,
            "scratch",
            {
                "amplitudes_m": [-0.003],
                "move_times_s": [0.5],
                "start_times_s": [0.2],
                "first_trials": [1],
            },
        )
        with _before_the_fix():
            before = _run(reversed_ref)
            before_scratch = _run(scratch)
        after = _run(reversed_ref)
        after_scratch = _run(scratch)
    print(
        "trial  RMS (um): reversed Ref. 2 before / after the fix | Ref. 2 from scratch before / after"
    )
    for j in range(TRIALS):
        print(
            f"{j + 1:5d}  {before[0][j] * 1e6:8.3f} / {after[0][j] * 1e6:7.3f}"
            f"   | {before_scratch[0][j] * 1e6:8.3f} / {after_scratch[0][j] * 1e6:7.3f}"
        )
    t = np.arange(before[1].shape[1]) * 1e-3
    trials = np.arange(1, TRIALS + 1)
    fig, ax = plt.subplots(3, 2, figsize=(12, 10))
    ax[0, 0].semilogy(trials, before[0] * 1e6, "o-", label="reversed Ref. 2 from trial 6, before")
    ax[0, 0].semilogy(trials, after[0] * 1e6, "s-", label="reversed Ref. 2 from trial 6, after")
    ax[0, 0].semilogy(trials, before_scratch[0] * 1e6, "x--", label="Ref. 2 from trial 1, before")
    ax[0, 0].semilogy(trials, after_scratch[0] * 1e6, "+--", label="Ref. 2 from trial 1, after")
    ax[0, 0].axvline(5.5, color="k", lw=0.8)
    ax[0, 0].set_xlabel("trial")
    ax[0, 0].set_ylabel("RMS error (um)")
    ax[0, 0].set_title("S-ILC per trial (Ref. 1 = +2 mm, Ref. 2 = -3 mm)")
    ax[0, 0].legend(fontsize=7)
    ends = np.arange(TRIALS)
    ax[0, 1].plot(trials, before[2][ends, 0], "o-", label="f at the trial start, before")
    ax[0, 1].plot(trials, before[2][ends, -1], "o--", label="f at the trial end, before")
    ax[0, 1].plot(trials, after[2][ends, 0], "s-", label="f at the trial start, after")
    ax[0, 1].plot(trials, after[2][ends, -1], "s--", label="f at the trial end, after")
    for level in (3.2 / KT, -3.2 / KT):
        ax[0, 1].axhline(level, color="k", lw=0.6, ls=":")
    ax[0, 1].set_xlabel("trial")
    ax[0, 1].set_ylabel("learned input at rest (A); dotted: +-T_c/K_T")
    ax[0, 1].set_title("the input at rest, reversed Ref. 2")
    ax[0, 1].legend(fontsize=7)
    for col, (label, run) in enumerate((("before the fix", before), ("after the fix", after))):
        for j in SHOWN:
            ax[1, col].plot(t, run[2][j - 1], label=f"trial {j}")
            ax[2, col].plot(t, run[1][j - 1] * 1e6, label=f"trial {j}")
        ax[1, col].set_ylabel("learned input f (A)")
        ax[1, col].set_title(f"reversed Ref. 2, {label}")
        ax[2, col].set_ylabel("error r - x (um)")
        ax[2, col].set_xlabel("time in the trial (s); Ref. 2 moves from 0.2 to 0.7 s")
        ax[1, col].legend(fontsize=7)
    for a in ax.ravel():
        a.grid(True, alpha=0.4)
    fig.tight_layout()
    out = REPO / "docs" / "figures" / "silc_relearning.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out.relative_to(REPO)}")


if __name__ == "__main__":
    main()
