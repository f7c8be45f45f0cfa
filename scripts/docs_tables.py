"""MkDocs hook (``mkdocs.yml``: ``hooks:``): a table's names wrap between their words only.

The theme lets code break anywhere (``word-break: break-word``), so a table
sizes a column of names (parameter keys, topics, options) as if any letter
could start a line: on the parameters page the key column shrank to a few
letters and split ``wait_for_producers`` as ``wait_for_p roducers``. This
hook lets the code of a table's cells break only after a ``_``, ``.``,
``/`` or ``:`` (a ``<wbr>`` there), and ``docs/stylesheets/extra.css``
keeps the theme from breaking it elsewhere: a column is then at least as
wide as the longest word of its names, and a name that does not fit wraps
at a word's end (``wait_for_`` / ``producers``).
"""

from __future__ import annotations

import re
from typing import Any

#: A table cell, as Python-Markdown writes it, and the code in it.
_CELL = re.compile(r"<td[^>]*>.*?</td>", re.DOTALL)
_CODE = re.compile(r"(<code>)([^<]+)(</code>)")
#: Where a name may break: after each of these.
_BREAK_AFTER = re.compile(r"(?<=[_./:])(?=[^_./:])")


def breakable(name: str) -> str:
    """``name`` (HTML text) with a ``<wbr>`` after each ``_``, ``.``, ``/`` or ``:`` inside it."""
    return _BREAK_AFTER.sub("<wbr>", name)


def wrap_names(html: str) -> str:
    """``html`` with the code of every table cell made :func:`breakable`."""

    def cell(m: re.Match[str]) -> str:
        return _CODE.sub(lambda c: c.group(1) + breakable(c.group(2)) + c.group(3), m.group(0))

    return _CELL.sub(cell, html)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    return wrap_names(html)
