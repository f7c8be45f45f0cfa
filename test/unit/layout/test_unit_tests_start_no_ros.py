"""No test in test/unit starts ROS: scripts/test.sh runs them beside the `shm` tests.

Those count the Fast DDS files in /dev/shm that a killed participant left;
a unit test's own ROS run beside them would add files of its own (and a
test that needs ROS belongs in test/ros or test/integration anyway).
"""

from __future__ import annotations

import re
from pathlib import Path

UNIT = Path(__file__).resolve().parents[1]
#: The fixtures that give a test a ROS domain (test/conftest.py), and rclpy's own start.
STARTS_ROS = re.compile(r"\b(ros_env|module_ros_env)\b|rclpy\.init\(|create_node\(")


def test_no_unit_test_takes_a_ros_domain_or_starts_rclpy() -> None:
    files = sorted(UNIT.rglob("*.py"))
    assert len(files) > 50
    found = {
        str(f.relative_to(UNIT)): sorted({m.group(0) for m in STARTS_ROS.finditer(f.read_text())})
        for f in files
        if f != Path(__file__) and STARTS_ROS.search(f.read_text())
    }
    assert found == {}


def test_the_pattern_finds_what_it_looks_for() -> None:
    for text in ("def test_x(ros_env: int)", "rclpy.init(args=[])", "rclpy.create_node('n')"):
        assert STARTS_ROS.search(text), text
    assert not STARTS_ROS.search("env = ros_environment(42, log_dir)")
