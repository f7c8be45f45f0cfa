"""The run's health: exit codes from deaths, fallbacks, strangers and faults; report files."""

from __future__ import annotations

import json

import pytest

from servo_axis.analysis.health import (
    EXIT_FAILED,
    EXIT_FAULT,
    EXIT_NOT_DETERMINISTIC,
    EXIT_OK,
    NodeDeath,
    RunHealth,
    assess,
)
from servo_axis.wire.node_report import Fallback, NodeHealth, read_health, write_health


def _clean() -> dict[str, NodeHealth]:
    return {role: NodeHealth(role, rejected={"state": 2}) for role in ("plant", "feedback")}


def test_a_clean_run_is_deterministic_and_exits_0_even_with_rejected_messages() -> None:
    health = assess(failure=None, deaths=[], reports=_clean(), faults=0)
    assert health.exit_code == EXIT_OK and health.deterministic and health.reasons == ()


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ("fallback", "fell back (learning_timeout) at step 900"),
        ("stranger", "1 stranger publisher(s) on state"),
        ("death", "learning ended with code -9 at step 500 (restarted)"),
        ("recovered", "bag was recovered"),
    ],
)
def test_anything_but_the_protocol_makes_the_run_not_deterministic(
    change: str, fragment: str
) -> None:
    reports = _clean()
    deaths = []
    if change == "fallback":
        reports["feedforward"] = NodeHealth(
            "feedforward", fallbacks=[Fallback("learning_timeout", 900, "unit gone")]
        )
    if change == "stranger":
        reports["feedback"].strangers["state"] = ["/junk 0123"]
    if change == "death":
        deaths.append(NodeDeath("learning", -9, 1.2, 500, "restarted", 0.01))
    health = assess(
        failure=None,
        deaths=deaths,
        reports=reports,
        faults=0,
        bag_recovered=change == "recovered",
    )
    assert health.exit_code == EXIT_NOT_DETERMINISTIC and not health.deterministic
    assert any(fragment in r for r in health.reasons), health.reasons


def test_a_fault_outranks_a_fallback_and_a_failure_outranks_both() -> None:
    reports = {"plant": NodeHealth("plant", fallbacks=[Fallback("command_timeout", 3, "x")])}
    fault = assess(failure=None, deaths=[], reports=reports, faults=1)
    assert fault.exit_code == EXIT_FAULT and fault.outcome == "complete"
    failed = assess(failure="plant exited with code -9:\nlog", deaths=[], reports={}, faults=1)
    assert failed.exit_code == EXIT_FAILED
    assert failed.outcome == "failed" and not failed.deterministic
    assert failed.reasons[0] == "stopped: plant exited with code -9:"


def test_an_interruption_outranks_everything_and_takes_the_signal_s_exit_code() -> None:
    for name, code in (("SIGINT", 130), ("SIGTERM", 143)):
        health = assess(
            failure=None,
            interrupted=f"interrupted by {name} at step 12 of 100; the nodes were stopped",
            deaths=[],
            reports={},
            faults=1,
        )
        assert health.outcome == "interrupted" and health.exit_code == code
        assert health.reasons[0].startswith(f"interrupted by {name} at step 12 of 100")
        assert not health.deterministic


def test_health_round_trips_through_json_and_report_files(tmp_path) -> None:
    reports = _clean()
    reports["feedback"].fallbacks.append(Fallback("input_timeout", 7, "reference gone"))
    reports["plant"].stepping = {"steps": 2000, "first_s": 101.25, "last_s": 102.0}
    for report in reports.values():
        write_health(tmp_path, report)
    assert read_health(tmp_path) == reports
    # What a node has not filled in is not written.
    assert "stepping" not in reports["feedback"].to_dict()
    assert reports["plant"].to_dict()["stepping"]["first_s"] == 101.25
    assert read_health(tmp_path / "missing") == {}
    health = assess(
        failure=None,
        deaths=[NodeDeath("feedforward", -9, 2.0, 10, "ran on")],
        reports=reports,
        faults=1,
    )
    again = RunHealth.from_dict(json.loads(json.dumps(health.to_dict())))
    assert again == health


def test_a_realtime_loop_not_closed_never_reports_success() -> None:
    """Misses over realtime.max_miss_fraction, or a plant that ended the run because no
    command came, exit 5 with the reason first (issue 30); within the limit, 0."""
    from servo_axis.analysis.health import EXIT_LOOP_NOT_CLOSED, loop_not_closed
    from servo_axis.analysis.realtime_summary import Realtime

    def block(misses: int) -> Realtime:
        return Realtime(
            period_ns=1_000_000, ticks=2000, misses=misses, commands_missing=misses // 2,
            commands_late=misses - misses // 2, timer_rate=1.0, tick_late_us=None,
            command_late_us=None,
        )  # fmt: skip

    assert loop_not_closed(block(100), 0.05, {}) is None  # exactly 5 %
    why = loop_not_closed(block(101), 0.05, {})
    assert why is not None and "101 of 2000 ticks (5.1 %)" in why and "50 commands" in why
    health = assess(failure=None, deaths=[], reports={}, faults=1, realtime=True, open_loop=why)
    assert health.exit_code == EXIT_LOOP_NOT_CLOSED and health.reasons[0] == why
    assert not health.deterministic and health.outcome == "complete"
    plant = NodeHealth("plant")
    plant.fallbacks.append(Fallback("loop_open", 812, "no command for 2.01 s"))
    why = loop_not_closed(block(0), 0.05, {"plant": plant})
    assert why == "the loop was not closed: plant ended the run (loop_open) at step 812"
    health = assess(failure=None, deaths=[], reports={"plant": plant}, faults=0, realtime=True,
                    open_loop=why)  # fmt: skip
    assert health.exit_code == EXIT_LOOP_NOT_CLOSED
    assert health.reasons[1].startswith("plant fell back (loop_open) at step 812")
    assert assess(failure=None, deaths=[], reports={}, faults=0, realtime=True).exit_code == 0
