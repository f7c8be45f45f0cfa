"""Run summary and plots from a recorded bag.

The tracking error is ``e[k] = R (r[k] - y[k])`` at the table (m), with
``r`` the feedback reference of topic ``reference`` and ``y`` the angle of
the feedback sensor in topic ``state``. With PTC the reference instants
``T_r = 2 T_u`` (even ``k``) are where perfect tracking holds; the summary
gives statistics over every sample and over those instants, for the whole
run and per cycle of a periodic reference.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core.errors import ConfigError
from servo_axis.recording.bag import read_messages

FAULT_NAMES = {1: "following_error", 2: "travel", 3: "current", 4: "input_timeout"}


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def load_signals(bag_dir: Path, period_s: float) -> dict[str, Any]:
    """Arrays per step from a bag: state, reference and command, plus faults and counts."""
    period_ns = round(period_s * 1e9)
    state: dict[int, tuple[float, float]] = {}
    ref: dict[int, tuple[float, float]] = {}
    cmd: dict[int, float] = {}
    faults: list[dict[str, Any]] = []
    counts: dict[str, int] = {}
    for m in read_messages(bag_dir):
        counts[m.topic] = counts.get(m.topic, 0) + 1
        leaf = m.topic.rsplit("/", 1)[-1]
        if leaf == "state":
            state[_stamp_ns(m.message) // period_ns] = (
                m.message.position[0],
                m.message.position[1],
            )
        elif leaf == "reference":
            ref[_stamp_ns(m.message) // period_ns] = (m.message.position[0], m.message.effort[0])
        elif leaf == "command":
            cmd[_stamp_ns(m.message) // period_ns] = m.message.effort[0]
        elif leaf == "fault":
            step, code, value = m.message.data
            faults.append(
                {
                    "step": int(step),
                    "code": int(code),
                    "name": FAULT_NAMES.get(int(code), "?"),
                    "value": value,
                }
            )
    steps = sorted(set(state) & set(ref))
    k = np.array(steps, dtype=int)
    return {
        "step": k,
        "encoder_rad": np.array([state[s][0] for s in steps]),
        "scale_m": np.array([state[s][1] for s in steps]),
        "reference_rad": np.array([ref[s][0] for s in steps]),
        "feedforward_A": np.array([ref[s][1] for s in steps]),
        "command_A": np.array([cmd.get(s, math.nan) for s in steps]),
        "faults": faults,
        "counts": counts,
    }


def _stats(e: np.ndarray) -> dict[str, float]:
    if e.size == 0:
        return {"rms_m": math.nan, "max_m": math.nan}
    return {"rms_m": float(np.sqrt(np.mean(e**2))), "max_m": float(np.max(np.abs(e)))}


def reference_period_s(params: dict[str, Any]) -> float | None:
    """Period of the scenario's reference (feedforward parameters), or None."""
    from servo_axis.core.reference import make_reference
    from servo_axis.nodes.feedforward import REFERENCE_KEYS, SCHEMA

    values = {**{k: v for k, v in SCHEMA.items() if k.startswith("reference.")}, **params}
    kind = values["reference.kind"]
    ref = make_reference(kind, **{k: values[f"reference.{k}"] for k in REFERENCE_KEYS[kind]})
    return ref.period_s


def error_statistics(
    error_m: np.ndarray, step: np.ndarray, *, period_s: float, cycle_s: float | None
) -> dict[str, Any]:
    """Whole-run, reference-instant and per-cycle statistics of the error."""
    at_tr = step % 2 == 0
    out: dict[str, Any] = {
        "all_samples": _stats(error_m),
        "reference_instants": _stats(error_m[at_tr]),
        "cycles": [],
    }
    if cycle_s:
        per_cycle = round(cycle_s / period_s)
        cycle = step // per_cycle
        for c in range(int(cycle.max()) + 1 if step.size else 0):
            sel = cycle == c
            if np.count_nonzero(sel) < per_cycle:
                continue  # incomplete last cycle
            out["cycles"].append(
                {
                    "cycle": c + 1,
                    **_stats(error_m[sel]),
                    "reference_instants": _stats(error_m[sel & at_tr]),
                }
            )
        after_first = step >= per_cycle
        out["after_first_cycle"] = {
            "all_samples": _stats(error_m[after_first]),
            "reference_instants": _stats(error_m[after_first & at_tr]),
        }
    return out


