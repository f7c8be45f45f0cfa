"""The parameter reference in docs/ is the one the schemas generate."""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

from servo_axis.params.registry import parameter_sections

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
    for title, schema in parameter_sections().items():
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


def test_help_writes_nothing_and_check_tells_a_stale_file(tmp_path: Path) -> None:
    """`parameter_docs.py --help` rewrote docs/parameters.md (it took no options)."""
    page = REPO / "docs" / "parameters.md"
    before = page.stat().st_mtime_ns
    helped = subprocess.run(
        [sys.executable, str(SCRIPT), "--help"], capture_output=True, text=True, cwd=tmp_path
    )
    assert helped.returncode == 0 and helped.stdout.startswith("usage: parameter_docs.py")
    assert "written" not in helped.stdout and page.stat().st_mtime_ns == before
    out = tmp_path / "p.md"
    check = [sys.executable, str(SCRIPT), "--out", str(out), "--check"]
    assert subprocess.run(check, capture_output=True).returncode == 1  # no file yet
    subprocess.run(
        [sys.executable, str(SCRIPT), "--out", str(out)], check=True, capture_output=True
    )
    assert out.read_text() == page.read_text()
    assert subprocess.run(check, capture_output=True).returncode == 0
    assert page.stat().st_mtime_ns == before


def test_the_repository_refers_to_nothing_a_clone_lacks() -> None:
    """No ``../shared/...`` and no "DESIGN N": the design intent is docs/design.md,
    the papers are cited in docs/papers.md, and the links between the docs resolve."""
    import re

    checked = [*REPO.glob("*.md"), REPO / "pyproject.toml"]
    for folder, pattern in (("src", "*"), ("docs", "*.md"), ("scripts", "*"), ("test", "*.py")):
        checked += [p for p in (REPO / folder).rglob(pattern) if p.is_file()]
    checked = [p for p in checked if p.suffix in {".py", ".md", ".yaml", ".toml", ".sh", ".txt"}]
    checked = [p for p in checked if "egg-info" not in str(p) and p != Path(__file__)]
    assert len(checked) > 100
    for path in checked:
        text = path.read_text(errors="replace")
        assert "../shared" not in text and "shared/papers" not in text, path
        assert not re.search(r"DESIGN\s+\d", text), path
    for doc in [*REPO.glob("*.md"), *(REPO / "docs").glob("*.md")]:
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", doc.read_text()):
            assert (doc.parent / target).exists(), f"{doc.name}: link to {target} does not resolve"
    design = (REPO / "docs" / "design.md").read_text()
    for n in range(1, 8):
        assert f"\n## {n}. " in design, f"docs/design.md has no section {n}"
    papers = (REPO / "docs" / "papers.md").read_text()
    for number in ("000", "001", "003", "004"):
        assert f"| {number} |" in papers
