"""Signals from a bag written in the test (CDR made with rosbags, no rclpy), and summarise().

The bag holds an axis ``/x`` of a realtime run (its ``params.yaml`` beside the
bag says so; a lost sample is allowed there): ``state`` on steps 0..N-1 but
7, ``reference`` on steps 0..N+4, ``command`` on every step but 3 and 10, one
``fault`` and some ``/clock`` and ``plant/status`` messages that are only
counted. Junk in a bag: test_analysis_junk.py.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.analysis.signals import FaultRecord, load_signals, tracking
from servo_axis.analysis.summary import RunSummary, load_summary, summarise
from servo_axis.params.factories import build_generator
from servo_axis.params.resolve import feedforward_values
from servo_axis.params.scenario import load_scenario
from servo_axis.params.schemas import SHARED
from servo_axis.recording.writer import BagWriter
from servo_axis.wire import layouts

JOINT_STATE = "sensor_msgs/msg/JointState"
MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
CLOCK = "rosgraph_msgs/msg/Clock"

PERIOD_S = 0.002
PERIOD_NS = 2_000_000
LEAD = 0.002
N = 230  # 4 whole cycles of 50 steps (10 Hz reference at 2 ms) and 30 steps
MISSING_STATE = {7}
MISSING_COMMAND = {3, 10}
FAULT = (120.0, 1.0, 2.5e-3)  # step, code (following error), value


class Cdr:
    """CDR payloads of the three recorded types, made with rosbags' typestore."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_JAZZY)
        self.t = self.ts.types

    def _stamp(self, ns: int) -> Any:
        return self.t["builtin_interfaces/msg/Time"](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
        )

    def joint_state(self, step: int, names: list[str], **fields: list[float]) -> bytes:
        header = self.t["std_msgs/msg/Header"](stamp=self._stamp(step * PERIOD_NS), frame_id="")
        msg = self.t[JOINT_STATE](
            header=header,
            name=names,
            position=np.array(fields.get("position", []), dtype=np.float64),
            velocity=np.array(fields.get("velocity", []), dtype=np.float64),
            effort=np.array(fields.get("effort", []), dtype=np.float64),
        )
        return bytes(self.ts.serialize_cdr(msg, JOINT_STATE))

    def multi_array(self, label: str | tuple[str, ...], data: list[float]) -> bytes:
        """One dimension per field of size 1 (the project's layout); a str: one dimension."""
        fields = [(label, len(data))] if isinstance(label, str) else [(lb, 1) for lb in label]
        dims = [
            self.t["std_msgs/msg/MultiArrayDimension"](label=lb, size=size, stride=size)
            for lb, size in fields
        ]
        layout = self.t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = self.t[MULTI_ARRAY](layout=layout, data=np.array(data, dtype=np.float64))
        return bytes(self.ts.serialize_cdr(msg, MULTI_ARRAY))

    def clock(self, step: int) -> bytes:
        msg = self.t[CLOCK](clock=self._stamp(step * PERIOD_NS))
        return bytes(self.ts.serialize_cdr(msg, CLOCK))


def signals_of_step(k: int) -> dict[str, float]:
    """The values the bag records for step ``k``."""
    return {
        "encoder_rad": 0.5 * math.sin(0.01 * k),
        "scale_m": LEAD * 0.5 * math.sin(0.01 * k) + 1e-6 * math.cos(0.3 * k),
        "reference_rad": 0.5 * math.sin(0.01 * k + 0.001),
        "feedforward_Nm": 0.1 * k,
        "command_Nm": -0.2 * k,
    }


