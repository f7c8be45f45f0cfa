"""Analysis of the deformation ratio (paper 004 Sect. III-C): reader, stops, summary, text, plots.

A synthetic lockstep run of an axis ``x`` is written with the project's bag
writer (CDR made with rosbags, no rclpy): a segments reference (half-cosine
moves meeting at a slow reversal, a slow non-reversal, a fast reversal and a
fast stop at the end), ``state`` with a table that lags the screw by a
deformation proportional to the reference acceleration, and ``deformation``
computed from those readings by :func:`servo_axis.core.deformation.deformation_ratio`.
Every expected number is computed here from those arrays with numpy or in
closed form, independently of the analysis.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.analysis.plots import DEFORMATION_FIGURE, plot, plot_reversal_detail
from servo_axis.analysis.signals import StreamRules, load_signals, read_streams
from servo_axis.analysis.summary import (
    DEFORMATION_WINDOWS_S,
    RunSummary,
    reference_stops,
    run_series,
    summarise,
    summarise_series,
)
from servo_axis.analysis.text import format_summary
from servo_axis.core.deformation import DeformationTrace, deformation_ratio
from servo_axis.core.errors import ConfigError
from servo_axis.core.reference import SegmentsReference
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.writer import BagWriter

JOINT_STATE = "sensor_msgs/msg/JointState"
MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

PERIOD_S = 0.001
PERIOD_NS = 1_000_000
N = 1500  # 1.5 s
LEAD = 0.002  # R, m/rad
P = 4  # window_samples
MIN_ROT = 4e-3  # rad: valid down to 2 mm/s, 33 ms before a slow stop, 4 ms before a fast one
COMPLIANCE = 2e-6  # m of deformation per m/s^2 of reference acceleration
DELAY = 0.1
DISTANCES = (0.002, -0.002, -0.004, 0.004)
DURATIONS = (0.4, 0.4, 0.2, 0.2)
# The stops: where each move ends, the kind, the move into it.
STOPS = (
    (0.5, "reversal", 0),
    (0.9, "non_reversal", 1),
    (1.1, "reversal", 2),
    (1.3, "final", 3),
)
AXIS_NAMES = ["x_motor", "x_table"]
MOTOR = ["x_motor"]
DEFORMATION = ("step", "d_r_m_per_rad", "scale_increment_m", "encoder_increment_rad", "valid")


class Cdr:
    """CDR payloads made with rosbags' typestore; any stamp (ns), names and arrays."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_JAZZY)
        self.t = self.ts.types

    def joint_state(self, ns: int, names: list[str], **fields: list[float]) -> bytes:
        stamp = self.t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        msg = self.t[JOINT_STATE](
            header=self.t["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
            name=names,
            **{
                f: np.array(fields.get(f, []), dtype=np.float64)
                for f in ("position", "velocity", "effort")
            },
        )
        return bytes(self.ts.serialize_cdr(msg, JOINT_STATE))

    def multi_array(self, labels: tuple[str, ...], data: list[float]) -> bytes:
        """One dimension per field of size 1, as the nodes write it."""
        dims = [
            self.t["std_msgs/msg/MultiArrayDimension"](label=label, size=1, stride=1)
            for label in labels
        ]
        layout = self.t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = self.t[MULTI_ARRAY](layout=layout, data=np.array(data, dtype=np.float64))
        return bytes(self.ts.serialize_cdr(msg, MULTI_ARRAY))

    def deformation(self, step: float, values: list[float]) -> bytes:
        """A ``deformation`` message ``[step, d_r, dx, dth, valid]``."""
        return self.multi_array(DEFORMATION, [float(step), *values])


CDR = Cdr()


def reference() -> SegmentsReference:
    return SegmentsReference(distances_m=DISTANCES, durations_s=DURATIONS, delay_s=DELAY)


def decel(i: int) -> float:
    """The closed form of 004's deceleration into the stop after move ``i``: |d| (pi/T)^2 / 2."""
    return abs(DISTANCES[i]) * (math.pi / DURATIONS[i]) ** 2 / 2


class Run:
    """The synthetic run's readings and its deformation trace."""

    def __init__(self) -> None:
        t = np.arange(N) * PERIOD_S
        pos, vel, acc = reference().sample(t)
        self.t = t
        self.ref_pos, self.ref_vel = pos, vel
        self.scale = pos.copy()
        # The screw leads the table by the spring's deformation (the drive
        # force of a rigid body: proportional to the acceleration).
        self.encoder = (pos + COMPLIANCE * acc) / LEAD
        self.trace = deformation_ratio(
            self.encoder,
            self.scale,
            window_samples=P,
            lead_m_per_rad=LEAD,
            min_rotation_rad=MIN_ROT,
        )

    def deformation_values(self, k: int) -> list[float]:
        tr = self.trace
        return [
            float(tr.d_r_m_per_rad[k]),
            float(tr.scale_increment_m[k]),
            float(tr.encoder_increment_rad[k]),
            1.0 if tr.valid[k] else 0.0,
        ]


RUN = Run()


def messages(junk: bool = False) -> tuple[list[tuple[str, bytes]], int]:
    """The run's messages in recording order, with junk on ``deformation`` if asked (and its count)."""
    out: list[tuple[str, bytes]] = []
    n_junk = 0
    nan = math.nan
    for k in range(N):
        ns = k * PERIOD_NS
        out.append(
            (
                "/x/reference",
                CDR.joint_state(
                    ns,
                    MOTOR,
                    position=[RUN.ref_pos[k] / LEAD],
                    velocity=[RUN.ref_vel[k] / LEAD],
                    effort=[0.5 * math.sin(k / 50)],
                ),
            )
        )
        state = CDR.joint_state(
            ns,
            AXIS_NAMES,
            position=[RUN.encoder[k], RUN.scale[k]],
            velocity=[0.0, 0.0],
            effort=[0.0, 0.0],
        )
        out.append(("/x/state", state))
        values = RUN.deformation_values(k)
        real = CDR.deformation(k, values)
        if junk and k % 97 == 5:
            # A stranger's copy of the next sample arriving first, and kinds
            # of junk the subscribers refuse: all before the real message.
            bad = [
                CDR.deformation(k + 1, [1.0, 0.0, 0.0, 1.0]),  # ahead
                CDR.deformation(k, [nan, 0.0, 0.0, 1.0]),
                CDR.multi_array(DEFORMATION, [float(k), *values[:3]]),  # short
                CDR.deformation(k, [*values[:3], 0.5]),  # valid 0.5
                CDR.multi_array(  # the fields in another order
                    ("step", "scale_increment_m", "d_r_m_per_rad", *DEFORMATION[3:]),
                    [float(k), *values],
                ),
                CDR.deformation(k + 0.5, values),  # not a whole step
                b"\x00\x01\x00\x00",
            ]
            out += [("/x/deformation", b) for b in bad]
            n_junk += len(bad)
        out.append(("/x/deformation", real))
        if junk and k % 89 == 7:
            out += [
                ("/x/deformation", CDR.deformation(0, values)),  # past
                ("/x/deformation", real),  # the same step again
                ("/x/deformation", CDR.deformation(10**12, values)),
            ]
            n_junk += 3
        out.append(("/x/command", CDR.joint_state(ns, MOTOR, effort=[-0.1 * math.cos(k / 30)])))
    return out, n_junk


def write_bag(bag_dir: Path, msgs: list[tuple[str, bytes]]) -> None:
    with BagWriter(bag_dir) as bag:
        for topic in ("/x/reference", "/x/state", "/x/command"):
            bag.add_topic(topic, JOINT_STATE)
        bag.add_topic("/x/deformation", MULTI_ARRAY)
        for i, (topic, data) in enumerate(msgs):
            bag.write(topic, data, log_time_ns=i)


def write_scenario(path: Path, *, deformation: bool = True) -> Path:
    data: dict[str, Any] = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": "deformation_synthetic", "description": "004 Fig. 11"},
                "control_period_s": PERIOD_S,
                "duration_s": N * PERIOD_S,
                "axis": "x",
                "lead_m_per_rad": LEAD,
            }
        },
        "plant": {"ros__parameters": {}},
        "feedback": {
            "ros__parameters": {
                "sensor": "scale",
                "deformation": {
                    "enabled": deformation,
                    "window_samples": P,
                    "min_rotation_rad": MIN_ROT,
                },
            }
        },
        "feedforward": {
            "ros__parameters": {
                "reference": {
                    "kind": "segments",
                    "segment_distances_m": list(DISTANCES),
                    "segment_durations_s": list(DURATIONS),
                    "segment_delay_s": DELAY,
                }
            }
        },
    }
    path.write_text(yaml.safe_dump(data))
    return path


