"""The Python source of the value classes of schemas (what ``scripts/typed_values.py`` writes).

:func:`render` turns :class:`Spec` s (a class name, its base, the keys it
adds) into the text of modules of frozen dataclasses, one attribute per key
and one class per group of keys, as :func:`servo_axis.params.typed.derive`
makes them at run time: a key of a group the base has extends that group's
class (a subclass), any other key is a field, and a group whose keys (the
same :class:`~servo_axis.params.param.Param` objects) several classes share
is one class. Each field carries its key's unit and range
(``dataclasses.field(metadata=...)``) and, in its docstring, the key, unit,
range and meaning. Nothing here imports rclpy.
"""

from __future__ import annotations

import json
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from servo_axis.params.param import Param
from servo_axis.params.typed import RESERVED, Tree, attribute, camel, leaf_type, nest, range_text


@dataclass(frozen=True)
class Spec:
    """One value class to write.

    Attributes
    ----------
    name : str
        Its name (``FeedbackValues``).
    base : str
        Its base: ``Values`` or the name of a spec written before it.
    schema : mapping of str to Param
        The keys it adds to its base.
    doc : str
        Its docstring's first line.
    module : str
        Which of the modules written it goes in.
    owner : str
        The stem of its groups' class names (``Feedback``: ``FeedbackDob``).
    """

    name: str
    base: str
    schema: Mapping[str, Param]
    doc: str
    module: str
    owner: str


@dataclass
class _Class:
    """A class of the modules written: a spec's, or a group's."""

    name: str
    bases: tuple[str, ...]
    module: str
    doc: str
    #: attribute -> (key part, Param) or (key part, group class name)
    fields: dict[str, tuple[str, Param | str]] = field(default_factory=dict)
    key_path: str = ""
    owners: list[str] = field(default_factory=list)


#: The module of :class:`~servo_axis.params.typed.Values` and ``Group``.
TYPED = "servo_axis.params.typed"


@dataclass(frozen=True)
class Module:
    """One module to write: its dotted name and its docstring."""

    name: str
    doc: str


def render(modules: Sequence[Module], specs: Sequence[Spec]) -> dict[str, str]:
    """The text of each module of ``modules`` (by name) holding the classes of ``specs``.

    Raises
    ------
    ValueError
        For a key no attribute can name, a key that clashes with the base's
        (a value and a group), or two group classes given the same name.
    """
    classes: dict[str, _Class] = {
        "Values": _Class("Values", (), TYPED, ""),
        "Group": _Class("Group", (), TYPED, ""),
    }
    order: list[str] = []
    groups: dict[tuple[object, ...], str] = {}  # content -> provisional name
    for spec in specs:
        base = classes[spec.base]
        cls = _Class(spec.name, (spec.base,), spec.module, spec.doc)
        classes[spec.name] = cls
        _fill(cls, _all_fields(classes, base), nest(spec.schema), spec, "", classes, order, groups)
        order.append(spec.name)
    _name_groups(classes, order)
    out = {}
    for module in modules:
        names = [n for n in order if classes[n].module == module.name]
        out[module.name] = _module_text(module, [classes[n] for n in names], classes)
    return out


def _all_fields(classes: dict[str, _Class], cls: _Class) -> dict[str, tuple[str, Param | str]]:
    """Every field of ``cls``, its bases' first (a subclass's own override theirs)."""
    out: dict[str, tuple[str, Param | str]] = {}
    for base in cls.bases:
        out.update(_all_fields(classes, classes[base]))
    out.update(cls.fields)
    return out


def _fill(
    cls: _Class,
    inherited: dict[str, tuple[str, Param | str]],
    tree: Tree,
    spec: Spec,
    path: str,
    classes: dict[str, _Class],
    order: list[str],
    groups: dict[tuple[object, ...], str],
) -> None:
    for part, sub in tree.items():
        attr = attribute(part)
        key_path = f"{path}{part}"
        have = inherited.get(attr)
        if isinstance(sub, Param):
            if have is not None:
                raise ValueError(f"key {key_path!r}: given twice, or as a key and as a group")
            cls.fields[attr] = (part, sub)
            continue
        if have is not None and isinstance(have[1], Param):
            raise ValueError(f"key {key_path!r}: a key of its own in the base, a group here")
        bases = (have[1],) if have is not None else ()
        assert all(isinstance(b, str) for b in bases)
        content = (bases, key_path, _identity(sub))
        if content in groups:
            name = groups[content]
        else:
            name = f"_group{len(groups)}"
            groups[content] = name
            own_bases = tuple(str(b) for b in bases) or ("Group",)
            group = _Class(name, own_bases, spec.module, "", key_path=key_path)
            classes[name] = group
            base_fields = _all_fields(classes, classes[own_bases[0]])
            _fill(group, base_fields, sub, spec, f"{key_path}.", classes, order, groups)
            order.append(name)
        classes[name].owners.append(spec.owner)
        cls.fields[attr] = (part, name)


