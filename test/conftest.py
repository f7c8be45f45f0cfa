"""Shared fixtures: an isolated ROS environment per test."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "config"

# Each test that touches ROS gets its own domain; the base depends on the pid
# so that two suites on one machine are unlikely to collide.
_domains = itertools.count()
_BASE = 10 + (os.getpid() % 9) * 10


def next_domain_id() -> int:
    return 10 + (_BASE - 10 + next(_domains)) % 90


@pytest.fixture
def ros_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[int]:
    """Distinct ROS_DOMAIN_ID, localhost discovery, UDP only, temporary ROS_LOG_DIR."""
    domain = next_domain_id()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("FASTDDS_BUILTIN_TRANSPORTS", "UDPv4")
    log_dir = tmp_path / "ros_log"
    log_dir.mkdir()
    monkeypatch.setenv("ROS_LOG_DIR", str(log_dir))
    yield domain
