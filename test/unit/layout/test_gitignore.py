"""What a run or a study writes into a checkout is ignored by git; the shipped files are not."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def ignored(path: str) -> bool:
    """``git check-ignore`` of a path of the checkout (it need not exist)."""
    proc = subprocess.run(
        ["git", "-C", str(REPO), "check-ignore", "--no-index", "-q", path], check=False
    )
    assert proc.returncode in (0, 1), proc
    return proc.returncode == 0


@pytest.mark.skipif(
    shutil.which("git") is None or not (REPO / ".git").exists(), reason="not a git checkout"
)
def test_outputs_are_ignored_and_shipped_files_are_not() -> None:
    # `sweep` writes studies/<name>/ by default, `run` runs/<name>-<time>/, mkdocs site/.
    for output in ("studies/reversal_004/results.csv", "runs/ptc_nominal-1/summary.json"):
        assert ignored(output), output
    assert ignored("site/index.html")
    for shipped in (
        "src/servo_axis/studies/reversal_004.yaml",
        "src/servo_axis/scenarios/ptc_nominal.yaml",
        "docs/figures/studies/reversal_004_max.png",
    ):
        assert not ignored(shipped), shipped