def make_run(root: Path, name: str, *, junk: bool = False) -> tuple[Path, RunSummary, int]:
    run = root / name
    run.mkdir(parents=True)
    path = write_scenario(run / "scenario.yaml")
    msgs, n_junk = messages(junk)
    write_bag(run / "bag", msgs)
    summary = summarise(
        run, scenario=load_scenario(path), scenario_path=path, wall_time_s=1.0, mode="processes"
    )
    return run, summary, n_junk


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("deformation")
    clean_run, clean, _ = make_run(root, "clean")
    junk_run, dirty, n_junk = make_run(root, "junk", junk=True)
    return {
        "clean_run": clean_run,
        "clean": clean,
        "junk_run": junk_run,
        "dirty": dirty,
        "junk": n_junk,
    }


def assert_trace_equal(got: DeformationTrace | None, want: DeformationTrace) -> None:
    assert got is not None
    for name in ("d_r_m_per_rad", "scale_increment_m", "encoder_increment_rad", "valid"):
        assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)


def test_the_synthetic_run_has_valid_and_invalid_samples() -> None:
    """The fixture exercises what the analysis must handle: both kinds of sample, d_r moving."""
    valid = RUN.trace.valid
    assert 0 < np.count_nonzero(valid) < N
    assert not valid[:P].any()
    assert np.ptp(RUN.trace.d_r_m_per_rad[valid]) > 1e-7


