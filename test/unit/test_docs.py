"""The parameter reference in docs/ is the one the schemas generate."""

from __future__ import annotations

import runpy
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_parameter_reference_is_up_to_date() -> None:
    render = runpy.run_path(str(REPO / "scripts" / "parameter_docs.py"))["render"]
    text = (REPO / "docs" / "parameters.md").read_text()
    assert text == render(), "docs/parameters.md is stale: run scripts/parameter_docs.py"
    assert "`friction.rolling_coulomb_Nm`" in text and "`bandwidth_hz`" in text
