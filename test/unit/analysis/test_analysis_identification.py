"""Analysis of paper 003 runs: the identification block, RMSD in rad, plots and `compare`.

Synthetic bags of a tilting table (``lead_m_per_rad: 1``, axis ``tilt``) are
written with the project's bag writer (CDR made with rosbags, no rclpy):
``state``, ``reference`` and ``command`` on every step with a known tracking
error, and for an identifier run ``identifier/estimates`` every 4 steps with
known ``J, D, U, C``, kappa and update flags. Every expected number is
computed here from those arrays with numpy, independently of the analysis.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.plots import IDENTIFICATION_FIGURES, plot
from servo_axis.analysis.signals import load_signals
from servo_axis.analysis.summary import RunSummary, load_summary, summarise
from servo_axis.analysis.text import format_summary, rmsd_applies
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.writer import BagWriter
from servo_axis.wire.cdr import ESTIMATE_LABELS

JOINT_STATE = "sensor_msgs/msg/JointState"
MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

PERIOD_S = 0.001
PERIOD_NS = 1_000_000
N = 1500  # 1.5 s: three periods of the 2 Hz reference
FREQ_HZ = 2.0  # reference period 0.5 s = 500 steps
RLS = 4  # an estimate at each step k with k % 4 == 3
LATENCY = 5  # applies from k + 5
# The plant's true values: J and U set in the scenario, D and C its defaults (003 Table I).
TRUE = {"inertia_kgm2": 6e-3, "damping_Nms_per_rad": 130e-4, "unbalance_Nm": 0.25}
TRUE_ALL = np.array([6e-3, 130e-4, 0.25, 0.02])
AXIS = "tilt"
NAMES = ["tilt_motor", "tilt_table"]
MOTOR = ["tilt_motor"]
ESTIMATES = f"/{AXIS}/identifier/estimates"


class Cdr:
    """CDR payloads made with rosbags' typestore."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_JAZZY)
        self.t = self.ts.types

    def joint_state(self, k: int, names: list[str], **fields: list[float]) -> bytes:
        ns = k * PERIOD_NS
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

    def multi_array(self, labels: tuple[str, ...] | str, data: list[float]) -> bytes:
        """One dimension per field of size 1 (the project's layout); a str: one dimension."""
        fields = [(labels, len(data))] if isinstance(labels, str) else [(lb, 1) for lb in labels]
        dims = [
            self.t["std_msgs/msg/MultiArrayDimension"](label=lb, size=size, stride=size)
            for lb, size in fields
        ]
        layout = self.t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = self.t[MULTI_ARRAY](layout=layout, data=np.array(data, dtype=np.float64))
        return bytes(self.ts.serialize_cdr(msg, MULTI_ARRAY))


CDR = Cdr()


@dataclass(frozen=True)
class Truth:
    """What a synthetic run holds: per step the error, per estimate its values."""

    error_rad: np.ndarray  # r - y per step 0..N-1
    est_step: np.ndarray  # the clean estimates' steps
    est: np.ndarray  # (n, 4) J, D, U, C
    kappa: np.ndarray
    updated: np.ndarray  # (n, 4) bool


def target(k: np.ndarray) -> np.ndarray:
    t = k * PERIOD_S
    return 0.6 + 0.5 * np.sin(2 * np.pi * FREQ_HZ * t - np.pi / 2)


def make_truth(error_amplitude: float, seed: int) -> Truth:
    k = np.arange(N)
    t = k * PERIOD_S
    error = error_amplitude * (np.sin(2 * np.pi * 7.0 * t) + 0.3 * np.cos(2 * np.pi * 1.3 * t))
    est_step = np.arange(RLS - 1, N, RLS)
    te = est_step * PERIOD_S
    decay = np.exp(-te / 0.4)
    est = np.column_stack(
        [
            TRUE_ALL[i] * (1.0 + (0.6 - 0.2 * i) * decay + 0.01 * np.sin(2 * np.pi * (i + 1) * te))
            for i in range(4)
        ]
    )
    kappa = np.where(te < 0.1, 0.0, 1e-3 * (1.0 + te))
    updated = np.random.default_rng(seed).random((est_step.size, 4)) < 0.6
    return Truth(error, est_step, est, kappa, updated)