def test_reader_returns_the_deformation_written(runs: dict[str, Any]) -> None:
    run: Path = runs["clean_run"]
    scenario = load_scenario(run / "scenario.yaml")
    sig = load_signals(run / "bag", PERIOD_S, scenario=scenario)
    assert sig.step.tolist() == list(range(N))
    assert_trace_equal(sig.deformation, RUN.trace)
    assert sig.dropped["/x/deformation"] == 0


def test_junk_on_deformation_is_dropped_and_counted(runs: dict[str, Any]) -> None:
    rules = StreamRules(period_ns=PERIOD_NS, axis="x", steps=N, deformation=True)
    clean = read_streams(runs["clean_run"] / "bag", rules)
    dirty = read_streams(runs["junk_run"] / "bag", rules)
    got = [(k.step, k.data) for k in dirty.kept["/x/deformation"]]
    assert got == [(k.step, k.data) for k in clean.kept["/x/deformation"]]
    assert runs["junk"] > 100
    assert dirty.dropped["/x/deformation"] == runs["junk"]
    assert dirty.counts["/x/deformation"] == N + runs["junk"]
    scenario = load_scenario(runs["junk_run"] / "scenario.yaml")
    sig = load_signals(runs["junk_run"] / "bag", PERIOD_S, scenario=scenario)
    assert_trace_equal(sig.deformation, RUN.trace)
    dirty_block, clean_block = runs["dirty"].deformation, runs["clean"].deformation
    assert dirty_block is not None and clean_block is not None
    assert dirty_block.dropped == runs["junk"] and clean_block.dropped == 0
    assert dirty_block.stops == clean_block.stops


def test_a_run_without_the_deformation_ratio_keeps_none(tmp_path: Path) -> None:
    """deformation.enabled false: a stranger's messages on the topic are all dropped."""
    path = write_scenario(tmp_path / "off.yaml", deformation=False)
    msgs, _ = messages()
    write_bag(tmp_path / "bag", msgs)
    sig = load_signals(tmp_path / "bag", PERIOD_S, scenario=load_scenario(path))
    assert sig.deformation is not None
    assert not sig.deformation.valid.any()
    assert np.isnan(sig.deformation.scale_increment_m).all()
    assert sig.dropped["/x/deformation"] == N
    # No topic at all: None, and no block in the summary.
    write_bag(tmp_path / "run" / "bag", [m for m in msgs if m[0] != "/x/deformation"])
    on = write_scenario(tmp_path / "on.yaml")
    summary = summarise(
        tmp_path / "run", scenario=load_scenario(on), scenario_path=on, wall_time_s=1.0, mode="p"
    )
    assert summary.deformation is None
    assert "deformation" not in json.loads((tmp_path / "run" / "summary.json").read_text())
    assert "deformation d_r" not in format_summary(summary)


