"""``--external-timeout`` counts from when the run's own nodes are up, not the runner's start."""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from types import SimpleNamespace

import pytest

from servo_axis.run import watch
from servo_axis.run.watch import OutsideWait


@dataclass
class Plan:
    namespace: str = "/x"
    outside: tuple[str, ...] = ("feedback",)
    started: list[str] = field(default_factory=lambda: ["plant", "feedforward", "recorder"])

    def presence(self, role: str) -> str:
        return {"feedback": "/x/command"}[role]

    def where(self, role: str) -> str:
        return role


@dataclass
class Watcher:
    """What the runner's progress watcher saw: who reported on /diagnostics, who publishes."""

    reported: set[str] = field(default_factory=set)
    publishers: int = 0

    def endpoints(self, topic: str) -> tuple[int, int]:
        assert topic == "/x/command"
        return self.publishers, 1


@dataclass
class Axis:
    plan: Plan = field(default_factory=Plan)
    watcher: Watcher = field(default_factory=Watcher)

    def where(self, role: str) -> str:
        return role


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The watch's clock, set by the test."""
    now = [1000.0]
    monkeypatch.setattr(watch, "time", SimpleNamespace(monotonic=lambda: now[0]))
    return now


def test_the_timeout_starts_once_every_node_the_run_started_has_reported(
    clock: list[float],
) -> None:
    axis = Axis()
    out = io.StringIO()
    wait = OutsideWait([axis], timeout_s=2.0, out=out)  # type: ignore[list-item]
    # A slow start-up, far longer than the timeout: not the outside node's time.
    for up in ("/x/plant", "/x/feedforward"):
        clock[0] += 30.0
        axis.watcher.reported.add(up)
        assert not wait.arrived() and not wait.counting and wait.failure() is None
    assert "(the run's own nodes still starting)" in out.getvalue()
    clock[0] += 30.0
    axis.watcher.reported.add("/x/recorder")  # its first status: the bag is open
    assert not wait.arrived() and wait.counting and wait.t0 == clock[0]
    clock[0] += 2.0
    assert wait.failure() is None  # 2 s of 2 s
    clock[0] += 0.01
    assert wait.failure() == (
        "the outside node did not come within --external-timeout 2 s: "
        "feedback (no publisher on /x/command)"
    )


def test_an_outside_node_that_comes_within_the_timeout_ends_the_wait(clock: list[float]) -> None:
    axis = Axis()
    axis.watcher.reported.update({"/x/plant", "/x/feedforward", "/x/recorder"})
    wait = OutsideWait([axis], timeout_s=2.0, out=None)  # type: ignore[list-item]
    assert not wait.arrived() and wait.counting
    clock[0] += 1.5
    axis.watcher.publishers = 1
    assert wait.arrived() and wait.missing == []
