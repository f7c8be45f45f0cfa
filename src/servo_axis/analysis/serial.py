"""One serialiser for the summary's dataclasses (``summary.json`` and its blocks).

:func:`to_dict` turns a dataclass into JSON-ready values and
:func:`from_dict` reads them back, both driven by :func:`dataclasses.fields`
and the fields' type hints: nested dataclasses, tuples and lists of them,
dicts (``dict[str, X]``), ``X | None`` and plain values. :class:`Serial`
gives a dataclass the methods ``to_dict()`` / ``from_dict()``.

The layout is the one ``summary.json`` has always had:

* a mapping per dataclass, keys in field order;
* tuples and lists as lists, dicts as dicts (their order kept);
* a field with ``metadata={"summary": False}`` is not written (series that
  are not part of the summary) and not read;
* a field with ``metadata={"omit_none": True}`` is not written while it is
  None; missing, it reads as its default.

A dataclass may rename its keys: a method ``serial_out(self, mapping) ->
mapping`` is applied to what is written, a classmethod ``serial_in(cls,
mapping) -> mapping`` to what is read before the fields are (a rotary run's
summary writes its errors as ``rms_rad``, ``max_rad``:
:class:`~servo_axis.analysis.summary.RunSummary`).

Reading: a key that is missing takes the field's default, else the field's
``metadata["missing"]`` (an older file's layout: a key added later), else it
is a :class:`KeyError` naming the key. A field declared ``int`` or ``float``
(not ``bool``) is converted to that type, so a hand-written ``1`` reads as
``1.0`` for a float; any other value is taken as it is (``Any``, ``str``,
``bool``).

This module imports nothing of the project (numpy neither): the standard
library only.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Mapping
from typing import Any, Self, TypeVar

T = TypeVar("T")

#: The ``metadata`` keys this module reads.
OMIT_NONE = "omit_none"
SUMMARY = "summary"
MISSING = "missing"


def to_plain(obj: Any) -> Any:
    """A value as JSON-ready values: dataclasses as mappings in field order, tuples as lists.

    A field with ``metadata={"summary": False}`` is left out; one with
    ``metadata={"omit_none": True}`` is left out while it is None. Any other
    value (str, int, float, bool, None) is returned as it is.
    """
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {}
        for f in dataclasses.fields(obj):
            if not f.metadata.get(SUMMARY, True):
                continue
            value = getattr(obj, f.name)
            if value is None and f.metadata.get(OMIT_NONE, False):
                continue
            out[f.name] = to_plain(value)
        rename = getattr(obj, "serial_out", None)
        return rename(out) if callable(rename) else out
    if isinstance(obj, tuple | list):
        return [to_plain(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_plain(v) for k, v in obj.items()}
    return obj


def to_dict(obj: Any) -> dict[str, Any]:
    """The mapping of a dataclass instance, as written in ``summary.json``.

    Raises
    ------
    TypeError
        If ``obj`` is not a dataclass instance.
    """
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise TypeError(f"to_dict: expected a dataclass instance, got {type(obj).__name__}")
    plain: dict[str, Any] = to_plain(obj)
    return plain


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """The resolved type hints of a dataclass (its module's names; cached per class)."""
    return typing.get_type_hints(cls)


def _convert(hint: Any, value: Any, where: str) -> Any:
    """``value`` (JSON-ready) as the type ``hint`` says."""
    if hint is Any:
        return value
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin is typing.Union or origin is types.UnionType:
        if value is None and type(None) in args:
            return None
        others = [a for a in args if a is not type(None)]
        if len(others) != 1:
            raise TypeError(f"{where}: cannot read a union of {others}")
        return _convert(others[0], value, where)
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        if not isinstance(value, Mapping):
            raise TypeError(f"{where}: expected a mapping, got {type(value).__name__}")
        return from_dict(hint, value)
    if origin is tuple:
        item = args[0] if len(args) == 2 and args[1] is Ellipsis else None
        if not isinstance(value, list | tuple):
            raise TypeError(f"{where}: expected a list, got {type(value).__name__}")
        if item is None:
            return tuple(
                _convert(a, v, f"{where}[{i}]")
                for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        return tuple(_convert(item, v, f"{where}[{i}]") for i, v in enumerate(value))
    if origin is list:
        if not isinstance(value, list | tuple):
            raise TypeError(f"{where}: expected a list, got {type(value).__name__}")
        return [_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, Mapping):
            raise TypeError(f"{where}: expected a mapping, got {type(value).__name__}")
        item_hint = args[1] if args else Any
        return {k: _convert(item_hint, v, f"{where}.{k}") for k, v in value.items()}
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if hint is int and isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def from_dict(cls: type[T], data: Mapping[str, Any]) -> T:
    """The dataclass ``cls`` from its mapping (the inverse of :func:`to_dict`).

    Parameters
    ----------
    cls : type
        A dataclass.
    data : Mapping
        Its mapping, as :func:`to_dict` writes it (or an older layout: keys
        added since are read as their default or ``metadata["missing"]``).
        Keys that are not fields are ignored.

    Raises
    ------
    KeyError
        A key without default is missing (the key's name).
    TypeError
        A value is not what its field holds (the message names the field).
    """
    if not (dataclasses.is_dataclass(cls) and isinstance(cls, type)):
        raise TypeError(f"from_dict: expected a dataclass, got {cls!r}")
    if not isinstance(data, Mapping):
        raise TypeError(f"{cls.__name__}: expected a mapping, got {type(data).__name__}")
    rename = getattr(cls, "serial_in", None)
    if callable(rename):
        data = rename(data)
    hints = _hints(cls)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if not f.init or not f.metadata.get(SUMMARY, True):
            continue
        if f.name in data:
            values[f.name] = _convert(hints[f.name], data[f.name], f"{cls.__name__}.{f.name}")
        elif f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING:
            continue
        elif MISSING in f.metadata:
            values[f.name] = f.metadata[MISSING]
        else:
            raise KeyError(f.name)
    return cls(**values)


class Serial:
    """``to_dict()`` and ``from_dict()`` of a dataclass by :func:`to_dict` / :func:`from_dict`."""

    __slots__ = ()

    def to_dict(self) -> dict[str, Any]:
        """As in ``summary.json``, keys in field order."""
        return to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """Inverse of :meth:`to_dict`."""
        return from_dict(cls, data)
