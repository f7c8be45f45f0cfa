"""The recording modules that rclpy-free code uses do not import ROS."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import servo_axis.recording as recording
from servo_axis.recording import writer

ROS_MODULES = ("rclpy", "rosidl", "sensor_msgs", "std_msgs", "builtin_interfaces", "rosgraph_msgs")
PACKAGE = Path(recording.__file__).parent


def imports(path: Path, *, top_level_only: bool) -> list[str]:
    """Modules imported by a source file (relative imports as ``.name``)."""
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    out = []
    for node in nodes:
        if isinstance(node, ast.Import):
            out.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            out.append("." * node.level + (node.module or ""))
    return out


def is_ros(module: str) -> bool:
    return module.split(".")[0].startswith(ROS_MODULES)


def test_reader_imports_only_yaml_mcap_and_errors_anywhere() -> None:
    allowed_third_party = {"yaml", "mcap"}
    allowed_own = {"servo_axis.core.errors", "servo_axis.recording.errors"}
    for module in imports(PACKAGE / "reader.py", top_level_only=False):
        top = module.split(".")[0]
        assert (
            module in allowed_own
            or top in allowed_third_party
            or top in sys.stdlib_module_names
            or module == "__future__"
        ), f"reader.py imports {module}"


@pytest.mark.parametrize("name", ["writer.py", "definitions.py", "errors.py", "deserialize.py"])
def test_no_ros_import_at_module_level(name: str) -> None:
    assert [m for m in imports(PACKAGE / name, top_level_only=True) if is_ros(m)] == []


def test_reading_raw_loads_no_ros_module(tmp_path: Path) -> None:
    with writer.BagWriter(tmp_path / "b") as bag:
        bag.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        bag.write("/clock", b"\x00\x01\x00\x00" + bytes(8), log_time_ns=5)
    script = f"""
import json, sys
import servo_axis.recording
from servo_axis.recording.reader import read_raw
got = [(m.topic, m.type_name, m.log_time_ns, m.data.hex()) for m in read_raw({str(tmp_path / "b")!r})]
print(json.dumps([got, sorted(sys.modules)]))
"""
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    got, modules = json.loads(result.stdout)
    assert got == [["/clock", "rosgraph_msgs/msg/Clock", 5, "000100000000000000000000"]]
    assert [m for m in modules if is_ros(m)] == []


def test_the_package_imports_none_of_its_modules() -> None:
    """Importing ``servo_axis.recording`` must not drag the rclpy reader into ROS-free code."""
    tree = ast.parse((PACKAGE / "__init__.py").read_text())
    assert not [n for n in ast.walk(tree) if isinstance(n, ast.Import | ast.ImportFrom)]
    assert not (PACKAGE / "bag.py").exists()
