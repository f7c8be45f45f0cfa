"""The identifier's memory file (paper 003): a restored identifier goes on bit-identically."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from servo_axis import storage
from servo_axis.core.errors import SignalError
from servo_axis.core.identification.online.base import OnlineIdentifier
from servo_axis.params import factories, resolve
from servo_axis.params.scenario import load_scenario
from servo_axis.storage import load_identifier_memory, save_identifier_memory
from servo_axis.wire.layouts import EstimateData, check_estimate_values

CONFIG = Path(__file__).resolve().parents[2] / "config"
SCENARIOS = {"dlpid": "dlpid_tilt_lpf2", "marc": "dlpid_tilt_marc"}

# The plant of 003 Table I, driven along 0.6 - 0.5 cos(pi t) (the scenarios' tilt).
J, D, U, C = 50e-4, 130e-4, 0.3, 0.02


def identifier_values(method: str) -> dict[str, Any]:
    scenario = load_scenario(CONFIG / f"{SCENARIOS[method]}.yaml")
    values: dict[str, Any] = resolve.node_values(scenario, "identifier")
    return values


def build(method: str) -> OnlineIdentifier:
    return factories.build_identifier(identifier_values(method))


def tilt(n: int, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Noisy angle and the torque of eq. (2) along it, ``n`` samples."""
    t = period_s * np.arange(n)
    w = math.pi
    th = 0.6 - 0.5 * np.cos(w * t)
    thd = 0.5 * w * np.sin(w * t)
    thdd = 0.5 * w * w * np.cos(w * t)
    torque = J * thdd + D * thd + U * np.sin(th) + C * np.sign(thd)
    noise = np.random.default_rng(3).uniform(-1e-5, 1e-5, n)
    return th + noise, torque


def feed(
    ident: OnlineIdentifier, angles: np.ndarray, torques: np.ndarray, start: int
) -> np.ndarray:
    """Rows ``[step, J, D, U, C, kappa, updated...]`` of the estimates of samples ``start..``."""
    rows = []
    for k in range(start, len(angles)):
        e = ident.update(k, float(angles[k]), float(torques[k]))
        if e is not None:
            rows.append([e.step, e.J, e.D, e.U, e.C, e.kappa, *map(float, e.updated)])
    return np.array(rows)


@pytest.mark.parametrize("method", ["dlpid", "marc"])
def test_restored_identifier_continues_bit_identically(method: str, tmp_path: Path) -> None:
    values = identifier_values(method)
    period = values["control_period_s"]
    angles, torques = tilt(4000, period)
    half = 2005  # mid RLS period, well after the filters' warm-up
    original = build(method)
    before = feed(original, angles[:half], torques[:half], 0)
    assert before[:, 6:].any()  # the layers ran before the save
    step, j, d, u, c, kappa = before[-1, :6]
    _, latency = factories.estimate_schedule(values, "rls_period_s", "latency_s")
    published = EstimateData(
        step=int(step),
        applies_from_step=int(step) + 1 + latency,
        inertia_kgm2=j,
        damping_Nms_per_rad=d,
        unbalance_Nm=u,
        coulomb_Nm=c,
        kappa=kappa,
        updated=tuple(bool(f) for f in before[-1, 6:]),
    )
    last = published.values()
    path = tmp_path / "identifier_memory.json"
    save_identifier_memory(path, original.state(), last, method=method, scenario="s")

    state, last_loaded = load_identifier_memory(path, method=method, scenario="s")
    assert last_loaded == last
    assert last_loaded is not None and check_estimate_values(last_loaded) == published
    restored = build(method)
    restored.load_state(state)
    assert restored.last_step == original.last_step == half - 1

    after_original = feed(original, angles, torques, half)
    after_restored = feed(restored, angles, torques, half)
    assert len(after_original) > 100
    assert_array_equal(after_restored, after_original)
    # Every parameter the method estimates was updated after the restore, so
    # the comparison covers the restored RLS, filters and friction layer ...
    flags = after_original[:, 6:].any(axis=0)
    assert flags.tolist() == [True, True, True, method == "dlpid"]
    # ... and the state mattered: a fresh identifier on the same samples differs.
    fresh = feed(build(method), angles, torques, half)
    assert not np.array_equal(fresh[:, 1:5], after_original[: len(fresh), 1:5])


