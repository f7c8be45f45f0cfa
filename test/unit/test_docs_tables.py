"""The site's tables: names wrap between their words only (scripts/docs_tables.py).

Checked in a browser (headless Chromium, 1280 px): on the parameters page 178
of its 242 keys were split inside a word before (``wait_for_p roducers``),
none after, and no table of the site got wider than its page. Here: where
the hook lets a name break, and that the site uses it.
"""

from __future__ import annotations

import re
import runpy
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
HOOK = runpy.run_path(str(REPO / "scripts" / "docs_tables.py"))

ROW = (
    "<table>\n<thead>\n<tr>\n<th>parameter</th>\n<th>meaning</th>\n</tr>\n</thead>\n<tbody>\n"
    "<tr>\n<td><code>wait_for_producers</code></td>\n"
    "<td>see <code>plant/status</code> and <code>a.b:c</code></td>\n</tr>\n</tbody>\n</table>\n"
    "<p>Outside a table <code>wait_for_producers</code> stays as it is.</p>"
)


def text_of(html: str) -> str:
    return re.sub(r"<[^>]+>", "", html)


def test_a_name_may_break_only_after_a_separator() -> None:
    assert HOOK["breakable"]("wait_for_producers") == "wait_<wbr>for_<wbr>producers"
    assert HOOK["breakable"]("nominal.torque_constant_Nm_per_A") == (
        "nominal.<wbr>torque_<wbr>constant_<wbr>Nm_<wbr>per_<wbr>A"
    )
    assert HOOK["breakable"]("servo_axis.plugins.ilc:PILC_BF") == (
        "servo_<wbr>axis.<wbr>plugins.<wbr>ilc:<wbr>PILC_<wbr>BF"
    )
    # No break before a name's first letter or after its last, none between two separators.
    assert HOOK["breakable"]("_private") == "_<wbr>private"
    assert HOOK["breakable"]("/diagnostics") == "/<wbr>diagnostics"
    assert HOOK["breakable"]("a__b_") == "a__<wbr>b_"


def test_the_code_of_table_cells_gets_the_breaks_and_nothing_else_changes() -> None:
    out = HOOK["wrap_names"](ROW)
    assert "<td><code>wait_<wbr>for_<wbr>producers</code></td>" in out
    assert "<code>plant/<wbr>status</code>" in out and "<code>a.<wbr>b:<wbr>c</code>" in out
    assert "<p>Outside a table <code>wait_for_producers</code> stays as it is.</p>" in out
    assert text_of(out) == text_of(ROW)  # what the page says is the same


def test_the_site_uses_the_hook_and_the_style() -> None:
    class Loader(yaml.SafeLoader):
        pass

    Loader.add_multi_constructor("!", lambda loader, suffix, node: None)  # !!python/name etc.
    config = yaml.load((REPO / "mkdocs.yml").read_text(), Loader=Loader)
    assert "scripts/docs_tables.py" in config["hooks"]
    assert config["extra_css"] == ["stylesheets/extra.css"]
    css = (REPO / "docs" / "stylesheets" / "extra.css").read_text()
    # The theme's break-anywhere is undone for the code of table cells.
    assert re.search(r"table:not\(\[class\]\) td code \{\s*word-break: normal;", css)