def estimate_values(truth: Truth, i: int) -> list[float]:
    step = int(truth.est_step[i])
    return [
        float(step),
        float(step + LATENCY),
        *(float(v) for v in truth.est[i]),
        float(truth.kappa[i]),
        *(1.0 if u else 0.0 for u in truth.updated[i]),
    ]


def write_scenario(path: Path, name: str, *, identifier: bool) -> Path:
    data: dict[str, Any] = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": name, "description": "synthetic 003 run"},
                "control_period_s": PERIOD_S,
                "duration_s": N * PERIOD_S,
                "axis": AXIS,
                "lead_m_per_rad": 1.0,
            }
        },
        "plant": {"ros__parameters": {"model": "tilting_table", **TRUE}},
        "feedback": {"ros__parameters": {}},
        "feedforward": {
            "ros__parameters": {
                "reference": {
                    "kind": "sine",
                    "amplitude_m": 0.5,
                    "frequency_hz": FREQ_HZ,
                    "offset_m": 0.6,
                    "phase_rad": -math.pi / 2,
                }
            }
        },
    }
    if identifier:
        data["identifier"] = {"ros__parameters": {"method": "dlpid"}}
    path.write_text(yaml.safe_dump(data))
    return path


def write_bag(bag_dir: Path, truth: Truth, estimates: list[tuple[int, bytes]] | None) -> None:
    """The run's bag: per step reference, state and command, then the
    ``estimates`` ``(step, payload)`` recorded at that step, in list order
    (None: no estimates topic)."""
    r = target(np.arange(N))
    y = r - truth.error_rad
    by_step: dict[int, list[bytes]] = {}
    for step, data in estimates or []:
        by_step.setdefault(step, []).append(data)
    with BagWriter(bag_dir) as bag:
        for topic in ("state", "reference", "command"):
            bag.add_topic(f"/{AXIS}/{topic}", JOINT_STATE)
        if estimates is not None:
            bag.add_topic(ESTIMATES, MULTI_ARRAY)
        for k in range(N):
            ns = k * PERIOD_NS
            ref = CDR.joint_state(k, MOTOR, position=[r[k]], velocity=[0.0], effort=[0.0])
            bag.write(f"/{AXIS}/reference", ref, log_time_ns=ns)
            state = CDR.joint_state(
                k, NAMES, position=[y[k], y[k]], velocity=[0.0, 0.0], effort=[0.0, 0.0]
            )
            bag.write(f"/{AXIS}/state", state, log_time_ns=ns)
            bag.write(f"/{AXIS}/command", CDR.joint_state(k, MOTOR, effort=[0.1]), log_time_ns=ns)
            for data in by_step.get(k, []):
                bag.write(ESTIMATES, data, log_time_ns=ns)


def clean_estimates(truth: Truth) -> list[tuple[int, bytes]]:
    return [
        (int(step), CDR.multi_array(ESTIMATE_LABELS, estimate_values(truth, i)))
        for i, step in enumerate(truth.est_step)
    ]