def write_bag(directory: Path) -> dict[str, int]:
    """Write the test bag; returns the messages per topic in order of first message."""
    cdr = Cdr()
    counts: dict[str, int] = {}
    with BagWriter(directory) as bag:
        for topic, type_name in (
            ("/clock", CLOCK),
            ("/x/reference", JOINT_STATE),
            ("/x/state", JOINT_STATE),
            ("/x/command", JOINT_STATE),
            ("/x/fault", MULTI_ARRAY),
            ("/x/plant/status", MULTI_ARRAY),
        ):
            bag.add_topic(topic, type_name)
        t = 1_000

        def put(topic: str, data: bytes) -> None:
            nonlocal t
            t += 10
            bag.write(topic, data, log_time_ns=t)
            counts[topic] = counts.get(topic, 0) + 1

        for k in range(N + 5):
            v = signals_of_step(k)
            if k % 10 == 0:
                put("/clock", cdr.clock(k))
            put(
                "/x/reference",
                cdr.joint_state(
                    k,
                    ["x_motor"],
                    position=[v["reference_rad"]],
                    velocity=[0.0],
                    effort=[v["feedforward_Nm"]],
                ),
            )
            if k >= N:
                continue
            if k not in MISSING_STATE:
                put(
                    "/x/state",
                    cdr.joint_state(
                        k,
                        ["x_motor", "x_table"],
                        position=[v["encoder_rad"], v["scale_m"]],
                        velocity=[0.0, 0.0],
                        effort=[0.0, 0.0],
                    ),
                )
            if k not in MISSING_COMMAND:
                put("/x/command", cdr.joint_state(k, ["x_motor"], effort=[v["command_Nm"]]))
            if k == int(FAULT[0]):
                put("/x/fault", cdr.multi_array(layouts.FAULT.labels, list(FAULT)))
            if k % 50 == 0:
                put(
                    "/x/plant/status",
                    cdr.multi_array(layouts.STATUS.labels, [float(k), 0.0, 0.0, 0.0]),
                )
    return counts


@pytest.fixture
def run_dir(tmp_path: Path) -> tuple[Path, dict[str, int]]:
    run = tmp_path / "run"
    counts = write_bag(run / "bag")
    # The run's parameters as the runner writes them: the analysis takes its
    # rules from them (realtime: the stream may skip a sample).
    shared = {"mode": "realtime", "control_period_s": PERIOD_S, "lead_m_per_rad": LEAD}
    params = {"/**": {"ros__parameters": shared}, "/**/plant": {"ros__parameters": {}}}
    (run / "params.yaml").write_text(yaml.safe_dump(params))
    return run, counts


def write_scenario(path: Path, **feedforward: Any) -> Path:
    data = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": "tiny", "description": "a tiny run"},
                "mode": "realtime",
                "control_period_s": PERIOD_S,
                "lead_m_per_rad": LEAD,
            }
        },
        "plant": {"ros__parameters": {}},
        "feedback": {"ros__parameters": {"sensor": "scale"}},
        "feedforward": {
            "ros__parameters": {
                "reference": {"kind": "sine", "frequency_hz": 10.0, "amplitude_m": 0.001},
                "ptc": {"enabled": False},
                **feedforward,
            }
        },
    }
    path.write_text(yaml.safe_dump(data))
    return path


def test_load_signals_reads_the_bag_by_leaf_topic(run_dir: tuple[Path, dict[str, int]]) -> None:
    run, counts = run_dir
    sig = load_signals(run / "bag", PERIOD_S)
    steps = [k for k in range(N) if k not in MISSING_STATE]
    assert sig.step.dtype.kind == "i"
    assert sig.step.tolist() == steps
    for name in ("encoder_rad", "scale_m", "reference_rad", "feedforward_Nm"):
        expected = [signals_of_step(k)[name] for k in steps]
        assert_allclose(getattr(sig, name), expected, rtol=0, atol=0, err_msg=name)
    command = [
        math.nan if k in MISSING_COMMAND else signals_of_step(k)["command_Nm"] for k in steps
    ]
    assert_allclose(sig.command_Nm, command, rtol=0, atol=0, equal_nan=True)
    assert np.isnan(sig.command_Nm[[3, 9]]).all()  # steps 3 and 10 (step 7 is not there)
    assert sig.faults == [FaultRecord(step=120, code=1, name="following_error", value=2.5e-3)]
    assert sig.counts == counts
    assert list(sig.counts) == list(counts)  # order of first message
    assert sig.dropped == dict.fromkeys(counts, 0)  # every topic of this bag has rules


