"""The /diagnostics status of a node from plain values (no rclpy)."""

from __future__ import annotations

import ast
from pathlib import Path

from servo_axis.nodes.diagnostics import ERROR, OK, WARN, node_status, text
from servo_axis.wire.node_report import Fallback, NodeHealth


def test_a_clean_node_is_ok_with_its_state_first() -> None:
    status = node_status(NodeHealth("plant"), [("step", 12), ("mode", "lockstep")])
    assert status.level == OK and status.level_name == "OK"
    assert status.values == (
        ("step", "12"),
        ("mode", "lockstep"),
        ("rejected", "0"),
        ("fallbacks", "0"),
    )


def test_rejected_messages_and_strangers_warn_and_say_where() -> None:
    health = NodeHealth(
        "feedback",
        rejected={"state": 3, "reference": 1},
        strangers={"state": ["/junk 0123456789abcdef"]},
    )
    status = node_status(health, [("tripped", False)])
    assert status.level == WARN
    assert status.message == "4 messages rejected (1 reference, 3 state); 1 strangers on state"
    values = dict(status.values)
    assert values["rejected"] == "4" and values["rejected state"] == "3"
    assert values["rejected reference"] == "1" and values["tripped"] == "false"
    assert values["strangers state"] == "/junk 0123456789abcdef"


def test_a_trip_or_a_fallback_is_an_error_that_names_it() -> None:
    tripped = node_status(NodeHealth("feedback"), error="tripped: following_error, zero current")
    assert tripped.level == ERROR and tripped.message.startswith("tripped: following_error")
    health = NodeHealth("plant", rejected={"command": 2})
    health.fallbacks.append(Fallback("command_timeout", 41, "the feedback is gone"))
    status = node_status(health)
    assert status.level == ERROR
    assert status.message == "fallback command_timeout at step 41; 2 messages rejected (2 command)"
    assert dict(status.values)["fallback"] == "command_timeout at step 41: the feedback is gone"


def test_values_are_text_in_full_precision() -> None:
    assert text(0.1 + 0.2) == "0.30000000000000004"
    assert text(True) == "true" and text(7) == "7"


def test_the_module_imports_no_ros_at_module_level() -> None:
    """Only :func:`diagnostic_array` imports the message classes, when called."""
    import servo_axis.nodes.diagnostics as mod

    tree = ast.parse(Path(mod.__file__).read_text())
    top = set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            top.add((node.module or "").split(".")[0])
        elif isinstance(node, ast.Import):
            top.update(a.name.split(".")[0] for a in node.names)
    assert top <= {"__future__", "collections", "dataclasses", "typing", "servo_axis"}