def with_junk(truth: Truth) -> tuple[list[tuple[int, bytes]], int, int]:
    """The clean estimates with junk and repeats interleaved: (messages, junk, repeats)."""
    out = clean_estimates(truth)
    i = 40  # an estimate in the middle of the run
    good = estimate_values(truth, i)
    step = int(truth.est_step[i])
    nan = list(good)
    nan[2] = math.nan
    same_step = list(good)
    same_step[1] = good[0]  # applies_from == step
    before = list(good)
    before[1] = good[0] - 3  # applies_from < step
    beyond = list(good)
    beyond[0], beyond[1] = float(N + 3), float(N + 8)  # after the run's last step
    zero_j = list(good)
    zero_j[2] = 0.0
    other = list(good)
    other[4] *= 2.0  # the same step as a kept estimate, other values
    junk = [
        CDR.multi_array(ESTIMATE_LABELS, nan),
        CDR.multi_array(ESTIMATE_LABELS, good[:-1]),  # one value short
        CDR.multi_array(ESTIMATE_LABELS, [*good, 0.0]),  # one value too many
        CDR.multi_array(ESTIMATE_LABELS, same_step),
        CDR.multi_array(ESTIMATE_LABELS, before),
        CDR.multi_array(ESTIMATE_LABELS, beyond),
        CDR.multi_array(ESTIMATE_LABELS, zero_j),
        CDR.multi_array("step,applies_from_step", good),  # wrong labels
        CDR.multi_array(ESTIMATE_LABELS, other),  # recorded after the real one
        b"",
    ]
    repeat = out[i][1]  # a restarted identifier publishes its last estimate again
    last_repeat = out[-1][1]
    messages = out[: i + 1] + [(step, m) for m in junk] + [(step, repeat)] + out[i + 1 :]
    messages.append((N - 1, last_repeat))
    return messages, len(junk), 2


def make_run(
    root: Path,
    name: str,
    truth: Truth,
    *,
    identifier: bool,
    estimates: list[tuple[int, bytes]] | None,
) -> tuple[Path, RunSummary]:
    run = root / name
    run.mkdir(parents=True)
    path = write_scenario(run / "scenario.yaml", name, identifier=identifier)
    write_bag(run / "bag", truth, estimates)
    summary = summarise(
        run, scenario=load_scenario(path), scenario_path=path, wall_time_s=1.0, mode="processes"
    )
    return run, summary


def expected_identification(truth: Truth) -> dict[str, Any]:
    """The numbers of the identification block, computed with numpy."""
    last = truth.est[-1]
    t = truth.est_step * PERIOD_S
    window = t > t[-1] - 1.0 / FREQ_HZ + PERIOD_S / 2  # the last 0.5 s of estimate steps
    return {
        "final": last,
        "ratio": last / TRUE_ALL,
        "p2p": np.ptp(truth.est[window], axis=0),
        "kappa": truth.kappa[-1],
        "updates": truth.updated.sum(axis=0),
        "window": int(np.count_nonzero(window)),
    }


def rmsd(truth: Truth) -> float:
    return float(np.sqrt(np.mean(truth.error_rad**2)))


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("ident")
    truth = make_truth(2e-3, seed=3)
    junky, junk, repeats = with_junk(truth)
    clean_run, clean = make_run(
        root, "t_clean", truth, identifier=True, estimates=clean_estimates(truth)
    )
    junk_run, dirty = make_run(root, "t_junk", truth, identifier=True, estimates=junky)
    return {
        "truth": truth,
        "clean": clean,
        "clean_run": clean_run,
        "dirty": dirty,
        "junk_run": junk_run,
        "junk": junk,
        "repeats": repeats,
        "root": root,
    }


def test_identification_block_against_numpy(runs: dict[str, Any]) -> None:
    truth: Truth = runs["truth"]
    ident = runs["clean"].identification
    assert ident is not None
    want = expected_identification(truth)
    assert want["window"] == 125  # 0.5 s of estimates every 4 ms
    assert ident.estimates == truth.est_step.size
    assert (ident.repeated, ident.dropped) == (0, 0)
    assert (ident.first_step, ident.last_step) == (3, N - 1)
    assert_allclose(ident.true.values(), TRUE_ALL, rtol=1e-15)  # D, C: the schema's defaults
    assert_allclose(ident.final.values(), want["final"], rtol=1e-15)
    assert_allclose(ident.final_ratio.values(), want["ratio"], rtol=1e-12)
    assert ident.last_period_s == pytest.approx(1.0 / FREQ_HZ, rel=1e-12)
    assert_allclose(ident.last_period_p2p.values(), want["p2p"], rtol=1e-12)
    assert_allclose(ident.final_kappa, want["kappa"], rtol=1e-15)
    counts = ident.updates
    assert [
        counts.inertia_kgm2,
        counts.damping_Nms_per_rad,
        counts.unbalance_Nm,
        counts.coulomb_Nm,
    ] == want["updates"].tolist()


