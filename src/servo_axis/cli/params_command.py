"""``params [NAME]``: every key of what is installed here, with its default, unit, range and meaning.

docs/parameters.md is the reference of the suite as it ships; the plugins
installed beside it (another distribution's entry points) are not on it,
since the site is built once, not on the user's machine. This command is
the reference of the installation at hand, as ``ros2 param describe`` or
``gst-inspect-1.0`` are: each node's keys and each installed extension's,
from the same schemas the nodes check, with where each extension comes from.
"""

from __future__ import annotations

import argparse
import difflib
from collections.abc import Mapping
from dataclasses import dataclass

from servo_axis.cli.options import Subparsers
from servo_axis.core.errors import ConfigError
from servo_axis.params.param import Param


def add_parser(commands: Subparsers) -> None:
    """The ``params`` command."""
    pm = commands.add_parser(
        "params",
        help="every key of the nodes and of the installed extensions (plugins included) with "
        "its default, unit, range and meaning; NAME: one node or extension",
    )
    pm.add_argument(
        "name",
        nargs="?",
        default=None,
        metavar="NAME",
        help="a node (shared, plant, feedback, feedforward, learning, identifier, recorder: its "
        "keys and its installed extensions') or an extension (ball_screw, friction_table, rptc, "
        "dlpid, an installed plugin's name)",
    )
    pm.set_defaults(func=handle)


@dataclass(frozen=True)
class Section:
    """One block of the output: a node's own keys or one extension's."""

    title: str
    node: str
    name: str
    source: str
    schema: Mapping[str, Param]


#: The nodes in the order of a scenario file, with the schema of each.
NODES = ("shared", "plant", "feedback", "feedforward", "learning", "identifier", "recorder")
#: Which kind of extension plugs into which node, and what one is called in its title.
EXTENDED_BY = {
    "plant": ("plant model", "model"),
    "feedforward": ("feedforward term", "term"),
    "learning": ("learning law", "law"),
    "identifier": ("identification method", "method"),
}


def sections() -> list[Section]:
    """Every node's section, each followed by those of its installed extensions."""
    from servo_axis.params import schemas
    from servo_axis.params.registry import REGISTRIES, feedforward_terms

    own = {
        "shared": schemas.SHARED,
        "plant": schemas.PLANT,
        "feedback": schemas.FEEDBACK,
        "feedforward": schemas.FEEDFORWARD,
        "learning": schemas.LEARNING,
        "identifier": schemas.IDENTIFIER,
        "recorder": schemas.RECORDER,
    }
    out: list[Section] = []
    for node in NODES:
        title = "shared (/**, read by every node)" if node == "shared" else f"{node} node"
        out.append(Section(title, node, node, "", own[node]))
        if node not in EXTENDED_BY:
            continue
        kind, word = EXTENDED_BY[node]
        registry = REGISTRIES[kind]
        names = [n for n, _ in feedforward_terms()] if node == "feedforward" else sorted(registry)
        for name in names:
            dist = registry.distribution(name)
            of = f", {dist}" if dist and not registry.shipped(name) else ""
            out.append(
                Section(
                    f"{node} ({word} {name})",
                    node,
                    name,
                    f"{registry.source(name)}{of}",
                    registry[name].schema,
                )
            )
    return out


def _range(param: Param) -> str:
    d = param.default
    if isinstance(d, list) and d and isinstance(d[0], str):
        return ""
    return param.range_text().replace("\\|", "|")


def render(section: Section) -> str:
    """A section as aligned text: a heading, then one line per key."""
    head = section.title + (f"  [{section.source}]" if section.source else "")
    if not section.schema:
        return f"{head}\n  (no keys of its own)\n"
    rows = [("parameter", "default", "unit", "range", "meaning")]
    rows += [(k, repr(p.default), p.unit, _range(p), p.meaning) for k, p in section.schema.items()]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = [head]
    for row in rows:
        cells = [row[i].ljust(widths[i]) for i in range(4)]
        lines.append(("  " + "  ".join([*cells, row[4]])).rstrip())
    return "\n".join(lines) + "\n"


def chosen(name: str | None, found: list[Section]) -> list[Section]:
    """The sections ``name`` names: a node's with its extensions', or one extension's.

    Raises
    ------
    ConfigError
        For a broken extension (its entry point and error named) or a name
        that is neither a node nor an installed extension (the closest and
        every name listed).
    """
    if name is None:
        return found
    key = "shared" if name == "/**" else name
    if key in NODES:
        return [s for s in found if s.node == key]
    picked = [s for s in found if s.name == key and s.node != key]
    if picked:
        return picked
    from servo_axis.params.registry import broken_plugins

    for plugin in broken_plugins():
        if plugin.name == key:
            raise ConfigError(f"params {name}: {plugin.line()}")
    names = [*NODES, *sorted({s.name for s in found} - set(NODES))]
    close = difflib.get_close_matches(key, names, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise ConfigError(
        f"params {name}: neither a node nor an installed extension ({hint}expected one of "
        f"{', '.join(names)})"
    )


def handle(args: argparse.Namespace) -> int:
    """Print the sections ``args.name`` names (all without one)."""
    picked = chosen(args.name, sections())
    print("\n".join(render(s) for s in picked), end="")
    return 0
