"""The runner stops a run whose outside plant left the graph before the end (issue 31; no ROS)."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import pytest

from servo_axis.run import watch
from servo_axis.run.state import RunState
from servo_axis.run.watch import OutsidePlantGone


@dataclass
class Plan:
    outside: tuple[str, ...] = ("plant",)

    def presence(self, role: str) -> str:
        return {"plant": "state"}[role]


@dataclass
class Watcher:
    publishers: int = 1

    def endpoints(self, topic: str) -> tuple[int, int]:
        assert topic == "state"
        return self.publishers, 2


@dataclass
class Axis:
    plan: Plan = field(default_factory=Plan)
    watcher: Watcher = field(default_factory=Watcher)
    plant_done: bool = False

    def where(self, role: str) -> str:
        return role


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The watch's clock, set by the test: a busy host cannot stretch a grace."""
    now = [1000.0]
    monkeypatch.setattr(watch, "time", SimpleNamespace(monotonic=lambda: now[0]))
    return now


def test_a_plant_gone_before_the_end_stops_the_run_after_the_grace(clock: list[float]) -> None:
    axis = Axis()
    check = OutsidePlantGone([axis], grace_s=0.05)  # type: ignore[list-item]
    state = RunState(steps=120)
    assert check.failure(state) is None  # there
    axis.watcher.publishers = 0
    assert check.failure(state) is None  # gone, within the grace
    clock[0] += 0.04
    assert check.failure(state) is None  # still within it
    clock[0] += 0.02
    reason = check.failure(state)
    assert reason == "the outside plant is gone (no publisher on state) at step 120"


def test_a_plant_not_yet_there_or_done_or_back_is_no_failure(clock: list[float]) -> None:
    never = Axis(watcher=Watcher(publishers=0))
    done, back = Axis(), Axis()
    check = OutsidePlantGone([never, done, back], grace_s=0.0)  # type: ignore[list-item]
    state: Any = RunState(steps=5)
    assert check.failure(state) is None
    done.watcher.publishers, done.plant_done = 0, True
    back.watcher.publishers = 0
    check.failure(state)  # back seen gone ...
    back.watcher.publishers = 1
    clock[0] += 0.01
    assert check.failure(state) is None  # ... and back: never seen gone long enough


def test_a_suite_plant_is_not_watched() -> None:
    assert OutsidePlantGone([Axis(plan=Plan(outside=()))]).axes == []  # type: ignore[list-item]