def test_rmsd_in_rad_over_the_whole_run(runs: dict[str, Any]) -> None:
    truth: Truth = runs["truth"]
    s: RunSummary = runs["clean"]
    assert s.error_unit == "rad" and s.unit == "rad"
    assert_allclose(s.rmsd, rmsd(truth), rtol=1e-9)
    assert_allclose(s.tracking_error.all_samples.rms_m, rmsd(truth), rtol=1e-9)
    assert_allclose(s.tracking_error.all_samples.max_m, np.max(np.abs(truth.error_rad)), rtol=1e-9)
    text = format_summary(s)
    assert "tracking error (rad)" in text and "urad" not in text
    assert (
        "error unit        rad of table angle (rotary table); RMSD = RMS over all samples" in text
    )
    row = next(x for x in text.splitlines() if x.startswith("  all samples"))
    assert_allclose(
        [float(x) for x in row.split()[2:]],
        [rmsd(truth), np.max(np.abs(truth.error_rad))],
        rtol=1e-5,
    )
    assert f"identification    {truth.est_step.size} estimates (steps 3 to {N - 1})" in text


def test_summary_json_has_the_block_and_round_trips(runs: dict[str, Any]) -> None:
    run: Path = runs["clean_run"]
    data = json.loads((run / "summary.json").read_text())
    assert data["error_unit"] == "rad"
    assert list(data["identification"]) == [
        "estimates",
        "repeated",
        "dropped",
        "first_step",
        "last_step",
        "final",
        "true",
        "final_ratio",
        "last_period_s",
        "last_period_p2p",
        "final_kappa",
        "updates",
    ]
    assert list(data["identification"]["final"]) == [
        "inertia_kgm2",
        "damping_Nms_per_rad",
        "unbalance_Nm",
        "coulomb_Nm",
    ]
    assert load_summary(run) == runs["clean"]


def test_junk_and_repeats_change_no_estimate(runs: dict[str, Any]) -> None:
    clean, dirty = runs["clean"].identification, runs["dirty"].identification
    assert clean is not None and dirty is not None
    assert dirty.dropped == runs["junk"] == 10
    assert dirty.repeated == runs["repeats"] == 2
    # Everything else is the clean run's, to the bit.
    assert dirty.estimates == clean.estimates
    assert dirty.final == clean.final and dirty.last_period_p2p == clean.last_period_p2p
    assert dirty.updates == clean.updates and dirty.final_kappa == clean.final_kappa
    # The signals count junk the way they count other topics' junk.
    scenario = load_scenario(runs["junk_run"] / "scenario.yaml")
    sig = load_signals(runs["junk_run"] / "bag", PERIOD_S, scenario=scenario)
    assert sig.dropped[ESTIMATES] == 10 and sig.repeated == {ESTIMATES: 2}
    truth: Truth = runs["truth"]
    assert [e.step for e in sig.estimates] == truth.est_step.tolist()
    # The differing duplicate was recorded after the real estimate: the real one is kept.
    assert_allclose(sig.estimates[40].unbalance_Nm, truth.est[40, 2], rtol=0)


def test_estimates_recorded_out_of_order_are_ordered_by_step(tmp_path: Path) -> None:
    truth = make_truth(1e-3, seed=5)
    msgs = clean_estimates(truth)
    # Swap two estimates' recording places (e.g. after a restart): still by step.
    shuffled = [*msgs[:10], (msgs[12][0], msgs[11][1]), (msgs[12][0], msgs[10][1]), *msgs[12:]]
    _, s = make_run(tmp_path, "t_order", truth, identifier=True, estimates=shuffled)
    assert s.identification is not None
    assert s.identification.estimates == truth.est_step.size
    assert s.identification.dropped == 0
    assert_allclose(s.identification.final.values(), truth.est[-1], rtol=0)


