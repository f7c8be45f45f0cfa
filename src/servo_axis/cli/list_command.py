"""``list``: the shipped scenarios, then the installed extensions with their keys.

An installed extension that cannot be loaded is listed as ``broken`` with
its error (:attr:`servo_axis.params.registry.Registry.broken`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from servo_axis.cli.options import Subparsers, existing_dir
from servo_axis.core.errors import ConfigError


def add_parser(commands: Subparsers) -> None:
    """The ``list`` command and its option."""
    ls = commands.add_parser(
        "list",
        help="the shipped scenarios and what each runs, then the installed plant models, "
        "feedforward terms, learning laws and identification methods with their keys",
    )
    ls.add_argument(
        "--config-dir",
        type=existing_dir,
        default=None,
        help="list this folder's scenarios instead",
    )
    ls.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Each scenario with its description, then :func:`_list_extensions`."""
    from servo_axis.params.scenario import load_scenario, scenario_dir, shared

    folder = Path(args.config_dir) if args.config_dir else scenario_dir()
    found = sorted(folder.glob("*.yaml"))
    if not found:
        raise ConfigError(f"--config-dir {folder}: no scenario files (*.yaml) there")
    width = max(len(p.stem) for p in found)
    for path in found:
        about = shared(load_scenario(path)).get("scenario", {})
        print(f"{path.stem:<{width}}  {about.get('description', '')}")
    _list_extensions()
    return 0


def _list_extensions() -> None:
    """The installed plant models, feedforward terms, learning laws and identification methods."""
    from servo_axis.params.registry import REGISTRIES

    selected_by = {
        "plant model": "plant.model",
        "feedforward term": "its <term>.enabled",
        "learning law": "learning.law",
        "identification method": "identifier.method",
    }
    width = max(len(name) for registry in REGISTRIES.values() for name in registry)
    for kind, registry in REGISTRIES.items():
        print(f"\n{kind}s (selected by {selected_by[kind]}; entry points {registry.group}):")
        broken = registry.broken
        for name in sorted([*registry, *broken]):
            if name in broken:
                # Listed, so that a user sees it is installed and why it does not work.
                plugin = broken[name]
                of = f", {plugin.distribution}" if plugin.distribution else ""
                print(f"  {name:<22} broken: {plugin.error} [{plugin.value}{of}]")
                continue
            entry = registry[name]
            dist = registry.distribution(name)
            of = f", {dist}" if dist and not registry.shipped(name) else ""
            print(f"  {name:<{width}}  {entry.description} [{registry.source(name)}{of}]")
            if entry.schema:
                print(f"  {'':<{width}}  keys: {', '.join(entry.schema)}")
    print(
        "\nEach key's default, unit, range and meaning: python -m servo_axis params NAME "
        "(a node or an extension); every installed one: python -m servo_axis params"
    )
