"""What every command of the command line shares: the parser, the option types, file errors.

Every bad option is one line on stderr and exit 2 (:class:`Parser`): the
types here refuse a value with the words argparse puts after
``error: argument --option:``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import NoReturn, TypeAlias

from servo_axis.core.errors import ConfigError
from servo_axis.params.names import domain_id_problem, namespace_problem

#: The shipped scenario ``python -m servo_axis`` runs.
DEFAULT_SCENARIO = "rptc_friction_table"

#: What a command module's ``add_parser`` is given: the top-level parser's subparsers.
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2)."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())
        self.exit(2, f"error: {text} (see {self.prog} --help)\n")


def describe_commands(parser: argparse.ArgumentParser) -> None:
    """Give each (sub)command without a description its help as one, so its --help starts with it."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                command = action.choices[choice.dest]
                text = choice.help
                if command.description is None and text:
                    command.description = f"{text[0].upper()}{text[1:]}."
                describe_commands(command)


def domain_id(text: str) -> int:
    problem = domain_id_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return int(text)


def namespace(text: str) -> str:
    if text == "":
        return ""
    problem = namespace_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{text!r} is not a valid ROS namespace: {problem}")
    return "" if text == "/" else text


def int_at_least(low: int, high: int | None = None) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            span = f"{low}..{high}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"{text!r}: expected an integer {span}")
        return value

    return parse


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number > 0")
    return value


def output_file(text: str) -> str:
    """A file to write: its folder must exist; it must not be a folder."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a directory, expected a file to write")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: cannot write it: no directory {path.parent}")
    return text


def existing_dir(text: str) -> str:
    if not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"{text}: no such directory")
    return text


@contextmanager
def writing(option: str, path: str) -> Iterator[None]:
    """Turn an OS error while ``path`` is written into one line naming ``option``."""
    try:
        yield
    except OSError as err:
        raise ConfigError(f"{option} {path}: cannot write it: {err}") from None
