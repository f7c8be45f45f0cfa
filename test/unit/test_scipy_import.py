"""numerics.scipy_import: scipy without numpy's f2py and testing, numpy and the numbers unchanged."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = r"""
import json, sys
import numpy as np
before = (sorted(dir(np)), list(np.__all__))
if sys.argv[1] == "installed":
    from servo_axis.numerics import scipy_import
    scipy_import.install()
    scipy_import.install()  # a second call adds nothing
    hooks = sum(type(f).__module__ == scipy_import.__name__ for f in sys.meta_path)
else:
    hooks = 1
import scipy.linalg
m = np.array([[-3.0, 1.5, 0.2], [0.0, -0.5, 2.0], [0.1, 0.0, -7.0]]) * 1e-3
out = {
    "hooks_before_and_after": [hooks, [type(f).__module__ for f in sys.meta_path].count(
        "servo_axis.numerics.scipy_import")],
    "loaded": sorted(n for n in ("numpy.f2py", "numpy.testing") if n in sys.modules),
    "numpy_unchanged": (sorted(dir(np)), list(np.__all__)) == before,
    "expm": scipy.linalg.expm(m).tobytes().hex(),
    "compat_has_linalg": hasattr(sys.modules["scipy._lib.array_api_compat.numpy"], "linalg"),
}
print(json.dumps(out))
"""


def probe(how: str) -> dict[str, object]:
    out = subprocess.run(
        [sys.executable, "-c", PROBE, how], capture_output=True, text=True, check=True
    )
    result: dict[str, object] = json.loads(out.stdout)
    return result


@pytest.fixture(scope="module")
def runs() -> dict[str, dict[str, object]]:
    return {how: probe(how) for how in ("plain", "installed")}


def test_a_plain_import_of_scipy_loads_numpys_f2py_and_testing(
    runs: dict[str, dict[str, object]],
) -> None:
    """What the hook avoids happens without it (else it has no reason to be)."""
    assert runs["plain"]["loaded"] == ["numpy.f2py", "numpy.testing"]


def test_with_the_hook_scipy_loads_neither_and_numpy_and_expm_are_as_they_were(
    runs: dict[str, dict[str, object]],
) -> None:
    got = runs["installed"]
    assert got["hooks_before_and_after"] == [1, 0]  # installed once, gone once used
    assert got["loaded"] == []
    assert got["numpy_unchanged"] is True
    assert got["compat_has_linalg"] is True
    assert got["expm"] == runs["plain"]["expm"]