def test_load_signals_drops_a_fault_of_an_unknown_code_or_layout(tmp_path: Path) -> None:
    cdr = Cdr()
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic("fault", MULTI_ARRAY)
        bag.write("fault", cdr.multi_array(layouts.FAULT.labels, [4.0, 99.0, -1.0]), log_time_ns=5)
        bag.write("fault", cdr.multi_array("step,code,value", [5.0, 1.0, -1.0]), log_time_ns=6)
        bag.write("fault", cdr.multi_array(layouts.FAULT.labels, [6.5, 1.0, -1.0]), log_time_ns=7)
        bag.write("fault", cdr.multi_array(layouts.FAULT.labels, [7.0, 3.0, -1.0]), log_time_ns=8)
        bag.write("fault", cdr.multi_array(layouts.FAULT.labels, [7.0, 3.0, -2.0]), log_time_ns=9)
    sig = load_signals(tmp_path / "bag", PERIOD_S)
    assert sig.step.size == 0 and sig.command_Nm.size == 0
    # Unknown code, wrong labels, a step that is no whole number, the same step again.
    assert sig.faults == [FaultRecord(step=7, code=3, name="current", value=-1.0)]
    assert sig.counts == {"fault": 5}
    assert sig.dropped == {"fault": 4}


def test_tracking_uses_the_feedback_sensor(
    run_dir: tuple[Path, dict[str, int]], tmp_path: Path
) -> None:
    run, _ = run_dir
    sig = load_signals(run / "bag", PERIOD_S)
    path = write_scenario(tmp_path / "tiny.yaml")
    target, y = tracking(load_scenario(path), path, sig)
    assert target is sig.reference_rad
    assert_allclose(y, sig.scale_m / LEAD, rtol=1e-15, atol=0)
    scenario = load_scenario(path)
    scenario["feedback"]["ros__parameters"]["sensor"] = "encoder"
    _, y_enc = tracking(scenario, path, sig)
    assert_allclose(y_enc, sig.encoder_rad, rtol=0, atol=0)


def test_tracking_with_learning_recomputes_the_original_target(
    run_dir: tuple[Path, dict[str, int]], tmp_path: Path
) -> None:
    run, _ = run_dir
    sig = load_signals(run / "bag", PERIOD_S)
    # The learning law (rptc) corrects the target, which needs PTC.
    path = write_scenario(
        tmp_path / "learn.yaml", learning={"enabled": True, "cycle_s": 0.1}, ptc={"enabled": True}
    )
    scenario = load_scenario(path)
    target, _ = tracking(scenario, path, sig)
    values = feedforward_values(scenario, path).with_keys({"learning.enabled": False})
    rows = build_generator(values).samples(0, N)
    assert_allclose(target, [rows[k][0] for k in sig.step], rtol=0, atol=0)
    # The generator's target, not the recorded reference.
    assert np.max(np.abs(target - sig.reference_rad)) > 1e-3


def _key_paths(obj: Any, prefix: str = "") -> list[str]:
    """Every key of nested mappings and lists, in order, as paths."""
    if isinstance(obj, dict):
        out = []
        for k, v in obj.items():
            out += [f"{prefix}/{k}", *_key_paths(v, f"{prefix}/{k}")]
        return out
    if isinstance(obj, list):
        return [p for i, v in enumerate(obj) for p in _key_paths(v, f"{prefix}[{i}]")]
    return []


def _leaves(obj: Any) -> list[Any]:
    if isinstance(obj, dict):
        return [x for v in obj.values() for x in _leaves(v)]
    if isinstance(obj, list):
        return [x for v in obj for x in _leaves(v)]
    return [obj]


def _stats(e: list[float]) -> dict[str, float]:
    if not e:
        return {"rms_m": math.nan, "max_m": math.nan}
    return {
        "rms_m": math.sqrt(sum(x * x for x in e) / len(e)),
        "max_m": max(abs(x) for x in e),
    }