def test_no_block_without_an_identifier_even_with_a_strangers_estimates(tmp_path: Path) -> None:
    truth = make_truth(1e-3, seed=5)
    run, s = make_run(tmp_path, "t_pid", truth, identifier=False, estimates=None)
    assert s.identification is None
    assert "identification" not in json.loads((run / "summary.json").read_text())
    run2, s2 = make_run(
        tmp_path, "t_pid2", truth, identifier=False, estimates=clean_estimates(truth)[:5]
    )
    assert s2.identification is None
    sig = load_signals(run2 / "bag", PERIOD_S, scenario=load_scenario(run2 / "scenario.yaml"))
    assert sig.estimates == () and sig.dropped[ESTIMATES] == 5
    assert_allclose(s2.rmsd, rmsd(truth), rtol=1e-9)


def test_plots_of_an_identifier_run(runs: dict[str, Any], tmp_path: Path) -> None:
    paths = plot(runs["clean_run"])
    names = [p.name for p in paths]
    for name in IDENTIFICATION_FIGURES:
        assert name in names
        assert (runs["clean_run"] / name).read_bytes()[:8] == PNG_MAGIC
    pid_run, _ = make_run(tmp_path, "t_pid", make_truth(1e-3, 1), identifier=False, estimates=None)
    assert not set(IDENTIFICATION_FIGURES) & {p.name for p in plot(pid_run)}


def parse_rmsd_table(text: str) -> dict[str, list[str]]:
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("RMSD of the tracking error"))
    rows = {}
    for line in lines[start + 2 :]:
        if not line.strip() or line.startswith("figure written"):
            break
        cells = line.split()
        rows[cells[0]] = cells[1:]
    return rows


