"""``params [NAME]``: the keys of what is installed, from the schemas the nodes check."""

from __future__ import annotations

import re

import pytest

from servo_axis.__main__ import main
from servo_axis.params import schemas
from servo_axis.params.registry import FEEDFORWARD_TERMS, PLANT_MODELS


def rows(text: str) -> dict[str, list[str]]:
    """The key rows of the output: key -> its cells (split on runs of 2+ spaces)."""
    out = {}
    for line in text.splitlines():
        if line.startswith("  ") and not line.startswith("  parameter "):
            cells = re.split(r" {2,}", line.strip())
            out[cells[0]] = cells
    return out


def test_an_extension_s_keys_with_default_unit_range_and_meaning(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["params", "friction_table"]) == 0
    text = capsys.readouterr().out
    head = text.splitlines()[0]
    assert head == "feedforward (term friction_table)  [servo_axis.plugins.friction_table:TERM]"
    schema = FEEDFORWARD_TERMS["friction_table"].schema
    got = rows(text)
    assert list(got) == list(schema)
    for key, param in schema.items():
        cells = got[key]
        assert cells[1] == repr(param.default) and cells[-1] == param.meaning


def test_a_node_gives_its_own_keys_then_each_installed_extension_s(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["params", "plant"]) == 0
    text = capsys.readouterr().out
    heads = [line for line in text.splitlines() if line and not line.startswith(" ")]
    assert heads[0] == "plant node"
    # (with ", <distribution>" after the entry point of one installed beside the suite)
    assert len(heads) == 1 + len(PLANT_MODELS)
    for head, name in zip(heads[1:], sorted(PLANT_MODELS), strict=True):
        assert head.startswith(f"plant (model {name})  [{PLANT_MODELS.source(name)}")
    blocks = text.split("\n\n")
    assert list(rows(blocks[0])) == list(schemas.PLANT)
    first = sorted(PLANT_MODELS)[0]
    assert list(rows(blocks[1])) == list(PLANT_MODELS[first].schema)
    param = PLANT_MODELS[first].schema["torque_constant_Nm_per_A"]
    cells = rows(blocks[1])["torque_constant_Nm_per_A"]
    assert cells[1:4] == [repr(param.default), "N m/A", param.range_text()]


def test_an_unknown_name_is_one_line_with_the_closest(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "fricton_table"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("error: params fricton_table: neither a node nor an installed extension")
    assert "did you mean 'friction_table'?" in err and "ball_screw" in err