def old_way_summary(path: Path, counts: dict[str, int], wall: float) -> dict[str, Any]:
    """The summary dict as the report module built it, numbers computed independently."""
    steps = [k for k in range(N) if k not in MISSING_STATE]
    err = {}
    for k in steps:
        v = signals_of_step(k)
        err[k] = LEAD * (v["reference_rad"] - v["scale_m"] / LEAD)
    per_cycle = 50
    cycles = []
    for c in range(N // per_cycle + 1):
        inside = [k for k in steps if c * per_cycle <= k < (c + 1) * per_cycle]
        if len(inside) == per_cycle:
            cycles.append(
                {
                    "cycle": c + 1,
                    **_stats([err[k] for k in inside]),
                    "reference_instants": _stats([err[k] for k in inside if k % 2 == 0]),
                }
            )
    later = [k for k in steps if k >= per_cycle]
    sim_time = len(steps) * PERIOD_S
    return {
        "scenario": "tiny",
        "description": "a tiny run",
        "scenario_file": str(path),
        "processes": "composed",
        "time_mode": "realtime",
        "control_period_s": PERIOD_S,
        "steps": len(steps),
        "sim_time_s": sim_time,
        "wall_time_s": wall,
        "steps_per_s": len(steps) / wall,
        "realtime_factor": sim_time / wall,
        "message_counts": counts,
        "faults": [{"step": 120, "code": 1, "name": "following_error", "value": 2.5e-3}],
        "ptc": False,
        "friction_table": False,
        "reference_period_s": 0.1,
        "tracking_error": {
            "all_samples": _stats(list(err.values())),
            "reference_instants": _stats([err[k] for k in steps if k % 2 == 0]),
            "cycles": cycles,
            "after_first_cycle": {
                "all_samples": _stats([err[k] for k in later]),
                "reference_instants": _stats([err[k] for k in later if k % 2 == 0]),
            },
        },
    }


def test_summarise_writes_the_old_layout(
    run_dir: tuple[Path, dict[str, int]], tmp_path: Path
) -> None:
    run, counts = run_dir
    path = write_scenario(tmp_path / "tiny.yaml")
    summary = summarise(
        run, scenario=load_scenario(path), scenario_path=path, wall_time_s=0.25, mode="composed"
    )
    text = (run / "summary.json").read_text()
    assert text == summary.to_json()
    written = json.loads(text)
    expected = old_way_summary(path, counts, 0.25)
    assert _key_paths(written) == _key_paths(expected)
    # Cycle 1 lacks step 7 (no state): incomplete, left out.
    assert [c["cycle"] for c in written["tracking_error"]["cycles"]] == [2, 3, 4]
    for got, want in zip(_leaves(written), _leaves(expected), strict=True):
        if isinstance(want, float):
            assert_allclose(got, want, rtol=1e-12, atol=0)
        else:
            assert got == want
    assert load_summary(run) == summary
    assert RunSummary.from_json(text).to_json() == text


def test_summarise_names_an_unnamed_scenario_after_its_file(
    run_dir: tuple[Path, dict[str, int]], tmp_path: Path
) -> None:
    run, _ = run_dir
    path = write_scenario(tmp_path / "unnamed_run.yaml")
    scenario = load_scenario(path)
    del scenario["/**"]["ros__parameters"]["scenario"]
    del scenario["feedforward"]
    summary = summarise(run, scenario=scenario, scenario_path=path, wall_time_s=0.0, mode="p")
    assert summary.scenario == "unnamed_run"
    assert summary.description == ""
    assert summary.reference_period_s is None
    assert summary.tracking_error.cycles == ()
    assert summary.tracking_error.after_first_cycle is None
    assert summary.ptc is True  # the default of ptc.enabled
    assert math.isnan(summary.steps_per_s) and math.isnan(summary.realtime_factor)
    assert "NaN" in (run / "summary.json").read_text()


def write_circle_axis(run: Path, tmp_path: Path, col: int, d: np.ndarray) -> Path:
    """Bag and summary.json of one axis of a 10 mm circle; the measured radius is R + d."""
    cdr = Cdr()
    steps = np.arange(d.size)
    theta = 2 * np.pi * 10.0 * steps * PERIOD_S
    unit = np.column_stack((np.cos(theta), np.sin(theta)))
    target = 0.01 * unit[:, col] / LEAD
    measured = (0.01 + d) * unit[:, col] / LEAD
    with BagWriter(run / "bag") as bag:
        bag.add_topic("state", JOINT_STATE)
        bag.add_topic("reference", JOINT_STATE)
        for k in steps.tolist():
            ref = cdr.joint_state(
                k, ["x_motor"], position=[target[k]], velocity=[0.0], effort=[0.0]
            )
            state = cdr.joint_state(
                k,
                ["x_motor", "x_table"],
                position=[measured[k], measured[k] * LEAD],
                velocity=[0.0, 0.0],
                effort=[0.0, 0.0],
            )
            bag.write("reference", ref, log_time_ns=2 * k + 1)
            bag.write("state", state, log_time_ns=2 * k + 2)
    path = write_scenario(tmp_path / f"axis{col}.yaml")
    scenario = load_scenario(path)
    scenario["feedback"]["ros__parameters"]["sensor"] = "encoder"
    path.write_text(yaml.safe_dump(scenario))
    (run / "scenario.yaml").write_text(path.read_text())  # what the runner records
    summarise(run, scenario=scenario, scenario_path=path, wall_time_s=1.0, mode="processes")
    return path


def test_summarise_axes_gives_the_contour_and_the_plots_draw(tmp_path: Path) -> None:
    from servo_axis.analysis.plots import plot, plot_contour, plot_cycles, plot_error_overlay
    from servo_axis.analysis.summary import AxesSummary, summarise_axes
    from servo_axis.analysis.text import format_any_summary

    n, per_cycle = 200, 50  # 4 revolutions at 10 Hz, 2 ms
    steps = np.arange(n)
    d = np.where(steps < 100, 3e-6, 1e-6) * np.sin(2 * np.pi * 4 * steps / per_cycle)
    run = tmp_path / "xy"
    path = write_circle_axis(run / "x", tmp_path, 0, d)
    write_circle_axis(run / "y", tmp_path, 1, d)
    axes = {a: RunSummary.from_json(run / a / "summary.json") for a in ("y", "x")}
    summary = summarise_axes(run, scenario=load_scenario(path), axes=axes, wall_time_s=2.0)
    assert isinstance(load_summary(run), AxesSummary)
    assert load_summary(run) == summary
    assert (run / "summary.json").read_text() == summary.to_json()
    assert list(json.loads(summary.to_json())) == [
        "scenario",
        "description",
        "wall_time_s",
        "axes",
        "contour",
    ]
    c = summary.contour
    assert c is not None and c.axes == ("x", "y")
    assert_allclose(c.centre_m, (0.0, 0.0), rtol=0, atol=1e-15)
    assert_allclose(c.radius_m, 0.01, rtol=1e-12)
    assert_allclose(c.circular_deviation_m, np.ptp(d), rtol=0, atol=1e-14)
    assert [r.cycle for r in c.cycles] == [1, 2, 3, 4]
    assert_allclose(
        [r.max_radial_m for r in c.cycles],
        [np.max(np.abs(d[i * per_cycle : (i + 1) * per_cycle])) for i in range(4)],
        rtol=0,
        atol=1e-14,
    )
    assert "== contour: circle of radius 10.000 mm" in format_any_summary(summary)
    written = [plot_contour(run), *plot(run / "x")]
    written.append(plot_cycles(list(axes.values()), ["y", "x"], tmp_path / "c.png", title="t"))
    written.append(
        plot_error_overlay(
            [run / "x", run / "y"], ["x", "y"], tmp_path / "e.png", zoom_cycle=2, title="t"
        )
    )
    names = [p.name for p in written]
    assert names == [
        "contour.png",
        "reference_position.png",
        "error.png",
        "cycle_errors.png",
        "c.png",
        "e.png",
    ]
    assert all(p.stat().st_size > 1000 for p in written)


def test_friction_table_from_run_uses_the_scenario_nominal_model(tmp_path: Path) -> None:
    from servo_axis.core.feedforward.friction_table import build_friction_table
    from servo_axis.identify.friction import estimate_friction_torque, table_from_run

    cdr = Cdr()
    n = 1000  # 2 s at 2 ms: two reversals of a 1 Hz, 20 um sine
    k = np.arange(n)
    ref = 20e-6 / LEAD * np.sin(2 * np.pi * 1.0 * k * PERIOD_S)
    # The motor torque reference K_T i of the command topic, N m.
    torque_Nm = 0.3 * np.sign(np.cos(2 * np.pi * k * PERIOD_S)) + 0.01 * np.sin(0.7 * k)
    run = tmp_path / "fid"
    with BagWriter(run / "bag") as bag:
        for topic in ("state", "reference", "command"):
            bag.add_topic(topic, JOINT_STATE)
        for i in k.tolist():
            t = 3 * i
            bag.write(
                "reference",
                cdr.joint_state(i, ["x_motor"], position=[ref[i]], velocity=[0.0], effort=[0.0]),
                log_time_ns=t,
            )
            bag.write(
                "state",
                cdr.joint_state(
                    i,
                    ["x_motor", "x_table"],
                    position=[ref[i], ref[i] * LEAD],
                    velocity=[0.0, 0.0],
                    effort=[0.0, 0.0],
                ),
                log_time_ns=t + 1,
            )
            command = cdr.joint_state(i, ["x_motor"], effort=[torque_Nm[i]])
            bag.write("command", command, log_time_ns=t + 2)
    path = write_scenario(tmp_path / "fid.yaml")
    scenario = load_scenario(path)
    nominal = {"torque_constant_Nm_per_A": 0.8, "inertia_kgm2": 0.02, "damping_Nms_per_rad": 0.05}
    scenario["/**"]["ros__parameters"]["nominal"] = nominal
    path.write_text(yaml.safe_dump(scenario))
    (run / "scenario.yaml").write_text(path.read_text())  # what the runner records
    summarise(run, scenario=scenario, scenario_path=path, wall_time_s=1.0, mode="processes")

    table = table_from_run(run, bin_width_m=1e-6, max_displacement_m=10e-6)
    torque = estimate_friction_torque(
        reference_rad=ref,
        motor_torque_Nm=torque_Nm,
        period_s=PERIOD_S,
        inertia_kgm2=nominal["inertia_kgm2"],
        damping_Nms_per_rad=nominal["damping_Nms_per_rad"],
    )
    expected = build_friction_table(
        position_m=ref * LEAD, torque_Nm=torque, bin_width_m=1e-6, max_displacement_m=10e-6
    )
    assert_allclose(table.displacement_m, expected.displacement_m, rtol=0, atol=0)
    assert_allclose(table.torque_Nm, expected.torque_Nm, rtol=1e-12, atol=1e-15)
    # With the default nominal model the table differs: the scenario's values are used.
    default = estimate_friction_torque(
        reference_rad=ref,
        motor_torque_Nm=torque_Nm,
        period_s=PERIOD_S,
        inertia_kgm2=SHARED["nominal.inertia_kgm2"].default,  # type: ignore[arg-type]
        damping_Nms_per_rad=SHARED["nominal.damping_Nms_per_rad"].default,  # type: ignore[arg-type]
    )
    other = build_friction_table(
        position_m=ref * LEAD, torque_Nm=default, bin_width_m=1e-6, max_displacement_m=10e-6
    )
    assert np.max(np.abs(other.torque_Nm - table.torque_Nm)) > 1e-3
