"""The parameter reference in docs/ is the one the schemas generate."""

from __future__ import annotations

import os
import re
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
    # The suite's own sections (plugins installed beside it are not on the page).
    for title, schema in parameter_sections(shipped_only=True).items():
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
    # The options themselves through the script's main (the command line is
    # the one above; a process each would only repeat its imports).
    main = runpy.run_path(str(SCRIPT))["main"]
    out = tmp_path / "p.md"
    check = ["--out", str(out), "--check"]
    assert main(check) == 1  # no file yet
    assert main(["--out", str(out)]) == 0
    assert out.read_text() == page.read_text()
    assert main(check) == 0
    assert page.stat().st_mtime_ns == before


def test_the_repository_refers_to_nothing_a_clone_lacks() -> None:
    """No ``../shared/...`` and no "DESIGN N": the design intent is docs/design.md,
    the papers are cited in docs/papers.md, and the links between the docs resolve."""
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
    for doc in [*REPO.glob("*.md"), *(REPO / "docs").rglob("*.md")]:
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", doc.read_text()):
            if (doc.parent / target).resolve().parent == REPO / "docs" / "reference" / "api":
                continue  # made at build time (scripts/docs_hooks.py); the strict build checks it
            assert (doc.parent / target).exists(), f"{doc.name}: link to {target} does not resolve"
    design = (REPO / "docs" / "design.md").read_text()
    for n in range(1, 8):
        assert f"\n## {n}. " in design, f"docs/design.md has no section {n}"
    papers = (REPO / "docs" / "papers.md").read_text()
    for number in ("000", "001", "003", "004"):
        assert f"| {number} |" in papers


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    """`mkdocs build --strict`: a warning fails it (a broken link or anchor, a page not in
    the nav, a snippet whose file is gone, a docstring the API pages cannot read)."""
    site = tmp_path / "site"
    build = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=REPO,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        timeout=300,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    # The generated pages: every command of the parser, the API from the docstrings.
    cli = (site / "reference" / "cli" / "index.html").read_text()
    from servo_axis.__main__ import build_parser

    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    for name in commands:
        assert f'id="{name}"' in cli, f"the CLI page lacks {name}"
    assert "--external-timeout" in cli and "--retry-failed" in cli
    api = (site / "reference" / "api" / "core" / "index.html").read_text()
    assert "servo_axis.core.timing" in api and "SampleGrid" in api
    assert "check_values" in (site / "reference" / "api" / "params" / "index.html").read_text()
    # The tutorials show the tested files themselves (snippets), not copies.
    tutorial = (site / "tutorials" / "own-controller" / "index.html").read_text()
    assert "PdController" in tutorial and "create_publisher" in tutorial


def test_the_readme_starts_with_the_two_commands_and_stays_short() -> None:
    readme = (REPO / "README.md").read_text()
    block = readme.split("```bash\n", 1)[1].split("```", 1)[0].splitlines()
    assert block[0].startswith("scripts/run_default.sh ") and block[1].startswith(
        "scripts/test.sh "
    )
    assert len(readme.splitlines()) < 150
    assert not re.search(r"\(20\d\d-\d\d-\d\d", readme), "dated measurements go to the history"
    for paper in ("000", "001", "003", "004"):
        assert f"| {paper}: " in readme


def test_figures_live_in_one_folder_and_every_one_is_linked() -> None:
    docs = REPO / "docs"
    assert not list(docs.glob("*.png")), "figures go into docs/figures/"
    text = "\n".join(p.read_text() for p in [REPO / "README.md", *docs.rglob("*.md")])
    for figure in (docs / "figures").rglob("*.png"):
        assert figure.name in text, f"{figure.relative_to(REPO)} is linked from no page"


def test_todays_benchmark_table_is_the_newest_of_the_history() -> None:
    """The table on top of docs/benchmarks.md is what scripts/benchmark.py makes of its
    history (`--current-from-history`), one row per shipped scenario."""
    bench = runpy.run_path(str(REPO / "scripts" / "benchmark.py"), run_name="benchmark")
    history = (REPO / "docs" / "history" / "benchmarks.md").read_text()
    page = (REPO / "docs" / "benchmarks.md").read_text()
    rows = bench["current_from_history"](history)
    assert bench["read_current"](page) == rows
    assert bench["render_current"](rows) in page
    shipped = {p.stem for p in (REPO / "config").glob("*.yaml")}
    assert shipped <= set(rows), f"no benchmark row for {sorted(shipped - set(rows))}"


def test_a_benchmark_run_updates_its_rows_and_keeps_the_others(tmp_path: Path) -> None:
    bench = runpy.run_path(str(REPO / "scripts" / "benchmark.py"), run_name="benchmark")
    page = tmp_path / "benchmarks.md"
    page.write_text("# Benchmarks\n\nintro\n\n" + bench["render_current"]({}) + "\n\nafter\n")
    section = "\n".join(
        [
            bench["LOCK_HEADER"],
            "| --- | --- | --- | --- | --- | --- |",
            "| a | 1 | 5.00x (0.30) | 1.5 / 0.2 | 4.00x (0.25) | 90.0x |",
            "| b | 0.5 | 2.00x (0.20) | 1.5 / 0.2 | n/a: a multi-axis run has separate "
            "processes only | 60.0x |",
            "",
            bench["RT_HEADER"],
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
            "| a | 1 | 3 of 1000 (0.30 %) | 0.66 % | 1/2/3 | 4/5/6 | 1.0000 | 0 | 1/1 | 0/0 |",
        ]
    )
    bench["update_current"](page, bench["rows_from_section"](section, "then, abc1234, --all"))
    later = section.replace("5.00x (0.30)", "6.00x (0.31)").replace("| b |", "| c |")
    bench["update_current"](page, bench["rows_from_section"](later, "now, def5678, --quick"))
    rows = bench["read_current"](page.read_text())
    assert sorted(rows) == ["a", "b", "c"]
    assert rows["a"][2:] == [
        "6.00x (0.31)",
        "4.00x (0.25)",
        "90.0x",
        "0.30 % (0.66 %)",
        "now, def5678, --quick",
    ]
    assert rows["b"][3] == "n/a" and rows["b"][5] == "-" and rows["b"][6] == "then, abc1234, --all"
    text = page.read_text()
    assert text.startswith("# Benchmarks\n\nintro\n") and text.endswith("\nafter\n")


def test_code_and_help_point_to_pages_that_exist_not_to_readme_sections() -> None:
    """The README's old sections (Studies, Watching a live run, ...) moved to the site:
    a pointer in a docstring, a help text or the run's header names a page of docs/."""
    named = set()
    for path in (REPO / "src").rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"README[,:)]", text), f"{path.relative_to(REPO)} points to the README"
        named |= set(re.findall(r"docs/[\w/-]+\.md", text))
    assert "docs/how-to/watch-a-run.md" in named and "docs/reference/studies.md" in named
    missing = sorted(p for p in named if not (REPO / p).is_file())
    assert not missing, f"pointers to no page: {missing}"
