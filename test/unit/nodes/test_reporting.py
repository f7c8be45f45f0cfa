"""A node's health report (``nodes.reporting.Reporter``), without ROS."""

from __future__ import annotations

import ast
from pathlib import Path
from types import SimpleNamespace

import pytest

from servo_axis.nodes import reporting
from servo_axis.nodes.diagnostics import ERROR, OK, WARN
from servo_axis.nodes.reporting import Reporter, Throttle
from servo_axis.wire.node_report import read_health


class Lines:
    """A logger that keeps what it is told."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.errors: list[str] = []

    def warning(self, message: str) -> None:
        self.warnings.append(message)

    def error(self, message: str) -> None:
        self.errors.append(message)


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The module's clock, set by the test, not the host's: a test process held back
    for a period between two calls must not make the second one a new period."""
    now = [100.0]
    monkeypatch.setattr(reporting, "time", SimpleNamespace(monotonic=lambda: now[0]))
    return now


def test_rejections_are_counted_per_topic_and_logged_at_most_once_a_second(
    clock: list[float],
) -> None:
    log = Lines()
    report = Reporter("feedback", report_dir=None, logger=log)
    for _ in range(3):
        report.reject("state", "state rejected: NaN")
    report.reject("reference", "reference rejected: stale stamp")
    assert report.rejected == 4
    assert report.health.rejected == {"state": 3, "reference": 1}
    assert log.warnings == ["state rejected: NaN (1 rejected so far)"]
    assert report.status().level == WARN


def test_the_throttle_lets_one_line_through_per_period(clock: list[float]) -> None:
    throttle = Throttle(period_s=0.25)
    assert throttle.ready() and not throttle.ready()
    clock[0] += 0.125
    assert not throttle.ready()
    clock[0] += 0.125  # a whole period after the last line (exact in binary)
    assert throttle.ready() and not throttle.ready()


def test_a_fallback_is_logged_as_an_error_and_written_at_once(tmp_path: Path) -> None:
    log = Lines()
    report = Reporter("plant", report_dir=tmp_path, logger=log)
    report.reject("command", "command rejected: future stamp")
    report.fallback("command_timeout", 41, "the feedback is gone")
    (line,) = log.errors
    assert line.startswith("FALLBACK (command_timeout) at step 41: the feedback is gone;")
    written = read_health(tmp_path)["plant"]
    assert [(f.kind, f.step, f.detail) for f in written.fallbacks] == [
        ("command_timeout", 41, "the feedback is gone")
    ]
    assert written.rejected == {"command": 1} and not written.deterministic
    assert report.status().level == ERROR


def test_strangers_are_recorded_and_written_when_asked(tmp_path: Path) -> None:
    log = Lines()
    report = Reporter("feedback", report_dir=tmp_path, logger=log)
    report.stranger("state", "/junk 0123456789abcdef", "/x/plant")
    assert report.health.strangers == {"state": ["/junk 0123456789abcdef"]}
    assert "stranger publishing on state: /junk 0123456789abcdef" in log.warnings[0]
    assert "(the run declared only /x/plant)" in log.warnings[0]
    assert read_health(tmp_path) == {}  # the caller writes once per look at the graph
    report.write()
    assert read_health(tmp_path)["feedback"].strangers == {"state": ["/junk 0123456789abcdef"]}


def test_a_report_that_cannot_be_written_is_logged_not_raised(tmp_path: Path) -> None:
    log = Lines()
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    report = Reporter("learning", report_dir=not_a_folder, logger=log)
    report.write()
    assert len(log.errors) == 1 and log.errors[0].startswith("cannot write the health report")


def test_no_report_dir_writes_nothing_and_the_status_is_ok(tmp_path: Path) -> None:
    report = Reporter("recorder", report_dir=None, logger=Lines())
    report.write()
    status = report.status([("steps_recorded", 12)])
    assert status.level == OK and status.values[0] == ("steps_recorded", "12")
    assert report.status(error="tripped: travel").level == ERROR


def test_the_module_imports_no_ros_at_module_level() -> None:
    import servo_axis.nodes.reporting as mod

    tree = ast.parse(Path(mod.__file__).read_text())
    top = set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            top.add((node.module or "").split(".")[0])
        elif isinstance(node, ast.Import):
            top.update(a.name.split(".")[0] for a in node.names)
    assert top <= {"__future__", "collections", "pathlib", "time", "typing", "servo_axis"}
