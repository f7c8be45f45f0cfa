"""Every command's bad input: one line on stderr naming it, exit 2, nothing created.

One table (:data:`CASES`) over every command and option of ``python -m
servo_axis``: wrong types, missing files, NaN, numbers out of range, unknown
names (each with the closest one), bad ``--set``, directories that are not
the runs a command needs. Each case runs the command line's ``main`` in this
process, in a working directory of its own inputs (``runs/`` and
``studies/``, where ``run`` and ``sweep`` write by default, are under it),
and checks: exit 2, nothing on stdout, exactly one line on stderr, starting
``error: `` and naming what is wrong, and the working directory exactly as
it was (no file or folder made, none changed). A case that got through
would start nodes, a floor or a study: those are replaced by a failure, so
that no case starts ROS. :func:`test_the_command_line_says_the_same` runs
some of the cases as ``python -m servo_axis`` processes: the same line and
exit code.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from servo_axis.__main__ import main
from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.summary import AxesSummary, RunSummary, summarise
from servo_axis.params.scenario import find_scenario, load_scenario, scenario_names
from servo_axis.recording.writer import BagWriter

PERIOD_S = 0.001
LEAD = 0.002
JOINT_STATE = "sensor_msgs/msg/JointState"


# ------------------------------------------------------------------ the inputs


def summary_of(cycle_s: float = 0.25) -> dict[str, Any]:
    """A single-axis summary (1 s at 1 ms, a 1 um sine of the cycle) as JSON data."""
    step = np.arange(1000)
    e = 1e-6 * np.sin(2 * np.pi * step * PERIOD_S / cycle_s)
    return {
        "scenario": "demo",
        "description": "",
        "scenario_file": "/nonexistent/demo.yaml",
        "processes": "separate processes",
        "time_mode": "lockstep",
        "control_period_s": PERIOD_S,
        "steps": 1000,
        "sim_time_s": 1.0,
        "wall_time_s": 0.5,
        "steps_per_s": 2000.0,
        "realtime_factor": 2.0,
        "message_counts": {},
        "faults": [],
        "ptc": True,
        "friction_table": False,
        "reference_period_s": cycle_s,
        "tracking_error": error_statistics(e, step, period_s=PERIOD_S, cycle_s=cycle_s),
    }


def recorded_run(work: Path, name: str, reference_rad: np.ndarray, torque_Nm: np.ndarray) -> None:
    """A run directory of ``reference_rad`` and the command ``torque_Nm`` (bag, summary.json, scenario.yaml)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    t = ts.types

    def joint(step: int, names: list[str], **fields: list[float]) -> bytes:
        ns = round(step * PERIOD_S * 1e9)
        stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        msg = t[JOINT_STATE](
            header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
            name=names,
            position=np.array(fields.get("position", []), dtype=np.float64),
            velocity=np.array(fields.get("velocity", []), dtype=np.float64),
            effort=np.array(fields.get("effort", []), dtype=np.float64),
        )
        return bytes(ts.serialize_cdr(msg, JOINT_STATE))

    run = work / name
    with BagWriter(run / "bag") as bag:
        for topic in ("state", "reference", "command"):
            bag.add_topic(topic, JOINT_STATE)
        for i, (r, tq) in enumerate(zip(reference_rad.tolist(), torque_Nm.tolist(), strict=True)):
            ref = joint(i, ["x_motor"], position=[r], velocity=[0.0], effort=[0.0])
            bag.write("reference", ref, log_time_ns=3 * i)
            state = joint(
                i,
                ["x_motor", "x_table"],
                position=[r, r * LEAD],
                velocity=[0.0] * 2,
                effort=[0.0] * 2,
            )
            bag.write("state", state, log_time_ns=3 * i + 1)
            bag.write("command", joint(i, ["x_motor"], effort=[tq]), log_time_ns=3 * i + 2)
    scenario = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": name, "description": "a recorded run"},
                "control_period_s": PERIOD_S,
                "lead_m_per_rad": LEAD,
                "nominal": {"inertia_kgm2": 0.01, "damping_Nms_per_rad": 0.1},
            }
        },
        "plant": {"ros__parameters": {}},
        "feedback": {"ros__parameters": {}},
        "feedforward": {
            "ros__parameters": {
                "reference": {"kind": "sine", "frequency_hz": 2.0, "amplitude_m": 0.005},
                "ptc": {"enabled": False},
            }
        },
    }
    # The scenario as a run records it, where later commands read it.
    path = run / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    summarise(run, scenario=load_scenario(path), scenario_path=path, wall_time_s=1.0, mode="x")


