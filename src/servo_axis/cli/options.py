"""What every command of the command line shares: the parser, the option types, file errors.

Every bad option is one line on stderr and exit 2 (:class:`Parser`): the
types here refuse a value with the words argparse puts after
``error: argument --option:``.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import ClassVar, NoReturn, TypeAlias

from servo_axis.core.errors import ConfigError, closest, did_you_mean
from servo_axis.params.names import domain_id_problem, namespace_problem

#: The shipped scenario ``python -m servo_axis`` runs.
DEFAULT_SCENARIO = "rptc_friction_table"

#: What a command module's ``add_parser`` is given: the top-level parser's subparsers.
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


#: argparse's words for a value not among the choices (a command, ``--model``).
_INVALID_CHOICE = re.compile(r"^(argument .+?: invalid choice: '(.*?)') \(choose from (.*)\)$")


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2).

    A value not among the choices gets the closest one (``runn``: did you
    mean 'run'?); an option the command does not have gets the closest of
    its options, or the commands that have it (``--domain-id`` is an option
    of ``run``); ``run`` adds what a key of the scenario would be
    (``--duration``: ``--set shared.duration_s=...``, :data:`option_hints`).
    """

    #: Per command, a function from an option it does not have to a hint ("" for none).
    option_hints: ClassVar[dict[str, Callable[[str], str]]] = {}
    #: Per command, what to say of an argument more than it takes.
    extra_hints: ClassVar[dict[str, str]] = {}

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())
        choice = _INVALID_CHOICE.match(text)
        if choice is not None:
            head, value, listed = choice.groups()
            hint = did_you_mean(value, re.findall(r"'([^']*)'", listed))
            text = f"{head}; {hint} (choose from {listed})" if hint else text
        self.exit(2, f"error: {text} (see {self.prog} --help)\n")

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        given = list(sys.argv[1:] if args is None else args)
        if (
            self._subcommands()
            and given
            and given[0].startswith("-")
            and given[0]
            not in (
                "-h",
                "--help",
            )
        ):
            self.error(_misplaced(self, given[0].partition("=")[0], None))
        return super().parse_known_args(given, namespace)

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            command = getattr(parsed, "command", None)
            options = [e.partition("=")[0] for e in extras if e.startswith("-")]
            where = self._subcommands().get(command) if command else None
            hint = _misplaced(self, options[0], command, where) if options else ""
            if not options and command:
                hint = Parser.extra_hints.get(command, "")
            text = f"unrecognized arguments: {' '.join(extras)}"
            if hint:
                text += f" ({hint})"
            (where or self).error(text)
        return parsed

    def _subcommands(self) -> dict[str, argparse.ArgumentParser]:
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return dict(action.choices)
        return {}


def _options(parser: argparse.ArgumentParser) -> list[str]:
    """The long options of ``parser`` and of its own subcommands (``bag recover``)."""
    found = [o for a in parser._actions for o in a.option_strings if o.startswith("--")]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found += _options(sub)
    return found


def _closest_option(option: str, options: list[str]) -> str | None:
    """The option of ``options`` most like ``option``, compared without the dashes; None if none is."""
    by_name = {o.lstrip("-"): o for o in options if o != "--help"}
    found = closest(option.lstrip("-"), by_name)
    return by_name[found[0]] if found else None


def _misplaced(
    root: Parser,
    option: str,
    command: str | None,
    parser: argparse.ArgumentParser | None = None,
) -> str:
    """What an option that ``command`` (None: the command line itself) does not have may be."""
    if parser is not None and command is not None:
        close = _closest_option(option, _options(parser))
        if close:
            return f"did you mean {close}?"
        hint = Parser.option_hints.get(command)
        extra = hint(option) if hint else ""
        if extra:
            return extra
    owners = [name for name, sub in root._subcommands().items() if option in _options(sub)]
    if owners and command is None:
        return (
            f"{option} is an option of {' and '.join(owners)}, not of {root.prog} itself: "
            f"{root.prog} {owners[0]} ... {option} ..."
        )
    if owners:
        return f"{option} is an option of {' and '.join(owners)}, not of {command}"
    if command is None:
        every: dict[str, list[str]] = {}
        for name, sub in root._subcommands().items():
            for o in _options(sub):
                every.setdefault(o, []).append(name)
        near = _closest_option(option, list(every))
        return f"{root.prog} takes a command first; no command has the option {option}" + (
            f" (did you mean {near}, an option of {' and '.join(every[near])}?)" if near else ""
        )
    return ""


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


def override(text: str) -> object:
    """A ``--set SECTION.KEY=VALUE`` (:func:`servo_axis.params.overrides.parse_override`)."""
    from servo_axis.params.overrides import parse_override

    try:
        return parse_override(text)
    except ConfigError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


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
