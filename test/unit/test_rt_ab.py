"""scripts/rt_ab.py refuses a bad variant, scenario or count in one line, before it makes anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "rt_ab.py"


@pytest.mark.parametrize(
    ("args", "code", "said"),
    [
        (["ptc_friction", "no_such_rev"], 1, "variant 'no_such_rev': not a commit of"),
        (["ptc_friction", "HEAD@NOEQ"], 2, "variant 'HEAD@NOEQ': expected REV or REV@NAME=VALUE"),
        (["no_such_scenario", "HEAD"], 2, "scenario 'no_such_scenario': not a shipped scenario"),
        (["ptc_friction", "HEAD", "--reps", "0"], 2, "--reps 0, --seconds 2.0: expected >= 1"),
        (["ptc_friction", "HEAD", "--seconds", "nan"], 2, "expected >= 1 and > 0"),
    ],
)
def test_a_bad_input_is_one_line_and_nothing_is_made(
    tmp_path: Path, args: list[str], code: int, said: str
) -> None:
    work = tmp_path / "work"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *args, "--work", str(work)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == code, done.stderr
    assert said in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert not work.exists()