def scenario_file(path: Path, edit: dict[str, Any] | None = None, drop: str = "") -> None:
    """ptc_nominal, with the sections of ``edit`` merged in and ``drop`` left out."""
    data = load_scenario(find_scenario("ptc_nominal"))
    for section, params in (edit or {}).items():
        data.setdefault(section, {"ros__parameters": {}})["ros__parameters"].update(params)
    data.pop(drop, None)
    path.write_text(yaml.safe_dump(data))


def study_file(path: Path, **changes: Any) -> None:
    study = {
        "scenario": "ptc_nominal",
        "set": {"/**.duration_s": 0.5},
        "grid": {"feedback.bandwidth_hz": [30, 40]},
        "figures": ["tracking_error.all_samples.max_m"],
    }
    study.update(changes)
    path.write_text(yaml.safe_dump({k: v for k, v in study.items() if v is not None}))


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The working directory of every case, with the inputs the cases name."""
    w = tmp_path_factory.mktemp("bad_inputs")
    (w / "notarun").mkdir()
    for name, text in {"junk": "{not json", "partial": '{"steps": 3}'}.items():
        (w / name).mkdir()
        (w / name / "summary.json").write_text(text)
    for name, cycle in {"run_a": 0.25, "run_b": 0.5}.items():
        (w / name).mkdir()
        (w / name / "summary.json").write_text(json.dumps(summary_of(cycle)))
    (w / "multi").mkdir()
    axes = {"x": summary_of(), "y": summary_of()}
    multi = AxesSummary.from_dict(
        {"scenario": "xy", "description": "", "wall_time_s": 1.0, "axes": axes}
    )
    (w / "multi" / "summary.json").write_text(multi.to_json())
    for axis in axes:
        (w / "multi" / axis).mkdir()
        (w / "multi" / axis / "summary.json").write_text(RunSummary.from_dict(axes[axis]).to_json())
    # A 10 mm, 2 Hz sine whose command is the nominal model's torque: no friction in it.
    k = np.arange(1000)
    ref = 0.005 / LEAD * np.sin(2 * np.pi * 2.0 * k * PERIOD_S)
    vel, acc = np.gradient(ref, PERIOD_S), np.gradient(np.gradient(ref, PERIOD_S), PERIOD_S)
    recorded_run(w, "fast", ref, 0.01 * acc + 0.1 * vel)
    recorded_run(w, "still", np.zeros(1000), 0.3 + 0.01 * np.sin(0.7 * k))
    scenario_file(w / "feedbak.yaml", {"feedbak": {"bandwidth_hz": 30.0}})
    scenario_file(w / "bandwith.yaml", {"feedback": {"bandwith_hz": 30.0}})
    scenario_file(w / "noplant.yaml", drop="plant")
    scenario_file(w / "nan.yaml", {"plant": {"duration_s": float("nan")}})
    (w / "broken.yaml").write_text("plant:\n  ros__parameters:\n    duration_s: [1.0, 2.0\n")
    (w / "list.yaml").write_text("- plant\n- feedback\n")
    (w / "junk.jsonl").write_text('{"period_us": 1000}\n')
    (w / "notjson.jsonl").write_text("misses: 3\n")
    (w / "empty.jsonl").write_text("\n")
    (w / "afile").write_text("x")
    (w / "full").mkdir()
    (w / "full" / "something").write_text("x")
    study_file(w / "study.yaml")
    study_file(w / "grd.yaml", grid=None, grd={"feedback.bandwidth_hz": [30, 40]})
    study_file(w / "figure.yaml", figures=["tracking_eror.all_samples.max_m"])
    study_file(w / "scenario_typo.yaml", scenario="ptc_nominl")
    study_file(w / "key_typo.yaml", grid={"feedbak.bandwidth_hz": [30, 40]})
    return w


# ------------------------------------------------------------------ the cases

R = ["run", "ptc_nominal", "--out", "runs/ptc"]  # a run that would write under runs/
XY = ["run", "xy_circle", "--out", "runs/xy"]
N_SCENARIOS = len(scenario_names())

#: (argv, what the line must say).
CASES: list[tuple[list[str], str]] = [
    # -- the command line itself
    (["runn"], "invalid choice: 'runn'; did you mean 'run'?"),
    (["lst"], "invalid choice: 'lst'; did you mean 'list'?"),
    (
        ["--domain-id", "130"],
        "--domain-id is an option of run and floor, not of python -m servo_axis itself",
    ),
    (
        ["--domainid", "3"],
        "no command has the option --domainid (did you mean --domain-id, an option",
    ),
    (["--ticks", "5"], "--ticks is an option of floor"),
    (["bag"], "the following arguments are required: BAG_COMMAND"),
    (["bag", "recovr", "x"], "invalid choice: 'recovr'; did you mean 'recover'?"),
    # -- run: the scenario
    (["run"], "the following arguments are required: scenario"),
    (
        ["run", "ptc_nominl"],
        "'ptc_nominl': neither a file nor a shipped scenario; did you mean 'ptc_nominal'",
    ),
    (["run", "no_such_thing"], f"`python -m servo_axis list` shows the {N_SCENARIOS} shipped ones"),
    (["run", "missing.yaml"], "scenario missing.yaml: no such file"),
    (["run", "nodir/x.yaml"], "scenario nodir/x.yaml: no such file (no directory nodir)"),
    (["run", "notarun"], "scenario notarun: is a directory"),
    (["run", "broken.yaml"], "broken.yaml: not valid YAML: expected ',' or ']'"),
    (["run", "list.yaml"], "list.yaml: expected a mapping of node sections"),
    (["run", "feedbak.yaml"], "unknown section 'feedbak'; did you mean 'feedback'?"),
    (
        ["run", "bandwith.yaml"],
        "unknown parameter 'bandwith_hz' for node 'feedback' (did you mean 'bandwidth_hz'?)",
    ),
    (["run", "noplant.yaml"], "noplant.yaml: a 'plant' section is required"),
    (["run", "nan.yaml"], "parameter 'duration_s': expected a finite number, got nan"),
    # -- run: its options
    ([*R, "--domain-id", "233"], "argument --domain-id: 233 is outside 0..232"),
    ([*R, "--domain-id", "x"], "argument --domain-id: 'x' is not an integer"),
    (
        [*R, "--namespace", "bad-name"],
        "argument --namespace: 'bad-name' is not a valid ROS namespace",
    ),
    ([*R, "--namespace", "/a//b"], "'/a//b' is not a valid ROS namespace"),
    ([*R, "--respawn-limit", "-1"], "argument --respawn-limit: '-1': expected an integer >= 0"),
    (
        [*R, "--external-timeout", "nan"],
        "argument --external-timeout: 'nan': expected a finite number > 0",
    ),
    ([*R, "--external-timeout", "0"], "'0': expected a finite number > 0"),
    ([*R, "--live-port", "70000"], "argument --live-port: '70000': expected an integer 1..65535"),
    (
        [*R, "--external", "plnt"],
        "--external plnt: expected one of plant, feedback, feedforward, learning, identifier; "
        "did you mean 'plant'?",
    ),
    ([*R, "--external", "learning"], "--external learning: the scenario has no learning section"),
    (
        [*R, "--external", "plant", "--composed"],
        "--external: a run with outside nodes runs as separate processes",
    ),
    ([*XY, "--composed"], "a multi-axis scenario runs as separate processes"),
    ([*R, "--floor", "missing.jsonl"], "--floor missing.jsonl: cannot read it"),
    (
        [*R, "--floor", "junk.jsonl"],
        "--floor junk.jsonl: line 1 is not a result of `python -m servo_axis floor --json` "
        "(no miss_pct, round_trip_us)",
    ),
    ([*R, "--floor", "notjson.jsonl"], "--floor notjson.jsonl: line 1 is not a result"),
    ([*R, "--floor", "empty.jsonl"], "--floor empty.jsonl: no result"),
    (["run", "ptc_nominal", "--out", "afile"], "/afile: exists and is not a directory"),
    (["run", "ptc_nominal", "--out", "full"], "/full: exists and is not empty"),
    (
        [*R, "--duration", "1"],
        "unrecognized arguments: --duration 1 (a key of the scenario? --set "
        "shared.duration_s=VALUE)",
    ),
    ([*R, "--no-plts"], "did you mean --no-plots?"),
    # -- run --set
    (
        [*R, "--set", "feedbak.bandwidth_hz=30"],
        "'feedbak.bandwidth_hz=30': unknown section 'feedbak'; did you mean 'feedback'?",
    ),
    ([*R, "--set", "plant.duration_s"], "'plant.duration_s': expected SECTION.KEY=VALUE"),
    (
        [*R, "--set", "duration_s=1"],
        "'duration_s=1': expected SECTION.KEY=VALUE, the key after its section",
    ),
    ([*R, "--set", "feedback.bandwidth_hz="], "'feedback.bandwidth_hz=': no value after '='"),
    (
        [*R, "--set", "feedback.bandwidth_hz=[1"],
        "'feedback.bandwidth_hz=[1': the value is not YAML",
    ),
    (
        [*R, "--set", "feedback.bandwith_hz=30"],
        "--set feedback.bandwith_hz=30: unknown parameter 'bandwith_hz' for node 'feedback' "
        "(did you mean 'bandwidth_hz'?)",
    ),
    (
        [*R, "--set", "feedback.bandwidth_hz=abc"],
        "--set feedback.bandwidth_hz=abc: parameter 'bandwidth_hz': expected a number, got 'abc'",
    ),
    (
        [*R, "--set", "feedback.bandwidth_hz=.nan"],
        "--set feedback.bandwidth_hz=.nan: parameter 'bandwidth_hz': expected a finite number",
    ),
    (
        [*R, "--set", "feedback.bandwidth_hz=-3"],
        "--set feedback.bandwidth_hz=-3: parameter 'bandwidth_hz': expected a value > 0",
    ),
    (
        [*R, "--set", "shared.duraton_s=1"],
        "--set shared.duraton_s=1: unknown parameter 'duraton_s' in the shared section '/**', "
        "which every node reads (did you mean 'duration_s'?",
    ),
    (
        [*R, "--set", "shared.mode=fast"],
        "--set shared.mode=fast: parameter 'mode': expected one of ('lockstep', 'realtime'), "
        "got 'fast'",
    ),
    (
        [*R, "--set", "shared.duration_s=0.0005"],
        "--set shared.duration_s=0.0005: parameter 'duration_s'",
    ),
    (
        [*R, "--set", "recorder.max_bag_size_bytes=100"],
        "--set recorder.max_bag_size_bytes=100: parameter 'max_bag_size_bytes': expected 0 "
        "(no split) or >= 1024 (bytes), got 100",
    ),
    (
        [*R, "--set", "recorder.max_bag_duration_s=-1"],
        "--set recorder.max_bag_duration_s=-1: parameter 'max_bag_duration_s': expected a "
        "value >= 0",
    ),
    (
        [*R, "--set", "learning.law=rptc"],
        "--set learning.law=rptc: the scenario has no 'learning' section",
    ),
    (
        [*R, "--set", "/x/plant.inertia_kgm2=1"],
        "--set /x/plant.inertia_kgm2=1: a single-axis scenario has no per-axis sections; set "
        "plant.inertia_kgm2 instead",
    ),
    (
        [*R, "--set", "plant.model=ball_scew"],
        "--set plant.model=ball_scew: parameter 'model': expected one of",
    ),
    (
        [*R, "--set", "plant.friction=3"],
        "--set plant.friction=3: unknown parameter 'friction' for node 'plant' ('friction' is "
        "a group of keys: friction.rolling_coulomb_Nm, ",
    ),
    (
        ["run", "ptc_friction", "--out", "runs/f", "--set", "plant.friction=3"],
        "--set plant.friction=3: 'friction' of section 'plant' is a group of keys "
        "(friction.elements, ",
    ),
    ([*R, "--set", "plant.modes={}"], "--set plant.modes={}: an empty mapping sets nothing"),
    (
        [*R, "--set", "feedback.dob={enabled: true, cutoff_hz: 600}"],
        "--set feedback.dob={enabled: true, cutoff_hz: 600}: parameter 'dob.cutoff_hz'",
    ),
    (
        [*XY, "--set", "/z/plant.inertia_kgm2=1"],
        "--set /z/plant.inertia_kgm2=1: the scenario has no axis 'z'",
    ),
    ([*XY, "--set", "/x/plnt.inertia_kgm2=1"], "unknown section '/x/plnt'; did you mean 'plant'?"),
    (
        [*XY, "--set", "/x/identifier.method=dlpid"],
        "--set /x/identifier.method=dlpid: the scenario starts no identifier node on axis 'x'",
    ),
    # -- list
    (["list", "--config-dir", "nodir"], "argument --config-dir: nodir: no such directory"),
    (["list", "--config-dir", "notarun"], "--config-dir notarun: no scenario files (*.yaml) there"),
    (
        ["list", "--confg-dir", "x"],
        "unrecognized arguments: --confg-dir x (did you mean --config-dir?)",
    ),
    # -- summary
    (["summary"], "the following arguments are required: run_dir"),
    (["summary", "notarun"], "notarun: not a run directory: no summary.json"),
    (["summary", "nodir"], "nodir: not a run directory: no such directory"),
    (["summary", "junk"], "not a servo_axis run summary"),
    (["summary", "partial"], "summary.json: not a servo_axis run summary: missing key 'scenario'"),
    (["summary", "run_a", "run_b"], "unrecognized arguments: run_b"),
    (["summary", "run_a", "--model", "x"], "--model is an option of identify, not of summary"),
    # -- compare
    (["compare"], "the following arguments are required: run_dir"),
    (["compare", "notarun"], "notarun: not a run directory: no summary.json"),
    (["compare", "multi"], "multi: a multi-axis run; compare its axes: multi/x, multi/y"),
    (["compare", "run_a", "--labels", "a,b"], "--labels: expected 1 comma-separated labels, got 2"),
    (["compare", "run_a", "run_a", "--labels", "a,"], "--labels 'a,': a label is empty"),
    (
        ["compare", "run_a", "run_b"],
        "the runs do not compare: cycle: run_a 0.25 s, run_b 0.5 s (--force compares them anyway)",
    ),
    (
        ["compare", "run_a", "--zoom-cycle", "0"],
        "argument --zoom-cycle: '0': expected an integer >= 1",
    ),
    (
        ["compare", "run_a", "--out", "nodir/c.png"],
        "argument --out: nodir/c.png: cannot write it: no directory nodir",
    ),
    (
        ["compare", "run_a", "--bar-chart", "notarun"],
        "argument --bar-chart: notarun: is a directory, expected a file to write",
    ),
    (["compare", "run_a", "--lables", "x"], "did you mean --labels?"),
    # -- friction-table
    (
        ["friction-table", "notarun", "--out", "t.csv"],
        "notarun: not a run directory: no summary.json",
    ),
    (
        ["friction-table", "fast", "--out", "t.csv"],
        "fast: not a slow-reversal (friction identification) run like friction_id: the "
        "reference of fast moves so fast that its inertial and viscous torque",
    ),
    (
        ["friction-table", "still", "--out", "t.csv"],
        "still: not a slow-reversal (friction identification) run like friction_id: the "
        "reference of still never reverses",
    ),
    (
        ["friction-table", "multi", "--out", "t.csv"],
        "multi: a multi-axis run; give one of its axes",
    ),
    (["friction-table", "fast"], "the following arguments are required: --out"),
    (
        ["friction-table", "fast", "--out", "t.csv", "--bin-width-m", "0"],
        "argument --bin-width-m: '0': expected a finite number > 0",
    ),
    (
        ["friction-table", "fast", "--out", "t.csv", "--max-displacement-m", "nan"],
        "argument --max-displacement-m: 'nan': expected a finite number > 0",
    ),
    (
        ["friction-table", "fast", "--out", "t.csv", "--bin-width-m", "1e"],
        "argument --bin-width-m: '1e': expected a finite number > 0",
    ),
    # -- gms-fit
    (
        ["gms-fit", "fast", "--out", "g.txt"],
        "fast: not a slow-reversal (friction identification) run",
    ),
    (["gms-fit", "still", "--out", "g.txt"], "the reference of still never reverses"),
    (
        ["gms-fit", "fast", "--out", "g.txt", "--elements", "21"],
        "argument --elements: '21': expected an integer 1..20",
    ),
    (
        ["gms-fit", "fast", "--out", "g.txt", "--elements", "x"],
        "argument --elements: 'x': expected an integer 1..20",
    ),
    (
        ["gms-fit", "fast", "--out", "g.txt", "--plot", "nodir/f.png"],
        "argument --plot: nodir/f.png: cannot write it: no directory nodir",
    ),
    # -- identify
    (
        ["identify", "fast", "still", "--model", "ball_screw", "--out", "x.yaml"],
        "unrecognized arguments: still (identify takes one excitation run, RUN_DIR; a "
        "slow-reversal run goes with --friction",
    ),
    (
        ["identify", "fast", "--model", "bal_screw", "--out", "x.yaml"],
        "argument --model: invalid choice: 'bal_screw'; did you mean 'ball_screw'?",
    ),
    (["identify", "fast", "--model", "ball_screw"], "the following arguments are required: --out"),
    (
        ["identify", "notarun", "--model", "ball_screw", "--out", "x.yaml"],
        "notarun: not a run directory: no summary.json",
    ),
    (
        ["identify", "fast", "--model", "ball_screw", "--out", "x.yaml"],
        "fast: no excitation (feedforward excitation.enabled is false)",
    ),
    (
        ["identify", "fast", "--model", "ball_screw", "--out", "nodir/x.yaml"],
        "argument --out: nodir/x.yaml: cannot write it: no directory nodir",
    ),
    # -- sweep
    (
        ["sweep", "no_such_study"],
        "study 'no_such_study': neither a file nor a shipped study; the shipped ones:",
    ),
    (["sweep", "grd.yaml"], "'grd': unknown key; did you mean 'grid'?"),
    (
        ["sweep", "figure.yaml"],
        "no 'tracking_eror' at '.' of a plain point's summary; did you mean 'tracking_error'?",
    ),
    (
        ["sweep", "scenario_typo.yaml"],
        "'scenario': scenario 'ptc_nominl': neither a file nor a shipped scenario; did you "
        "mean 'ptc_nominal'",
    ),
    (
        ["sweep", "key_typo.yaml"],
        "'feedbak.bandwidth_hz': unknown section 'feedbak'; did you mean 'feedback'?",
    ),
    (
        ["sweep", "study.yaml", "--workers", "0"],
        "argument --workers: '0': expected an integer >= 1",
    ),
    (
        ["sweep", "study.yaml", "--set", "feedbak.x=1"],
        "'feedbak.x=1': unknown section 'feedbak'; did you mean 'feedback'?",
    ),
    (
        ["sweep", "study.yaml", "--set", "shared.duraton_s=1"],
        "'--set shared.duraton_s=1': unknown parameter 'duraton_s' in the shared section",
    ),
    # -- bag
    (["bag", "recover", "nodir"], "nodir: no bag there (not a directory)"),
    (["bag", "recover", "notarun"], "notarun: no bag there (no *.mcap file)"),
    # -- params
    (
        ["params", "feedbak"],
        "params feedbak: neither a node nor an installed extension (did you mean 'feedback'?",
    ),
    (["params", "ball_scew"], "did you mean 'ball_screw'?"),
    (["params", "feedback", "plant"], "unrecognized arguments: plant"),
    # -- floor
    (
        ["floor", "--period-us", "0"],
        "argument --period-us: '0': expected a period in us, 50..1e+06",
    ),
    (["floor", "--period-us", "nan"], "argument --period-us: 'nan': expected a period in us"),
    (["floor", "--period-us", "abc"], "argument --period-us: 'abc': expected a period in us"),
    (
        ["floor", "--period-us", "1000", "2e7"],
        "argument --period-us: '2e7': expected a period in us",
    ),
    (["floor", "--ticks", "0"], "argument --ticks: '0': expected an integer 1..10000000"),
    (["floor", "--ticks", "1.5"], "argument --ticks: '1.5': expected an integer 1..10000000"),
    (["floor", "--executor", "multi"], "argument --executor: invalid choice: 'multi'"),
    (["floor", "--priority", "100"], "argument --priority: '100': expected an integer 0..99"),
    (["floor", "--domain-id", "300"], "argument --domain-id: 300 is outside 0..232"),
    (
        ["floor", "--out", "nodir/f.jsonl"],
        "argument --out: nodir/f.jsonl: cannot write it: no directory nodir",
    ),
    (["floor", "--tics", "10"], "did you mean --ticks?"),
]


def tree(folder: Path) -> dict[str, tuple[int, int]]:
    """Every path under ``folder`` with its size and modification time (ns)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in folder.rglob("*")
    }