def test_missing_samples_are_invalid_and_nan(tmp_path: Path) -> None:
    """A deformation stream that ends early (lockstep: it cannot skip) leaves the rest invalid."""
    path = write_scenario(tmp_path / "s.yaml")
    msgs, _ = messages()
    cut = 700
    kept = [m for i, m in enumerate(msgs) if m[0] != "/x/deformation" or i < 4 * cut]
    write_bag(tmp_path / "bag", kept)
    sig = load_signals(tmp_path / "bag", PERIOD_S, scenario=load_scenario(path))
    tr = sig.deformation
    assert tr is not None
    assert_array_equal(tr.valid[:cut], RUN.trace.valid[:cut])
    assert not tr.valid[cut:].any()
    assert np.isnan(tr.encoder_increment_rad[cut:]).all()
    assert (tr.d_r_m_per_rad[cut:] == 0.0).all()


def test_stops_of_a_segments_reference_are_classified() -> None:
    t = np.arange(N) * PERIOD_S
    _, vel, acc = reference().sample(t)
    stops = reference_stops(t, vel, acc)
    assert [(s.kind) for s in stops] == [kind for _, kind, _ in STOPS]
    assert_allclose([s.time_s for s in stops], [t0 for t0, _, _ in STOPS], rtol=0, atol=1e-12)
    # The acceleration at the last sample before the stop: the closed form
    # |d| (pi/T)^2 cos(pi T_u / T) / 2, within (pi T_u / T)^2 of 004's value.
    for stop, (_, _, i) in zip(stops, STOPS, strict=True):
        exact = decel(i) * math.cos(math.pi * PERIOD_S / DURATIONS[i])
        assert_allclose(stop.deceleration_m_s2, exact, rtol=1e-9)
        assert_allclose(
            stop.deceleration_m_s2, decel(i), rtol=(math.pi * PERIOD_S / DURATIONS[i]) ** 2
        )


@pytest.mark.parametrize("delay", [0.1003, 0.1007])
def test_stops_between_samples(delay: float) -> None:
    """Moves meeting off the sample grid: a sign change (reversal) or a speed minimum (non-reversal)."""
    t = np.arange(N) * PERIOD_S
    _, vel, acc = SegmentsReference(
        distances_m=DISTANCES, durations_s=DURATIONS, delay_s=delay
    ).sample(t)
    stops = reference_stops(t, vel, acc)
    assert [s.kind for s in stops] == [kind for _, kind, _ in STOPS]
    shift = delay - DELAY
    # Linear in v across a zero of a half-cosine: off by O(T_u^2 / T) at most.
    assert_allclose([s.time_s for s in stops], [t0 + shift for t0, _, _ in STOPS], atol=2e-5)
    for stop, (_, _, i) in zip(stops, STOPS, strict=True):
        assert_allclose(
            stop.deceleration_m_s2, decel(i), rtol=(math.pi * PERIOD_S / DURATIONS[i]) ** 2
        )


def test_no_motion_no_stop_and_a_sine_reverses() -> None:
    t = np.arange(N) * PERIOD_S
    assert reference_stops(t, np.zeros(N), np.zeros(N)) == ()
    # A sine of 2 Hz: its velocity cos(w t) is 0 at 0.125 + k 0.25 s, each a reversal.
    w = 2 * math.pi * 2.0
    stops = reference_stops(t, 1e-3 * w * np.cos(w * t), -1e-3 * w * w * np.sin(w * t))
    assert [s.kind for s in stops] == ["reversal"] * 6
    assert_allclose([s.time_s for s in stops], 0.125 + 0.25 * np.arange(6), atol=1e-6)
    assert_allclose([s.deceleration_m_s2 for s in stops], 1e-3 * w * w, rtol=1e-4)


def expected_window(stop_s: float, lo_s: float, hi_s: float) -> tuple[int, float | None]:
    """Valid samples in [stop + lo, stop + hi] (ends included, by step) and their mean d_r."""
    k0 = round((stop_s + lo_s) / PERIOD_S)
    k1 = round((stop_s + hi_s) / PERIOD_S)
    steps = np.arange(k0, k1 + 1)
    valid = steps[RUN.trace.valid[steps]]
    if valid.size == 0:
        return 0, None
    return int(valid.size), float(np.mean(RUN.trace.d_r_m_per_rad[valid]))