def learning_enabled(scenario: dict[str, Any]) -> bool:
    """True when the scenario's feedforward generator applies learning corrections."""
    from servo_axis.bringup import node_params

    return "feedforward" in scenario and bool(
        node_params(scenario, "feedforward").get("learning.enabled")
    )


def tracking(
    scenario: dict[str, Any], scenario_path: Path, sig: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray]:
    """Target (rad) and measured angle (rad) per recorded step.

    The target is the reference the feedback got, except with learning: then
    it is the original target without the learned correction (the ``r`` of
    000 eq. (9)), recomputed with the same generator.
    """
    from servo_axis.bringup import node_params, shared
    from servo_axis.nodes import feedforward
    from servo_axis.simulate import feedforward_values

    lead = float(shared(scenario).get("lead_m_per_rad", 1.91e-3))
    fb = node_params(scenario, "feedback")
    y = sig["scale_m"] / lead if fb.get("sensor", "encoder") == "scale" else sig["encoder_rad"]
    target = sig["reference_rad"]
    if learning_enabled(scenario) and sig["step"].size:
        values = feedforward_values(scenario, scenario_path)
        values["learning.enabled"] = False
        rows = feedforward.build_generator(values).samples(0, int(sig["step"].max()) + 1)
        target = np.array([rows[k][0] for k in sig["step"]])
    return target, y


def summarise(
    run_dir: Path,
    *,
    scenario: dict[str, Any],
    scenario_path: Path,
    wall_time_s: float,
    mode: str,
) -> dict[str, Any]:
    """Compute the summary of a run, write ``summary.json`` and return it."""
    from servo_axis.bringup import node_params, shared

    common = shared(scenario)
    period = float(common.get("control_period_s", 1e-3))
    lead = float(common.get("lead_m_per_rad", 1.91e-3))
    ff = node_params(scenario, "feedforward")
    sig = load_signals(run_dir / "bag", period)
    target, y = tracking(scenario, scenario_path, sig)
    error = lead * (target - y)
    if learning_enabled(scenario):
        cycle: float | None = float(ff.get("learning.cycle_s", 0.5))
    else:
        cycle = reference_period_s(ff) if "feedforward" in scenario else None
    steps = int(sig["step"].size)
    sim_time = steps * period
    summary = {
        "scenario": common.get("scenario", {}).get("name") or scenario_path.stem,
        "description": common.get("scenario", {}).get("description", ""),
        "scenario_file": str(scenario_path),
        "processes": mode,
        "time_mode": common.get("mode", "lockstep"),
        "control_period_s": period,
        "steps": steps,
        "sim_time_s": sim_time,
        "wall_time_s": wall_time_s,
        "steps_per_s": steps / wall_time_s if wall_time_s > 0 else math.nan,
        "realtime_factor": sim_time / wall_time_s if wall_time_s > 0 else math.nan,
        "message_counts": sig["counts"],
        "faults": sig["faults"],
        "ptc": bool(ff.get("ptc.enabled", True)),
        "friction_table": bool(ff.get("friction_table.enabled", False)),
        "reference_period_s": cycle,
        "tracking_error": error_statistics(error, sig["step"], period_s=period, cycle_s=cycle),
    }
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=True))
    return summary