@pytest.fixture
def guarded(work: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """In ``work``; what a case that got through would start fails instead."""

    def started(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("the case got through: it would have started something")

    monkeypatch.chdir(work)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    monkeypatch.setattr("servo_axis.run.runner._run_nodes", started)
    monkeypatch.setattr("servo_axis.run.floor.measure", started)
    monkeypatch.setattr("servo_axis.sweep.engine.run_study", started)
    yield work


@pytest.mark.parametrize(("argv", "said"), CASES, ids=[" ".join(a) for a, _ in CASES])
def test_a_bad_input_is_one_line_exit_2_and_nothing_made(
    guarded: Path, capfd: pytest.CaptureFixture[str], argv: list[str], said: str
) -> None:
    before = tree(guarded)
    code = main(argv)
    out, err = capfd.readouterr()
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and said in lines[0], lines[0]
    assert out == ""
    assert tree(guarded) == before  # no runs/, studies/, output or log made, nothing changed


def test_the_table_covers_every_command() -> None:
    from servo_axis.__main__ import COMMANDS

    names = {
        m.__name__.rpartition(".")[2].removesuffix("_command").replace("_", "-") for m in COMMANDS
    }
    assert names <= {argv[0] for argv, _ in CASES}
    assert len(CASES) >= 70


#: Cases run again as ``python -m servo_axis`` processes (a parser error, a
#: handler's, the plan's, an override's, a file's).
AS_PROCESSES = [
    ["--domain-id", "130"],
    [*R, "--set", "feedback.bandwith_hz=30"],
    ["run", "ptc_nominl"],
    ["friction-table", "fast", "--out", "t.csv"],
    ["floor", "--ticks", "0"],
    ["summary", "notarun"],
]


def test_the_command_line_says_the_same(guarded: Path, capfd: pytest.CaptureFixture[str]) -> None:
    said = {argv: s for argv, s in ((tuple(a), s) for a, s in CASES)}
    before = tree(guarded)
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "servo_axis", *argv],
            cwd=guarded,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for argv in AS_PROCESSES
    ]
    for argv, proc in zip(AS_PROCESSES, procs, strict=True):
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 2, err
        assert out == ""
        assert main(argv) == 2
        assert err == capfd.readouterr().err  # the same line as main's
        assert said[tuple(argv)] in err
    assert tree(guarded) == before