def test_window_means_against_numpy(runs: dict[str, Any]) -> None:
    block = runs["clean"].deformation
    assert block is not None
    assert (block.window_samples, block.min_rotation_rad) == (P, MIN_ROT)
    assert block.samples == N and block.valid_samples == int(np.count_nonzero(RUN.trace.valid))
    assert [s.kind for s in block.stops] == [kind for _, kind, _ in STOPS]
    seen_none = seen_value = False
    for stop, (t0, _, i) in zip(block.stops, STOPS, strict=True):
        assert_allclose(stop.time_s, t0, atol=1e-12)
        assert_allclose(
            stop.deceleration_m_s2, decel(i), rtol=(math.pi * PERIOD_S / DURATIONS[i]) ** 2
        )
        assert [(w.start_s, w.end_s) for w in stop.windows] == list(DEFORMATION_WINDOWS_S)
        for w in stop.windows:
            n, mean = expected_window(t0, w.start_s, w.end_s)
            assert w.valid_samples == n
            if mean is None:
                assert w.mean_d_r_m_per_rad is None
                seen_none = True
            else:
                assert w.mean_d_r_m_per_rad is not None
                assert_allclose(w.mean_d_r_m_per_rad, mean, rtol=1e-12)
                seen_value = True
    # The windows of [-100, -50] ms hold 51 samples where the table moves.
    assert block.stops[0].windows[0].valid_samples == 51
    assert seen_none and seen_value  # the last 15 ms before a slow stop: nothing valid


def test_summary_round_trips_through_json(runs: dict[str, Any]) -> None:
    run: Path = runs["clean_run"]
    text = (run / "summary.json").read_text()
    data = json.loads(text)
    assert list(data)[-1] == "deformation"
    assert data["deformation"]["stops"][0]["kind"] == "reversal"
    summary = RunSummary.from_json(text)
    assert summary == runs["clean"]
    assert summary.to_json() == text
    assert RunSummary.from_json(summary.to_json()) == summary
    # An older summary without the block still reads.
    del data["deformation"]
    assert RunSummary.from_dict(data).deformation is None


def test_text_shows_the_block(runs: dict[str, Any]) -> None:
    text = format_summary(runs["clean"])
    assert f"deformation d_r   p = {P} samples, min rotation {MIN_ROT:g} rad" in text
    lines = text.splitlines()
    rows = [line for line in lines if line.strip().startswith(("0.5000", "0.9000", "1.1000"))]
    assert [r.split()[1] for r in rows] == ["reversal", "non_reversal", "reversal"]
    assert any("final" in line and "1.3000" in line for line in lines)


def test_plots_are_written(runs: dict[str, Any], tmp_path: Path) -> None:
    run: Path = runs["clean_run"]
    paths = plot(run)
    assert run / DEFORMATION_FIGURE in paths
    assert (run / DEFORMATION_FIGURE).read_bytes()[:8] == PNG_MAGIC
    detail = plot_reversal_detail(run, 1.1, tmp_path / "detail.png")
    assert detail.read_bytes()[:8] == PNG_MAGIC
    with pytest.raises(ConfigError, match="t_stop"):
        plot_reversal_detail(run, 99.0, tmp_path / "none.png")


def test_the_series_the_summary_read_is_what_the_run_directory_reads_back(
    runs: dict[str, Any], tmp_path: Path
) -> None:
    """What the runner hands the figures (the summary's signals) is run_series of the
    run directory, array for array, and the figures from it are the same bytes."""
    run: Path = runs["clean_run"]
    path = run / "scenario.yaml"
    given = summarise_series(
        run, scenario=load_scenario(path), scenario_path=path, wall_time_s=1.0, mode="processes"
    )
    read = run_series(run)
    assert given.summary == read.summary
    assert given.lead_m_per_rad == read.lead_m_per_rad
    assert_array_equal(given.target_rad, read.target_rad)
    assert_array_equal(given.y_rad, read.y_rad)
    assert_array_equal(given.signals.step, read.signals.step)
    assert_trace_equal(given.signals.deformation, RUN.trace)
    assert given.signals.counts == read.signals.counts
    figures = {p.name: p.read_bytes() for p in plot(run)}
    assert {p.name: p.read_bytes() for p in plot(run, series=given)} == figures
