"""The rclpy context of the in-process ROS tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
from rclpy.context import Context


@pytest.fixture
def context(ros_env: int) -> Iterator[Context]:
    """An initialised rclpy context in the test's own ROS domain, shut down after."""
    ctx = Context()
    rclpy.init(args=[], context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)
