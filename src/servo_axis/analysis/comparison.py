"""Whether runs can be compared: the same control period, cycle and reference.

``python -m servo_axis compare`` puts runs side by side cycle by cycle or by
their RMSD; that means something only when they followed the same reference
at the same control period with the same cycle. :func:`differences` says
what differs (the command refuses such runs unless ``--force``).

The reference of a run is read from the scenario it recorded
(``scenario.yaml``, or the ``params.yaml`` of a run made before runs kept
it: :mod:`servo_axis.params.recorded`), never from the scenario file as it
is now; a run with neither is compared by its summary alone (period and
cycle). Nothing here imports rclpy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from servo_axis.analysis.summary import RunSummary
from servo_axis.core.errors import ServoAxisError
from servo_axis.params.factories import REFERENCE_KEYS
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.resolve import Resolved


def run_reference(run_dir: Path, summary: RunSummary) -> dict[str, Any] | None:
    """The reference a run followed: ``reference.kind`` and the keys of that kind.

    Parameters
    ----------
    run_dir : Path
        The run directory (its recorded scenario is read,
        :func:`~servo_axis.params.recorded.recorded_scenario`).
    summary : RunSummary
        Its summary.

    Returns
    -------
    dict or None
        ``{"reference.kind": ..., "reference.<key>": value, ...}`` (SI units as
        in the scenario), None when the run recorded no scenario that reads.
    """
    try:
        resolved = Resolved(recorded_scenario(Path(run_dir), summary.scenario_file).scenario)
        if not resolved.has("feedforward"):
            return None
        reference = resolved.feedforward.reference
    except (OSError, ValueError, yaml.YAMLError, ServoAxisError):
        return None
    return {
        "reference.kind": reference.kind,
        **{f"reference.{k}": reference[k] for k in REFERENCE_KEYS.get(reference.kind, ())},
    }


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-12)
    return bool(a == b)


def _show(value: Any, unit: str = "") -> str:
    if value is None:
        return "none"
    text = f"{value:g}" if isinstance(value, float) else str(value)
    return f"{text} {unit}".rstrip()


def differences(
    run_dirs: Sequence[Path], summaries: Sequence[RunSummary], labels: Sequence[str]
) -> list[str]:
    """What differs between runs that a comparison needs equal, one phrase each.

    Compared: the control period ``T_u``, the cycle (the learning cycle or
    the reference's period; none for a reference that does not repeat) and
    the reference (:func:`run_reference`, for the runs whose reference is
    known). Each phrase names the quantity and every run's value, e.g.
    ``cycle: ptc 0.5 s, piddist 0.25 s``. Empty: the runs compare.
    """
    found: list[str] = []

    def note(name: str, named: Sequence[tuple[str, Any]], unit: str = "") -> None:
        values = [v for _, v in named]
        if any(not _same(v, values[0]) for v in values[1:]):
            found.append(f"{name}: " + ", ".join(f"{lb} {_show(v, unit)}" for lb, v in named))

    runs = list(zip(labels, summaries, strict=True))
    note("control period", [(lb, s.control_period_s) for lb, s in runs], "s")
    note("cycle", [(lb, s.reference_period_s) for lb, s in runs], "s")
    refs = [run_reference(Path(d), s) for d, s in zip(run_dirs, summaries, strict=True)]
    known = [(lb, ref) for lb, ref in zip(labels, refs, strict=True) if ref is not None]
    if len(known) > 1:
        note("reference.kind", [(lb, ref["reference.kind"]) for lb, ref in known])
        if not any(ref["reference.kind"] != known[0][1]["reference.kind"] for _, ref in known):
            for key in list(known[0][1])[1:]:
                note(key, [(lb, ref[key]) for lb, ref in known])
    return found
