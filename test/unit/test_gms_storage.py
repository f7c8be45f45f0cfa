"""GMS parameter files (storage), the fit from a recorded run and the ``gms-fit`` command.

No ROS: the run is a bag written here with rosbags' typestore.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.__main__ import main
from servo_axis.analysis.summary import summarise
from servo_axis.core.errors import TableError
from servo_axis.core.friction.gms_fitting import fit_gms
from servo_axis.core.friction.gms_model import simulate_gms
from servo_axis.core.friction.gms_params import GmsParams
from servo_axis.friction_id import estimate_friction_torque
from servo_axis.gms_fit import fit_from_run, load_fit_data, plant_fingerprint, plot_fit
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.writer import BagWriter
from servo_axis.storage import load_gms_parameters, save_gms_parameters

PARAMS = GmsParams(
    stiffness_Nm_per_m=(0.3 * 3.2 / 1e-6, 0.45 * 3.2 / 3e-6, 0.25 * 3.2 / 6e-6),
    weights=(0.3, 0.45, 0.25),
    coulomb_Nm=3.2,
    static_Nm=3.5,
    viscous_Nms_per_m=12.5,
)
FINGERPRINT = "ball_screw:0123456789abcdef"
# A slow reversal identifies only k_i, alpha_i and F_c: the run's friction has no Stribeck
# effect and no viscous part.
RUN_PARAMS = replace(PARAMS, static_Nm=None, viscous_Nms_per_m=0.0)


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "gms.txt"
    save_gms_parameters(path, PARAMS, plant_model="ball_screw", plant_fingerprint=FINGERPRINT)
    assert load_gms_parameters(path) == (PARAMS, "ball_screw", FINGERPRINT)
    assert load_gms_parameters(str(path)) == (PARAMS, "ball_screw", FINGERPRINT)
    assert [p.name for p in tmp_path.iterdir()] == ["gms.txt"]  # no temporary file left


def test_save_replaces_a_file_atomically(tmp_path: Path) -> None:
    path = tmp_path / "gms.txt"
    path.write_text("old")
    save_gms_parameters(path, PARAMS, plant_model="ball_screw", plant_fingerprint=FINGERPRINT)
    assert load_gms_parameters(path)[0] == PARAMS
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gms.txt"]


def test_truncated_file_is_a_table_error_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "gms.txt"
    save_gms_parameters(path, PARAMS, plant_model="ball_screw", plant_fingerprint=FINGERPRINT)
    text = path.read_text()
    cut = text.index("coulomb_Nm")
    (tmp_path / "cut.txt").write_text(text[:cut])
    with pytest.raises(TableError, match=re.escape(f"{tmp_path / 'cut.txt'}: missing key(s)")):
        load_gms_parameters(tmp_path / "cut.txt")
    # Cut in the middle of a number: still a number, but the weights no longer sum to 1.
    mid = text.index("weights = ") + len("weights = 0.3, 0.4")
    (tmp_path / "mid.txt").write_text(text[:mid])
    with pytest.raises(TableError, match=r"mid\.txt"):
        load_gms_parameters(tmp_path / "mid.txt")


def test_unreadable_files_are_table_errors_naming_the_file(tmp_path: Path) -> None:
    with pytest.raises(TableError, match=re.escape(f"{tmp_path / 'none.txt'}: cannot read it")):
        load_gms_parameters(tmp_path / "none.txt")
    (tmp_path / "bin.txt").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(TableError, match=r"bin\.txt: cannot read it"):
        load_gms_parameters(tmp_path / "bin.txt")
    (tmp_path / "empty.txt").write_text("")
    with pytest.raises(TableError, match=r"empty\.txt: line 1: expected header"):
        load_gms_parameters(tmp_path / "empty.txt")


# --------------------------------------------------------------------------- from a run

JOINT_STATE = "sensor_msgs/msg/JointState"
PERIOD_S = 0.002
LEAD = 0.002
NOMINAL = {"torque_constant_Nm_per_A": 0.8, "inertia_kgm2": 0.02, "damping_Nms_per_rad": 0.05}


def joint_state(ts: Any, step: int, names: list[str], **fields: list[float]) -> bytes:
    ns = round(step * PERIOD_S * 1e9)
    stamp = ts.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    msg = ts.types[JOINT_STATE](
        header=ts.types["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
        name=names,
        position=np.array(fields.get("position", []), dtype=np.float64),
        velocity=np.array(fields.get("velocity", []), dtype=np.float64),
        effort=np.array(fields.get("effort", []), dtype=np.float64),
    )
    return bytes(ts.serialize_cdr(msg, JOINT_STATE))


def write_scenario(path: Path, *, inertia_kgm2: float = 0.01) -> Path:
    data = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": "gms_fit", "description": "a slow reversal"},
                "mode": "realtime",
                "control_period_s": PERIOD_S,
                "duration_s": 3.0,
                "lead_m_per_rad": LEAD,
                "nominal": NOMINAL,
            }
        },
        "plant": {"ros__parameters": {"inertia_kgm2": inertia_kgm2}},
        "feedback": {"ros__parameters": {"sensor": "scale"}},
        "feedforward": {
            "ros__parameters": {
                "reference": {"kind": "sine", "frequency_hz": 0.5, "amplitude_m": 50e-6},
                "ptc": {"enabled": False},
            }
        },
    }
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture
def gms_run(tmp_path: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """A recorded slow reversal whose friction is RUN_PARAMS: 50 um, 0.5 Hz, 1.5 periods at 2 ms."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    k = np.arange(1500)
    w = 2 * math.pi * 0.5
    pos = 50e-6 * (1 - np.cos(w * k * PERIOD_S))
    friction = simulate_gms(
        RUN_PARAMS, pos, 50e-6 * w * np.sin(w * k * PERIOD_S), period_s=PERIOD_S
    )
    ref = pos / LEAD
    # The motor torque K_T i that makes K_T i - J a_r - D v_r the friction exactly.
    zero = estimate_friction_torque(
        reference_rad=ref,
        motor_torque_Nm=np.zeros(k.size),
        period_s=PERIOD_S,
        inertia_kgm2=NOMINAL["inertia_kgm2"],
        damping_Nms_per_rad=NOMINAL["damping_Nms_per_rad"],
    )
    torque = friction - zero
    run = tmp_path / "run"
    with BagWriter(run / "bag") as bag:
        for topic in ("state", "reference", "command"):
            bag.add_topic(topic, JOINT_STATE)
        for i in k.tolist():
            t = 3 * i
            r = float(ref[i])
            bag.write(
                "reference",
                joint_state(ts, i, ["x_motor"], position=[r], velocity=[0.0], effort=[0.0]),
                log_time_ns=t,
            )
            state = joint_state(
                ts,
                i,
                ["x_motor", "x_table"],
                position=[r, r * LEAD],
                velocity=[0.0, 0.0],
                effort=[0.0, 0.0],
            )
            bag.write("state", state, log_time_ns=t + 1)
            command = joint_state(ts, i, ["x_motor"], effort=[float(torque[i])])
            bag.write("command", command, log_time_ns=t + 2)
    path = write_scenario(tmp_path / "gms_fit.yaml")
    (run / "scenario.yaml").write_text(path.read_text())  # what the runner records
    summarise(
        run, scenario=load_scenario(path), scenario_path=path, wall_time_s=1.0, mode="processes"
    )
    return run, pos, friction


