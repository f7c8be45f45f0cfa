"""MkDocs hooks of the documentation site (``mkdocs.yml``: ``hooks:``).

Two reference pages are made from the code at build time, so they cannot go
stale:

* ``reference/cli.md``: its ``<!-- cli-reference -->`` marker becomes every
  command and option of ``python -m servo_axis``, read from the argparse parser
  that the command line itself uses (``servo_axis.__main__.build_parser``);
* ``reference/api/<package>.md``: one page per package of :data:`API`, a
  mkdocstrings block (``::: module``) for each of its modules found in the
  source tree, so a module added or renamed is documented without an edit here.

Nothing here imports rclpy: the parser is built without running a command.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
CLI_MARKER = "<!-- cli-reference -->"

#: Package -> (title, one line on what it holds) of the API pages.
API = {
    "core": ("servo_axis.core", "The numerics: numpy and scipy only, no I/O, no ROS."),
    "params": (
        "servo_axis.params",
        "Parameter schemas, scenario files, the registries of the extension points, "
        "factories and the resolver.",
    ),
    "analysis": (
        "servo_axis.analysis",
        "Reading a run's bag, the summary (`summary.json`) and its blocks, the plots.",
    ),
    "sweep": ("servo_axis.sweep", "Studies: parameter sweeps on dask.distributed."),
    "simulate": (
        "servo_axis.simulate",
        "The plain-call loops that the node graph reproduces bit for bit.",
    ),
}


def modules_of(package: str) -> list[str]:
    """The dotted names of the modules of ``servo_axis.<package>`` (sorted; packages first)."""
    root = SRC / "servo_axis" / package
    if root.with_suffix(".py").is_file():
        return [f"servo_axis.{package}"]
    names = []
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        names.append(".".join(parts))
    return sorted(names, key=lambda n: (n.count("."), n))


def api_page(package: str) -> str:
    """The markdown of the API page of ``package``: a heading and a block per module."""
    title, about = API[package]
    blocks = [f"# {title}\n\n{about} Generated from the docstrings.\n"]
    for name in modules_of(package):
        blocks.append(
            f"::: {name}\n    options:\n      show_root_heading: true\n"
            "      show_root_full_path: true\n      heading_level: 2\n      members_order: source\n"
        )
    return "\n".join(blocks)


def _cell(text: str) -> str:
    """One line of markdown: ``|`` escaped, ``<name>`` shown rather than taken for HTML."""
    text = " ".join(text.split()).replace("|", "\\|")
    return text.replace("<", "&lt;").replace(">", "&gt;")


def _option_row(action: argparse.Action) -> str:
    names = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.dest}`"
    if action.option_strings and action.nargs != 0:
        metavar = action.metavar or action.dest.upper()
        names += f" `{metavar}`" if isinstance(metavar, str) else ""
    default = action.default
    shown = (
        ""
        if default in (None, False, "", [], argparse.SUPPRESS) or action.nargs == 0
        else f"`{default}`"
    )
    meaning = action.help or ""
    if action.choices and not isinstance(action, argparse._SubParsersAction):
        meaning += f" (one of: {', '.join(f'`{c}`' for c in action.choices)})"
    return f"| {names} | {shown} | {_cell(meaning)} |"


def _options_table(parser: argparse.ArgumentParser) -> str:
    rows = [
        _option_row(a)
        for a in parser._actions
        if a.help != argparse.SUPPRESS
        and not isinstance(a, argparse._HelpAction | argparse._SubParsersAction)
    ]
    if not rows:
        return ""
    return "| argument | default | meaning |\n| --- | --- | --- |\n" + "\n".join(rows) + "\n"


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    found: list[tuple[str, argparse.ArgumentParser]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                if sub not in [s for _, s in found]:
                    found.append((name, sub))
    return found


def cli_reference(parser: argparse.ArgumentParser, level: int = 2) -> str:
    """Every command of ``parser`` with its usage, description and options, as markdown."""
    out = []
    for name, sub in _subcommands(parser):
        words = sub.prog.split()
        heading = (
            " ".join(words[words.index("servo_axis") + 1 :]) if "servo_axis" in words else name
        )
        out.append(f"{'#' * level} `{heading}`\n")
        if sub.description:
            out.append(_cell(sub.description) + "\n")
        out.append("```text\n" + sub.format_usage().removeprefix("usage: ").strip() + "\n```\n")
        table = _options_table(sub)
        if table:
            out.append(table)
        if sub.epilog:
            out.append("```text\n" + sub.epilog.strip() + "\n```\n")
        if _subcommands(sub):
            out.append(cli_reference(sub, level + 1))
    return "\n".join(out)


def cli_page_text() -> str:
    """The generated part of the CLI reference: top-level usage, options, then each command."""
    from servo_axis.__main__ import build_parser

    parser = build_parser("python -m servo_axis")
    head = "```text\n" + parser.format_usage().removeprefix("usage: ").strip() + "\n```\n"
    return "\n".join([head, _options_table(parser), cli_reference(parser)])


def on_files(files: Files, config: Any) -> Files:
    """Add the generated API pages (``reference/api/<package>.md``)."""
    for package in API:
        files.append(
            File.generated(config, f"reference/api/{package}.md", content=api_page(package))
        )
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    """Fill the CLI reference's marker."""
    if CLI_MARKER in markdown:
        return markdown.replace(CLI_MARKER, cli_page_text())
    return markdown