def _identity(tree: Tree) -> tuple[object, ...]:
    """What makes two groups the same class: their keys and the very Param objects."""
    return tuple(
        (part, id(sub) if isinstance(sub, Param) else _identity(sub)) for part, sub in tree.items()
    )


def _name_groups(classes: dict[str, _Class], order: list[str]) -> None:
    """Name each group class ``<Path>Keys``, the path qualified by its owner unless several share it."""
    renames: dict[str, str] = {}
    for provisional in [n for n in order if n.startswith("_group")]:
        group = classes[provisional]
        stem = camel(group.key_path)
        owners = sorted(set(group.owners))
        if len(owners) > 1:
            name = stem + "Keys"
        else:
            name = (stem if stem.startswith(owners[0]) else owners[0] + stem) + "Keys"
        if name in renames.values() or (name in classes and not name.startswith("_group")):
            raise ValueError(f"group {group.key_path!r}: class name {name!r} is taken")
        renames[provisional] = name
    for cls in classes.values():
        cls.bases = tuple(renames.get(b, b) for b in cls.bases)
        cls.fields = {
            attr: (part, renames.get(v, v) if isinstance(v, str) else v)
            for attr, (part, v) in cls.fields.items()
        }
    for old, new in renames.items():
        group = classes.pop(old)
        group.name = new
        classes[new] = group
        order[order.index(old)] = new
        if not group.doc:
            group.doc = f"The ``{group.key_path}.*`` keys."
    assert not RESERVED & set(renames.values())


def _type_text(param: Param) -> str:
    hint = leaf_type(param)
    if isinstance(param.default, list):
        return f"tuple[{hint.__args__[0].__name__}, ...]"
    return str(hint.__name__)


def _field_text(attr: str, part: str, value: Param | str, key: str) -> list[str]:
    if isinstance(value, str):
        line = f"    {attr}: {value}"
        return [line + (f' = field(metadata={{"key": "{part}"}})' if part != attr else "")]
    items = [f'"unit": {_quoted(value.unit)}', f'"range": {_quoted(range_text(value))}']
    if part != attr:
        items.append(f'"key": {_quoted(part)}')
    metadata = ", ".join(items)
    head = f"    {attr}: {_type_text(value)} = field("
    lines = [f"{head}metadata={{{metadata}}})"]
    if len(lines[0]) > 100:
        lines = [head, f"        metadata={{{metadata}}}", "    )"]
    if len(lines) > 1 and len(lines[1]) > 100:
        lines = [
            head,
            "        metadata={",
            *(f"            {i}," for i in items),
            "        }",
            "    )",
        ]
    about = ", ".join(p for p in (value.unit, range_text(value)) if p)
    text = f"``{key}``" + (f" ({about})" if about else "") + f": {value.meaning}"
    body = textwrap.wrap(text.replace('"""', "'''"), width=92, break_on_hyphens=False)
    body[0] = '"""' + body[0]
    body[-1] += '"""'
    return [*lines, *(f"    {line}" for line in body)]


def _module_text(module: Module, own: list[_Class], classes: dict[str, _Class]) -> str:
    doc = module.doc.strip("\n")
    used = {
        name
        for cls in own
        for name in (*cls.bases, *(v for _, v in cls.fields.values() if isinstance(v, str)))
    }
    imports: dict[str, list[str]] = {}
    for name in sorted(used):
        where = classes[name].module
        if where != module.name:
            imports.setdefault(where, []).append(name)
    lines = ['"""' + doc + '\n"""', "", "from dataclasses import dataclass, field", ""]
    for where in sorted(imports):
        line = f"from {where} import {', '.join(sorted(imports[where]))}"
        if len(line) > 100:
            line = "\n".join(
                [f"from {where} import (", *(f"    {n}," for n in sorted(imports[where])), ")"]
            )
        lines.append(line)
    for cls in own:
        full_key = {attr: _key(cls, part) for attr, (part, _) in cls.fields.items()}
        lines += ["", "", "@dataclass(frozen=True, kw_only=True, eq=False)"]
        lines.append(f"class {cls.name}({', '.join(cls.bases)}):")
        lines.append(f'    """{cls.doc}"""')
        if cls.fields:
            lines.append("")
        for attr, (part, value) in cls.fields.items():
            lines += _field_text(attr, part, value, full_key[attr])
    return "\n".join(lines) + "\n"


def _quoted(text: str) -> str:
    """``text`` as a string literal in the formatter's style (double quotes)."""
    return json.dumps(text, ensure_ascii=False)


def _key(cls: _Class, part: str) -> str:
    return f"{cls.key_path}.{part}" if cls.key_path else part
