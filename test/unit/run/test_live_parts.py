"""The live view's pieces without ROS: axes, error pairing, schemas, the checks before a run."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError
from servo_axis.params.run_plan import AxisPlan, plan_run
from servo_axis.params.scenario import load_scenario
from servo_axis.run.live_channels import (
    HOLD_LOCKSTEP_SAMPLES,
    HOLD_SAMPLES,
    ErrorPairs,
    InOrder,
    LiveAxis,
    error_schema,
    sample_schema,
)
from servo_axis.run.live_view import check_live, live_axis, module_args, wait_ready
from servo_axis.wire.messages import StateSample

CONFIG = Path(__file__).resolve().parents[3] / "config"


def axis_plan(name: str, out: Path, namespace: str = "", *, realtime: bool = False) -> AxisPlan:
    """The plan of a shipped single-axis scenario's run in ``namespace`` (``/``: the root)."""
    path = CONFIG / f"{name}.yaml"
    data = load_scenario(path)
    if realtime:
        data["/**"]["ros__parameters"]["mode"] = "realtime"
    return plan_run(data, path, out_dir=out, namespace=namespace).axes[0]


def test_the_axis_of_a_run_names_its_topics_sensor_and_units(tmp_path: Path) -> None:
    nominal = live_axis(axis_plan("ptc_nominal", tmp_path, "/"))
    assert (nominal.sensor, nominal.linear, nominal.axis) == ("encoder", True, "x")
    assert_allclose(nominal.control_period_s, 1e-3, rtol=0, atol=0)
    assert nominal.topic("state") == "/state"
    full_closed = live_axis(axis_plan("fast_reversal_sigmoid", tmp_path))
    assert full_closed.sensor == "scale"
    assert full_closed.topic("tracking_error") == "/x/tracking_error"
    assert nominal.lockstep
    assert not live_axis(axis_plan("ptc_nominal", tmp_path, realtime=True)).lockstep
    tilt = live_axis(axis_plan("dlpid_tilt_pid", tmp_path))
    assert not tilt.linear  # a rotary table: the error in rad only
    assert "error_m" not in error_schema(tilt)["properties"]
    assert "error_m" in error_schema(nominal)["properties"]


def test_the_axes_go_to_the_process_as_json_and_back() -> None:
    for lockstep in (True, False):
        axis = LiveAxis("/y", "y", 5e-4, "scale", 0.00191, True, lockstep)
        args = module_args(9000, [axis])
        assert args[:2] == ["--port", "9000"]
        assert [LiveAxis(**a) for a in json.loads(args[3])] == [axis]


def test_error_pairs_match_reference_and_output_of_the_same_step_in_either_order() -> None:
    pairs = ErrorPairs()
    assert pairs.reference(0, 1.0) is None  # the reference comes ahead
    assert pairs.reference(1, 2.0) is None
    assert pairs.output(0, 0.25) == (1.0, 0.25)
    assert pairs.output(2, 0.5) is None  # an output before its reference
    assert pairs.output(1, 1.5) == (2.0, 1.5)
    assert pairs.reference(2, 3.0) == (3.0, 0.5)
    assert pairs.output(0, 9.0) is None  # step 0 was paired already


def test_error_pairs_forget_values_whose_partner_never_comes() -> None:
    pairs = ErrorPairs(window=10)
    for k in range(100):
        pairs.reference(k, float(k))  # no output ever
    held = len(pairs._refs)
    assert held <= 21, held
    assert pairs.output(99, 0.0) == (99.0, 0.0)
    assert pairs.output(5, 0.0) is None  # long forgotten


def test_the_state_schema_names_every_field_with_its_type() -> None:
    schema = sample_schema(StateSample, "state")
    props = schema["properties"]
    assert set(props) == {f.name for f in fields(StateSample)} | {"timestamp"}
    assert props["step"] == {"type": "integer"}
    assert props["encoder_rad"] == {"type": "number"}


def test_a_busy_or_impossible_port_is_refused_in_one_line() -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(
            ConfigError, match=rf"^--live-port {port}: cannot listen on 127\.0\.0\.1"
        ):
            check_live(port)
    check_live(port)  # free again
    for bad in (0, 70000):
        with pytest.raises(ConfigError, match=rf"^--live-port {bad}: expected a TCP port 1..65535"):
            check_live(bad)


def test_without_the_extra_live_exits_2_with_how_to_install_it(tmp_path: Path) -> None:
    out = tmp_path / "run"
    code = (
        "import sys; sys.modules['foxglove'] = None\n"  # as if foxglove-sdk were not installed
        "from servo_axis.__main__ import main\n"
        f"raise SystemExit(main(['run', 'ptc_nominal', '--live', '--out', {str(out)!r}]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert "foxglove-sdk" in lines[0] and "pip install" in lines[0] and "[live]" in lines[0]
    assert not out.exists()


def test_waiting_for_the_live_process_names_why_it_did_not_start(tmp_path: Path) -> None:
    log = tmp_path / "live.log"
    log.write_text("live: cannot serve on 127.0.0.1:1: permission denied\n")
    with pytest.raises(ConfigError, match="live view exited: live: cannot serve on"):
        wait_ready(log, lambda: False)
    log.write_text("live view serving ws://127.0.0.1:8765 channels /state\n")
    assert wait_ready(log, lambda: True) == "ws://127.0.0.1:8765"
    log.write_text("")
    assert wait_ready(log, lambda: True, stopped=lambda: True) == ""


def test_samples_that_come_ahead_wait_for_the_missing_steps() -> None:
    # A reader matched late: state 0, then 5..7 live, then the history 1..4.
    order = InOrder(hold=10)
    got = []
    for step in (0, 5, 6, 7, 1, 2, 3, 4, 8, 3, 8):  # 3 and 8 again: a stranger's repeats
        got += order.put(step, step)
    assert got == list(range(9))
    # A gap that never fills is given up once more than `hold` samples wait.
    order = InOrder(hold=2)
    assert order.put(0, 0) == [0]
    assert order.put(2, 2) == [] and order.put(3, 3) == []
    assert order.put(4, 4) == [2, 3, 4]
    assert order.put(1, 1) == []  # too late: behind what was handed on
    # The end of the stream hands on what still waits, in order.
    assert order.put(7, 7) == [] and order.put(6, 6) == []
    assert order.flush() == [6, 7] and order.flush() == []
    # The first sample starts the stream (a bridge that joins one under way).
    order = InOrder(hold=2)
    assert order.put(7, 7) == [7] and order.put(9, 9) == [] and order.put(8, 8) == [8, 9]
    # Steps that went by unwatched are not waited for.
    order.skip(12)
    assert order.put(13, 13) == [13]


def test_in_lockstep_a_gap_is_waited_for_as_long_as_the_writers_keep_it() -> None:
    from servo_axis.nodes.runtime import STREAM_QOS

    assert HOLD_LOCKSTEP_SAMPLES == STREAM_QOS.depth > HOLD_SAMPLES
    # A reader matched late at a fast run: state 0, then 1,000 live states,
    # then the history 1..180 (the failing viewer's 181 missing states).
    order = InOrder(hold=HOLD_LOCKSTEP_SAMPLES)
    got = order.put(0, 0)
    for step in range(181, 1181):
        got += order.put(step, step)
    for step in range(1, 181):
        got += order.put(step, step)
    assert got == list(range(1181))
    # The realtime hold would have given the history up.
    order = InOrder(hold=HOLD_SAMPLES)
    got = order.put(0, 0)
    for step in [*range(181, 1181), *range(1, 181)]:
        got += order.put(step, step)
    assert len(got) == 1 + 1000
