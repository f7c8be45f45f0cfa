"""The committed scenario hashes hold on this machine, and as if on another one.

``scripts/scenario_hashes.py --check`` runs each scenario through
``python -m servo_axis run`` and compares the SHA-256 of every recorded
topic with ``test/data/scenario_hashes.txt``: with the versions of
``requirements.lock`` (``scripts/setup.sh``) any x86-64 machine records the
same bytes (docs/explanation/numerics.md). Here two scenarios of 2 s each,
as they are and with every mask of ``servo_axis.numerics.MASKS`` (numpy
without AVX-512, libm without FMA, OpenBLAS's Haswell kernels, numba for
Haswell: what another CPU would choose), composed; the whole file is
checked by the script itself (docs/how-to/develop.md).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
FAST = ("pid_disturbance", "ptc_nominal")


@pytest.mark.parametrize("host", ["this", "another"])
def test_the_committed_hashes_of_fast_scenarios_are_reproduced(ros_env: int, host: str) -> None:
    as_if = ["--mask", "all", "--composed"] if host == "another" else []
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "scripts" / "scenario_hashes.py"),
            "--domain-id",
            str(ros_env),
            *as_if,
            "--check",
            str(REPO / "test" / "data" / "scenario_hashes.txt"),
            *(str(REPO / "config" / f"{name}.yaml") for name in FAST),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    differ = [ln for ln in proc.stderr.splitlines() if ln.startswith(("expected ", "got "))]
    assert proc.returncode == 0, "\n".join(differ) or proc.stderr[-2000:]
    assert "identical: 12 topics of 2 scenarios" in proc.stderr