@pytest.fixture(scope="module")
def schemes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Three runs of 003 Fig. 9: PID (no identifier), previous MARC and the proposal."""
    root = tmp_path_factory.mktemp("schemes")
    out: dict[str, Any] = {}
    for name, amp, ident in (
        ("dlpid_tilt_marc", 4e-4, True),
        ("dlpid_tilt_lpf2", 1e-4, True),
        ("dlpid_tilt_pid", 5e-3, False),
    ):
        truth = make_truth(amp, seed=len(name))
        estimates = clean_estimates(truth) if ident else None
        run, summary = make_run(root, name, truth, identifier=ident, estimates=estimates)
        out[name] = (run, summary, truth)
    return out


def test_compare_prints_rmsd_and_reduction_against_pid(
    schemes: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from servo_axis.__main__ import main
    from servo_axis.analysis import plots

    order = ["dlpid_tilt_marc", "dlpid_tilt_lpf2", "dlpid_tilt_pid"]
    chart, error = tmp_path / "fig9.png", tmp_path / "error.png"
    dirs = [str(schemes[n][0]) for n in order]
    kept: list[Any] = []  # the figures, read from matplotlib's objects
    monkeypatch.setattr(plots._pyplot(), "close", kept.append)
    assert main(["compare", *dirs, "--bar-chart", str(chart), "--error-out", str(error)]) == 0
    monkeypatch.undo()
    text = capsys.readouterr().out
    assert "reduction against dlpid_tilt_pid" in text  # the scenario ending in _pid
    # A rotary table's error in rad, in the table and on the chart (issue 43: urad, mrad).
    assert "RMSD of the tracking error over the whole run (rad)" in text
    assert "RMSD (rad)" in text and "urad" not in text
    (bars,) = kept[0].axes
    assert bars.get_ylabel() == "RMSD of tracking error (rad)"
    heights = [p.get_height() for p in bars.patches]
    assert_allclose(heights, [rmsd(schemes[n][2]) for n in order], rtol=1e-9)
    # The error against time: rad too, r - y of each run.
    whole = kept[1].axes[0]
    assert whole.get_ylabel() == "tracking error (rad)"
    for line, name in zip(whole.get_lines(), order, strict=True):
        assert_allclose(line.get_ydata(), schemes[name][2].error_rad, rtol=1e-9, atol=1e-15)
    for fig in kept:
        plots._pyplot().close(fig)
    rows = parse_rmsd_table(text)
    assert list(rows) == order
    base = rmsd(schemes["dlpid_tilt_pid"][2])
    for name in order:
        truth = schemes[name][2]
        assert_allclose(float(rows[name][0]), rmsd(truth), rtol=1e-5)
        if name == "dlpid_tilt_pid":
            assert rows[name][1:] == ["base", "-", "-", "-", "-"]
            continue
        assert_allclose(float(rows[name][1]), 100 * (1 - rmsd(truth) / base), atol=0.006)
        assert_allclose([float(x) for x in rows[name][2:]], truth.est[-1] / TRUE_ALL, rtol=1e-4)
    assert chart.read_bytes()[:8] == PNG_MAGIC
    assert f"figure written to {chart}" in text


def test_compare_baseline_by_label_else_the_first(
    schemes: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    from servo_axis.__main__ import main

    dirs = [str(schemes[n][0]) for n in ("dlpid_tilt_lpf2", "dlpid_tilt_pid", "dlpid_tilt_marc")]
    assert main(["compare", *dirs, "--labels", "prop,pid,marc"]) == 0
    rows = parse_rmsd_table(capsys.readouterr().out)
    assert rows["pid"][1] == "base"
    base = rmsd(schemes["dlpid_tilt_pid"][2])
    prop = rmsd(schemes["dlpid_tilt_lpf2"][2])
    assert_allclose(float(rows["prop"][1]), 100 * (1 - prop / base), atol=0.006)
    # Without a pid run the first is the baseline.
    assert main(["compare", dirs[0], dirs[2], "--labels", "prop,marc"]) == 0
    out = capsys.readouterr().out
    rows = parse_rmsd_table(out)
    assert "reduction against prop" in out and rows["prop"][1] == "base"
    marc = rmsd(schemes["dlpid_tilt_marc"][2])
    assert_allclose(float(rows["marc"][1]), 100 * (1 - marc / prop), atol=0.006)


def learning_like(rms_scale: float) -> RunSummary:
    step = np.arange(1000)
    e = rms_scale * 1e-6 * np.sin(2 * np.pi * step / 250)
    stats = error_statistics(e, step, period_s=1e-3, cycle_s=0.25)
    return RunSummary.from_dict(
        {
            "scenario": "rptc_demo",
            "description": "",
            "scenario_file": "/s/rptc_demo.yaml",
            "processes": "processes",
            "time_mode": "lockstep",
            "control_period_s": 0.001,
            "steps": 1000,
            "sim_time_s": 1.0,
            "wall_time_s": 0.5,
            "steps_per_s": 2000.0,
            "realtime_factor": 2.0,
            "message_counts": {},
            "faults": [],
            "ptc": True,
            "friction_table": False,
            "reference_period_s": 0.25,
            "tracking_error": stats,
        }
    )


def test_learning_runs_keep_the_per_cycle_compare(
    schemes: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from servo_axis.__main__ import main

    a, b = learning_like(2.0), learning_like(1.0)
    assert not rmsd_applies([a, b])
    assert rmsd_applies([schemes["dlpid_tilt_pid"][1]])  # a rotary table
    dirs = []
    for name, s in (("q", a), ("q5", b)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "summary.json").write_text(s.to_json())
        dirs.append(str(tmp_path / name))
    assert main(["compare", *dirs]) == 0
    out = capsys.readouterr().out
    assert out.startswith("max tracking error per cycle (um)") and "RMSD" not in out
    # --rmsd asks for the RMSD table of any runs.
    assert main(["compare", *dirs, "--rmsd"]) == 0
    rows = parse_rmsd_table(capsys.readouterr().out)
    assert_allclose(float(rows["q5"][0]), 1e6 * b.rmsd, rtol=1e-5)
    assert_allclose(float(rows["q5"][1]), 50.0, atol=0.006)  # half the RMS of the first
    # Errors in m and in rad do not compare.
    assert main(["compare", dirs[0], str(schemes["dlpid_tilt_pid"][0]), "--rmsd"]) == 2
    assert "different units (m, rad)" in capsys.readouterr().err