def _um(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x * 1e6:.6g}"


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as a plain-text table (errors in um)."""
    te = summary["tracking_error"]
    lines = [
        f"scenario          {summary['scenario']}  ({summary['processes']}, {summary['time_mode']})",
        f"steps             {summary['steps']}  ({summary['sim_time_s']:.3f} s simulated)",
        f"wall time         {summary['wall_time_s']:.2f} s  ->  {summary['steps_per_s']:,.0f} steps/s, "
        f"{summary['realtime_factor']:.2f}x real time",
        "messages          "
        + ", ".join(f"{k}: {v}" for k, v in sorted(summary["message_counts"].items())),
        "faults            "
        + (", ".join(f"{f['name']} at step {f['step']}" for f in summary["faults"]) or "none"),
        "",
        "tracking error (um)          RMS            max",
        f"  all samples          {_um(te['all_samples']['rms_m']):>12} {_um(te['all_samples']['max_m']):>14}",
        f"  at T_r instants      {_um(te['reference_instants']['rms_m']):>12} "
        f"{_um(te['reference_instants']['max_m']):>14}",
    ]
    if "after_first_cycle" in te:
        a = te["after_first_cycle"]
        lines += [
            f"  after cycle 1        {_um(a['all_samples']['rms_m']):>12} {_um(a['all_samples']['max_m']):>14}",
            f"  ... at T_r instants  {_um(a['reference_instants']['rms_m']):>12} "
            f"{_um(a['reference_instants']['max_m']):>14}",
            "",
            "cycle   RMS (um)       max (um)       max at T_r (um)",
        ]
        for c in te["cycles"]:
            lines.append(
                f"{c['cycle']:>5} {_um(c['rms_m']):>12} {_um(c['max_m']):>14} "
                f"{_um(c['reference_instants']['max_m']):>18}"
            )
    return "\n".join(lines)


def cycle_errors(summary: dict[str, Any]) -> dict[str, np.ndarray]:
    """Per-cycle tracking error of a run summary, as arrays (cycle number, m).

    Returns ``{"cycle", "max_m", "rms_m", "max_at_tr_m"}``; empty arrays when
    the reference is not periodic.
    """
    cycles = summary.get("tracking_error", {}).get("cycles", [])
    return {
        "cycle": np.array([c["cycle"] for c in cycles], dtype=int),
        "max_m": np.array([c["max_m"] for c in cycles], dtype=float),
        "rms_m": np.array([c["rms_m"] for c in cycles], dtype=float),
        "max_at_tr_m": np.array([c["reference_instants"]["max_m"] for c in cycles], dtype=float),
    }


def compare_table(summaries: list[dict[str, Any]], labels: list[str]) -> str:
    """Max and RMS tracking error per cycle of several runs side by side (000 Fig. 15).

    Two blocks, ``max error per cycle (um)`` and ``RMS error per cycle (um)``,
    a row per cycle and a column per run; 6 significant digits.
    """
    per_run = [cycle_errors(s) for s in summaries]
    n = max((len(c["cycle"]) for c in per_run), default=0)
    width = max(14, *(len(label) + 2 for label in labels))
    lines: list[str] = []
    for title, key in (("max", "max_m"), ("RMS", "rms_m")):
        if lines:
            lines.append("")
        lines += [
            f"{title} error per cycle (um)",
            "cycle" + "".join(f"{x:>{width}}" for x in labels),
        ]
        for k in range(n):
            cells = [
                f"{1e6 * c[key][k]:>{width}.6g}" if k < len(c[key]) else " " * width
                for c in per_run
            ]
            lines.append(f"{k + 1:>5}" + "".join(cells))
    return "\n".join(lines)


def plot_cycles(
    summaries: list[dict[str, Any]], labels: list[str], path: Path, *, title: str
) -> Path:
    """Max and RMS tracking error per cycle of one or more runs (000 Fig. 15), log scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for summary, label, marker in zip(summaries, labels, "osd^v<>", strict=False):
        c = cycle_errors(summary)
        (line,) = ax.semilogy(c["cycle"], 1e6 * c["max_m"], "-" + marker, label=f"{label}: max")
        ax.semilogy(
            c["cycle"],
            1e6 * c["rms_m"],
            ":" + marker,
            color=line.get_color(),
            ms=4,
            label=f"{label}: RMS",
        )
    ax.set_xlabel("cycle")
    ax.set_ylabel("tracking error (um)")
    ax.set_title(title)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _run_series(
    run_dir: Path,
) -> tuple[dict[str, Any], dict[str, Any], np.ndarray, np.ndarray, float]:
    """Summary, recorded signals, target and measured angle (rad), lead (m/rad) of a run."""
    from servo_axis.bringup import load_scenario, shared

    summary = json.loads((run_dir / "summary.json").read_text())
    scenario = load_scenario(Path(summary["scenario_file"]))
    lead = float(shared(scenario).get("lead_m_per_rad", 1.91e-3))
    sig = load_signals(run_dir / "bag", summary["control_period_s"])
    target, y = tracking(scenario, Path(summary["scenario_file"]), sig)
    return summary, sig, target, y, lead