def test_fit_from_run_uses_the_reference_at_the_table_and_the_nominal_model(
    gms_run: tuple[Path, np.ndarray, np.ndarray],
) -> None:
    run, pos, friction = gms_run
    data = load_fit_data(run)
    assert_allclose(data.position_m, pos, rtol=1e-12, atol=1e-18)
    assert_allclose(data.torque_Nm, friction, rtol=0, atol=1e-9)
    assert data.period_s == PERIOD_S
    assert data.plant_model == "ball_screw"
    fit = fit_from_run(run, elements=3)
    again = fit_gms(data.position_m, data.torque_Nm, elements=3, period_s=PERIOD_S)
    assert fit.params == again.params
    assert_allclose(fit.params.coulomb_Nm, RUN_PARAMS.coulomb_Nm, rtol=1e-6)
    assert_allclose(fit.params.stiffness_Nm_per_m, RUN_PARAMS.stiffness_Nm_per_m, rtol=1e-6)
    assert_allclose(fit.params.weights, RUN_PARAMS.weights, rtol=1e-6)


def test_plant_fingerprint_follows_the_plant_physics_only(tmp_path: Path) -> None:
    a = plant_fingerprint(load_scenario(write_scenario(tmp_path / "a.yaml")))
    assert re.fullmatch(r"ball_screw:[0-9a-f]{16}", a)
    other = load_scenario(write_scenario(tmp_path / "b.yaml", inertia_kgm2=0.011))
    assert plant_fingerprint(other) != a
    longer = load_scenario(write_scenario(tmp_path / "c.yaml"))
    longer["/**"]["ros__parameters"]["duration_s"] = 99.0
    assert plant_fingerprint(longer) == a


def test_gms_fit_command_writes_the_file_and_the_figure(
    gms_run: tuple[Path, np.ndarray, np.ndarray],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    run, _, _ = gms_run
    out, png = tmp_path / "gms.txt", tmp_path / "gms.png"
    argv = ["gms-fit", str(run), "--out", str(out), "--elements", "3", "--plot", str(png)]
    assert main(argv) == 0
    params, model, fingerprint = load_gms_parameters(out)
    assert params == fit_from_run(run, elements=3).params
    assert model == "ball_screw"
    assert fingerprint == plant_fingerprint(load_scenario(tmp_path / "gms_fit.yaml"))
    printed = capsys.readouterr().out
    assert f"F_c = {params.coulomb_Nm:.6g} N m" in printed
    assert "RMS residual" in printed
    assert printed.count("\n") >= 6  # header, F_c, column titles, 3 elements, RMS
    assert png.stat().st_size > 1000
    assert main(["gms-fit", str(run), "--out", str(out), "--elements", "0"]) == 2
    assert "elements" in capsys.readouterr().err


def test_plot_fit_checks_the_lengths(gms_run: tuple[Path, np.ndarray, np.ndarray]) -> None:
    from servo_axis.core.errors import SignalError

    run, pos, friction = gms_run
    fit = fit_from_run(run, elements=3)
    with pytest.raises(SignalError, match="position_m, torque_Nm"):
        plot_fit(fit, pos[:-1], friction[:-1], run / "x.png")