def test_memory_text_holds_exactly_what_was_saved(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    ident = build("dlpid")
    angles, torques = tilt(700, 4e-4)
    feed(ident, angles, torques, 0)
    state = ident.state()
    save_identifier_memory(path, state, None, method="dlpid", scenario="dlpid_tilt_lpf2")
    data = json.loads(path.read_text())
    assert data["kind"] == storage.IDENTIFIER_MEMORY_KIND
    assert data["version"] == storage.IDENTIFIER_MEMORY_VERSION
    assert (data["method"], data["scenario"]) == ("dlpid", "dlpid_tilt_lpf2")
    assert data["state"] == json.loads(json.dumps(state))
    assert load_identifier_memory(path, method="dlpid", scenario="dlpid_tilt_lpf2") == (
        data["state"],
        None,
    )


def write_memory(path: Path, **change: Any) -> None:
    data: dict[str, Any] = {
        "kind": storage.IDENTIFIER_MEMORY_KIND,
        "version": storage.IDENTIFIER_MEMORY_VERSION,
        "method": "dlpid",
        "scenario": "s",
        "state": build("dlpid").state(),
        "last_estimate": [9.0, 20.0, 0.002, 0.01, 0.1, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0],
    }
    data.update(change)
    path.write_text(json.dumps(data))


def test_a_hand_written_memory_is_accepted(tmp_path: Path) -> None:
    # The baseline of the refusals below: only the changed key is wrong there.
    path = tmp_path / "m.json"
    write_memory(path)
    state, last = load_identifier_memory(path, method="dlpid", scenario="s")
    assert state["mode"] == "double_layer" and last is not None and len(last) == 11


@pytest.mark.parametrize(
    ("change", "load", "match"),
    [
        ({}, {"method": "marc"}, r"method 'dlpid', expected 'marc'"),
        ({"method": "marc"}, {}, r"method 'marc', expected 'dlpid'"),
        ({}, {"scenario": "other"}, r"scenario 's', expected 'other'"),
        ({"kind": "servo_axis.learning_memory"}, {}, r"not an identifier memory"),
        ({"kind": None}, {}, r"not an identifier memory"),
        ({"version": 2}, {}, r"version 2, expected 1"),
        ({"version": "1"}, {}, r"version '1', expected 1"),
        ({"state": [1.0, 2.0]}, {}, r"state: expected a mapping"),
        ({"state": None}, {}, r"state: expected a mapping"),
        ({"last_estimate": "9,20"}, {}, r"last_estimate: expected a list of numbers or null"),
        ({"last_estimate": {"step": 9}}, {}, r"last_estimate: expected a list of numbers"),
        ({"last_estimate": [9.0, "20"]}, {}, r"last_estimate: expected a list of numbers"),
        ({"last_estimate": [9.0, None]}, {}, r"last_estimate: expected a list of numbers"),
        ({"last_estimate": [[9.0]]}, {}, r"last_estimate: expected a list of numbers"),
    ],
)
def test_foreign_or_broken_memories_are_refused(
    tmp_path: Path, change: dict[str, Any], load: dict[str, str], match: str
) -> None:
    path = tmp_path / "m.json"
    write_memory(path, **change)
    with pytest.raises(SignalError, match=match) as info:
        load_identifier_memory(path, **{"method": "dlpid", "scenario": "s", **load})
    assert str(path) in str(info.value)  # names the file


@pytest.mark.parametrize("text", ["", "not json", "{'kind': 1}", '{"kind": '])
def test_a_file_that_is_not_json_is_refused(tmp_path: Path, text: str) -> None:
    path = tmp_path / "m.json"
    path.write_text(text)
    with pytest.raises(SignalError, match=rf"{path}: not JSON"):
        load_identifier_memory(path, method="dlpid", scenario="s")


@pytest.mark.parametrize("text", ["[]", "3", "null", '"servo_axis.identifier_memory"'])
def test_json_that_is_not_a_mapping_is_refused(tmp_path: Path, text: str) -> None:
    path = tmp_path / "m.json"
    path.write_text(text)
    with pytest.raises(SignalError, match="not an identifier memory"):
        load_identifier_memory(path, method="dlpid", scenario="s")


def test_a_missing_file_is_an_os_error(tmp_path: Path) -> None:
    with pytest.raises(OSError):
        load_identifier_memory(tmp_path / "absent.json", method="dlpid", scenario="s")


def test_save_is_atomic_and_leaves_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "identifier_memory.json"
    ident = build("dlpid")
    angles, torques = tilt(800, 4e-4)
    feed(ident, angles[:400], torques[:400], 0)
    first = ident.state()
    save_identifier_memory(path, first, None, method="dlpid", scenario="s")
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    feed(ident, angles, torques, 400)
    second = ident.state()
    assert second != first
    save_identifier_memory(path, second, [1.0], method="dlpid", scenario="s")
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    assert load_identifier_memory(path, method="dlpid", scenario="s") == (
        json.loads(json.dumps(second)),
        [1.0],
    )

    # Killed between writing and renaming: the previous memory is intact.
    def killed(src: object, dst: object) -> None:
        raise OSError("killed")

    monkeypatch.setattr(storage.os, "replace", killed)
    with pytest.raises(OSError, match="killed"):
        save_identifier_memory(path, first, None, method="dlpid", scenario="s")
    monkeypatch.undo()
    assert load_identifier_memory(path, method="dlpid", scenario="s")[1] == [1.0]


def test_a_non_finite_estimate_is_never_saved(tmp_path: Path) -> None:
    path = tmp_path / "identifier_memory.json"
    state = build("dlpid").state()
    save_identifier_memory(path, state, [1.0, 2.0], method="dlpid", scenario="s")
    before = path.read_text()
    with pytest.raises(ValueError, match="JSON compliant"):
        save_identifier_memory(path, state, [1.0, math.nan], method="dlpid", scenario="s")
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