def plot_error_overlay(
    run_dirs: list[Path], labels: list[str], path: Path, *, zoom_cycle: int, title: str
) -> Path:
    """Tracking error of several runs against time, whole run and one cycle
    enlarged (000 Fig. 13(b)-(c), Fig. 15(b)-(c))."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (whole, zoom) = plt.subplots(2, 1, figsize=(9, 6))
    for run_dir, label in zip(run_dirs, labels, strict=True):
        summary, sig, target, y, lead = _run_series(run_dir)
        t = sig["step"] * summary["control_period_s"]
        err_um = lead * (target - y) * 1e6
        whole.plot(t, err_um, lw=0.7, label=label)
        cycle_s = summary.get("reference_period_s")
        if cycle_s:
            inside = (t >= (zoom_cycle - 1) * cycle_s) & (t < zoom_cycle * cycle_s)
            zoom.plot(t[inside], err_um[inside], lw=0.8, label=label)
    whole.set_title(title)
    zoom.set_title(f"cycle {zoom_cycle} enlarged")
    for ax in (whole, zoom):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("tracking error (um)")
        ax.grid(True, lw=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot(run_dir: Path) -> list[Path]:
    """Write ``reference_position.png``, ``error.png`` and, for a periodic
    reference, ``cycle_errors.png`` into the run directory."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary, sig, target, y, lead = _run_series(run_dir)
    t = sig["step"] * summary["control_period_s"]
    err = lead * (target - y) * 1e6
    even = sig["step"] % 2 == 0
    figures = [
        (
            "reference_position.png",
            "table position (mm)",
            "reference and position",
            [
                (t, sig["reference_rad"] * lead * 1e3, "-", "reference r"),
                (t, y * lead * 1e3, "--", "position y"),
            ],
        ),
        (
            "error.png",
            "tracking error (um)",
            "tracking error e = R (r - y)",
            [(t, err, "-", "all samples"), (t[even], err[even], ".", "T_r instants")],
        ),
    ]
    paths = []
    for name, ylabel, title, lines in figures:
        fig, ax = plt.subplots(figsize=(9, 4))
        for x_values, y_values, style, label in lines:
            ax.plot(x_values, y_values, style, label=label, lw=0.8, ms=2)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{summary['scenario']}: {title}")
        ax.legend()
        ax.grid(True)
        fig.tight_layout()
        paths.append(run_dir / name)
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    if len(cycle_errors(summary)["cycle"]) >= 2:
        paths.append(
            plot_cycles(
                [summary],
                [summary["scenario"]],
                run_dir / "cycle_errors.png",
                title=f"{summary['scenario']}: tracking error per cycle",
            )
        )
    return paths


def contour(run_dir: Path, axes: list[str]) -> dict[str, Any]:
    """Contour error of a two-axis circle run (000 Fig. 18).

    The target circle is the least-squares circle through the axes'
    original targets (their own radial deviation from it is reported as
    ``target_radial_deviation_m``, so that a path that is not a circle shows).
    The radial deviation of the measured path is ``|p - c| - R``; per cycle
    of the reference its circular deviation (max - min, as ISO 230-4 defines
    it for a circular test) and its largest magnitude.
    """
    if len(axes) != 2:
        raise ConfigError(f"axes: expected two, got {axes!r}")
    series = [_run_series(run_dir / a) for a in axes]
    steps = np.intersect1d(series[0][1]["step"], series[1][1]["step"])
    target = np.empty((steps.size, 2))
    measured = np.empty((steps.size, 2))
    for col, (_summary, sig, tgt, y, lead) in enumerate(series):
        idx = np.searchsorted(sig["step"], steps)
        target[:, col] = lead * tgt[idx]
        measured[:, col] = lead * y[idx]
    # Least-squares (Kasa) circle through the target: exact for points on a
    # circle, however they are sampled.
    lhs = np.column_stack((2 * target, np.ones(len(target))))
    (cx, cy, c0), *_ = np.linalg.lstsq(lhs, np.sum(target**2, axis=1), rcond=None)
    centre = np.array([cx, cy])
    radius = float(np.sqrt(c0 + cx * cx + cy * cy))
    radial = np.hypot(*(measured - centre).T) - radius
    target_radial = np.hypot(*(target - centre).T) - radius
    summary = series[0][0]
    period = float(summary["control_period_s"])
    cycle_s = summary.get("reference_period_s")
    cycles = []
    if cycle_s:
        per_cycle = round(cycle_s / period)
        for c in range(int(steps.max() + 1) // per_cycle):
            inside = (steps >= c * per_cycle) & (steps < (c + 1) * per_cycle)
            if inside.any():
                r = radial[inside]
                cycles.append(
                    {
                        "cycle": c + 1,
                        "circular_deviation_m": float(r.max() - r.min()),
                        "max_radial_m": float(np.max(np.abs(r))),
                    }
                )
    return {
        "axes": axes,
        "centre_m": centre.tolist(),
        "radius_m": radius,
        "target_radial_deviation_m": float(np.max(np.abs(target_radial))),
        "circular_deviation_m": float(radial.max() - radial.min()),
        "max_radial_m": float(np.max(np.abs(radial))),
        "cycles": cycles,
        "_series": (steps, target, measured, radial),
    }


def summarise_axes(
    run_dir: Path,
    *,
    scenario: dict[str, Any],
    axes: dict[str, dict[str, Any]],
    wall_time_s: float,
) -> dict[str, Any]:
    """Summary of a multi-axis run: the axes' summaries and, for two, the contour."""
    from servo_axis.bringup import shared

    about = shared(scenario).get("scenario", {})
    summary: dict[str, Any] = {
        "scenario": about.get("name", ""),
        "description": about.get("description", ""),
        "wall_time_s": wall_time_s,
        "axes": axes,
    }
    if len(axes) == 2:
        c = contour(run_dir, sorted(axes))
        c.pop("_series")
        summary["contour"] = c
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=True))
    return summary


