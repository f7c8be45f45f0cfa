"""The analysis package and identify.friction import neither rclpy nor a ROS message package."""

from __future__ import annotations

import json
import subprocess
import sys

ROS_PACKAGES = (
    "rclpy",
    "rpyutils",
    "rosidl_runtime_py",
    "rosidl_parser",
    "builtin_interfaces",
    "std_msgs",
    "sensor_msgs",
    "rosgraph_msgs",
)

PROBE = """
import importlib, json, pkgutil, sys
import servo_axis.analysis as analysis
names = [f"servo_axis.analysis.{m.name}" for m in pkgutil.iter_modules(analysis.__path__)]
names.append("servo_axis.identify.friction")
for name in names:
    importlib.import_module(name)
print(json.dumps({"imported": names, "modules": sorted(sys.modules)}))
"""


def test_analysis_modules_do_not_import_ros() -> None:
    out = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, check=True, timeout=120
    )
    result = json.loads(out.stdout)
    assert set(result["imported"]) >= {
        "servo_axis.analysis.signals",
        "servo_axis.analysis.metrics",
        "servo_axis.analysis.summary",
        "servo_axis.analysis.text",
        "servo_axis.analysis.plots",
        "servo_axis.identify.friction",
    }
    modules = result["modules"]
    assert "rclpy" not in modules
    ros = [m for m in modules if m.split(".")[0] in ROS_PACKAGES or m.endswith("_msgs")]
    assert ros == []
