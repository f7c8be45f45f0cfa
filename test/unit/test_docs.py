"""The parameter reference in docs/ is the one the schemas generate."""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

from servo_axis.params.schemas import SECTIONS

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "parameter_docs.py"


def test_parameter_reference_is_up_to_date() -> None:
    render = runpy.run_path(str(SCRIPT))["render"]
    text = (REPO / "docs" / "parameters.md").read_text()
    assert text == render(), "docs/parameters.md is stale: run scripts/parameter_docs.py"
    assert "`friction.rolling_coulomb_Nm`" in text and "`bandwidth_hz`" in text
    assert "| parameter | default | unit | range | meaning |" in text


def test_parameter_reference_lists_every_key_with_its_meaning() -> None:
    text = (REPO / "docs" / "parameters.md").read_text()
    # Two plant models may share a key name: look for each in its own section.
    sections = {chunk.split("\n", 1)[0].strip(): chunk for chunk in text.split("\n## ")[1:]}
    for title, schema in SECTIONS.items():
        assert f"## {title}" in text or title == "/**"
        body = next((c for head, c in sections.items() if head.startswith(title)), text)
        for name, param in schema.items():
            row = next((r for r in body.splitlines() if r.startswith(f"| `{name}` |")), None)
            assert row is not None, f"{title}: '{name}' missing"
            assert row.endswith(f"| {param.meaning.replace('|', chr(92) + '|')} |")


def test_generator_imports_no_node_and_no_rclpy() -> None:
    code = (
        "import runpy, sys\n"
        f"runpy.run_path({str(SCRIPT)!r})['render']()\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] == 'rclpy'"
        " or m.startswith('servo_axis.nodes'))\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)