def format_axes_summary(summary: dict[str, Any]) -> str:
    """A multi-axis summary as text: each axis, then the contour per cycle (um)."""
    lines = [f"scenario          {summary['scenario']}  (axes {', '.join(summary['axes'])})"]
    for axis, s in summary["axes"].items():
        lines += ["", f"== axis {axis}", format_summary(s)]
    c = summary.get("contour")
    if c:
        lines += [
            "",
            f"== contour: circle of radius {1e3 * c['radius_m']:.3f} mm "
            f"(target off the circle by {_um(c['target_radial_deviation_m'])} um)",
            f"circular deviation {_um(c['circular_deviation_m'])} um, "
            f"max radial error {_um(c['max_radial_m'])} um",
            "cycle   circular deviation (um)   max radial error (um)",
        ]
        for row in c["cycles"]:
            lines.append(
                f"{row['cycle']:>5} {_um(row['circular_deviation_m']):>25} "
                f"{_um(row['max_radial_m']):>23}"
            )
    return "\n".join(lines)


def plot_contour(run_dir: Path) -> Path:
    """``contour.png``: the path of the first and last cycle with the radial
    error magnified (000 Fig. 18), and the circular deviation per cycle."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = json.loads((run_dir / "summary.json").read_text())
    c = contour(run_dir, summary["contour"]["axes"])
    steps, _target, measured, radial = c["_series"]
    centre, radius = np.array(c["centre_m"]), c["radius_m"]
    per_cycle = round(
        summary["axes"][c["axes"][0]]["reference_period_s"]
        / summary["axes"][c["axes"][0]]["control_period_s"]
    )
    gain = 0.2 * radius / max(c["max_radial_m"], 1e-15)
    fig, (xy, bars) = plt.subplots(1, 2, figsize=(11, 5))
    angle = np.arctan2(*(measured - centre).T[::-1])
    phi = np.linspace(0, 2 * np.pi, 400)
    xy.plot(
        1e3 * (centre[0] + radius * np.cos(phi)),
        1e3 * (centre[1] + radius * np.sin(phi)),
        "k:",
        lw=0.8,
        label="target",
    )
    last = max(0, (int(steps.max()) + 1) // per_cycle - 1)  # the last whole cycle
    for cycle, style in ((0, "-"), (last, "-")):
        inside = (steps >= cycle * per_cycle) & (steps < (cycle + 1) * per_cycle)
        r = radius + gain * radial[inside]
        xy.plot(
            1e3 * (centre[0] + r * np.cos(angle[inside])),
            1e3 * (centre[1] + r * np.sin(angle[inside])),
            style,
            lw=0.9,
            label=f"cycle {cycle + 1}",
        )
    xy.set_aspect("equal")
    xy.set_xlabel(f"{c['axes'][0]} (mm)")
    xy.set_ylabel(f"{c['axes'][1]} (mm)")
    xy.set_title(f"radial error x {gain:,.0f}")
    xy.legend(fontsize="small")
    rows = summary["contour"]["cycles"]
    bars.bar([r["cycle"] for r in rows], [1e6 * r["circular_deviation_m"] for r in rows])
    bars.set_xlabel("cycle")
    bars.set_ylabel("circular deviation (um)")
    bars.set_title(f"{summary['scenario']}: circularity per cycle")
    bars.grid(True, lw=0.3)
    fig.tight_layout()
    path = run_dir / "contour.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def format_any_summary(summary: dict[str, Any]) -> str:
    """:func:`format_axes_summary` for a multi-axis run, else :func:`format_summary`."""
    return format_axes_summary(summary) if "axes" in summary else format_summary(summary)
