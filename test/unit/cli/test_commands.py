"""The command line is one module per command, each listed once, each with its handler.

``servo_axis/cli/<name>_command.py`` adds its parser in ``add_parser`` and
sets its handler; ``servo_axis.__main__.COMMANDS`` lists them in the order
of the help. A module written but not listed would be a command nobody can
call: this fails on it.
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
from pathlib import Path

import servo_axis.cli
from servo_axis.__main__ import COMMANDS, build_parser

CLI = Path(servo_axis.cli.__file__).parent


def test_every_command_module_is_listed_once() -> None:
    modules = sorted(p.stem for p in CLI.glob("*_command.py"))
    listed = [m.__name__.rpartition(".")[2] for m in COMMANDS]
    assert sorted(listed) == modules
    assert len(set(listed)) == len(listed)


def test_each_command_sets_its_handler() -> None:
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    # Each module adds the commands named like it (bag: bag recover).
    for module in COMMANDS:
        name = module.__name__.rpartition(".")[2].removesuffix("_command").replace("_", "-")
        sub = commands.choices[name]
        nested = [a for a in sub._actions if isinstance(a, argparse._SubParsersAction)]
        leaves = list(nested[0].choices.values()) if nested else [sub]
        for leaf in leaves:
            handler = leaf.get_default("func")
            assert callable(handler), (name, leaf.prog)
            assert importlib.import_module(handler.__module__) is module


def test_the_help_and_the_parser_load_no_ros_numba_or_matplotlib() -> None:
    code = (
        "import sys, contextlib, io\n"
        "from servo_axis.__main__ import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main(['--help']) == 0\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'numba', 'matplotlib', 'scipy', 'numpy'))\n"
        "print(heavy)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.strip() == "[]"
