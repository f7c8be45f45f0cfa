"""The contour error of a two-axis run as in ``summary.json`` (000 Fig. 18; no series)."""

from __future__ import annotations

from dataclasses import dataclass

from servo_axis.analysis.metrics import ContourCycle, ContourResult
from servo_axis.analysis.serial import Serial


@dataclass(frozen=True)
class ContourSummary(Serial):
    """Contour error of a two-axis run as in ``summary.json`` (no series).

    Attributes
    ----------
    axes : tuple of str
        The two axes, in the order of the coordinates.
    centre_m, radius_m, target_radial_deviation_m, circular_deviation_m, max_radial_m, cycles
        As in :class:`~servo_axis.analysis.metrics.ContourResult`.
    """

    axes: tuple[str, ...]
    centre_m: tuple[float, ...]
    radius_m: float
    target_radial_deviation_m: float
    circular_deviation_m: float
    max_radial_m: float
    cycles: tuple[ContourCycle, ...]

    @classmethod
    def from_result(
        cls, axes: list[str] | tuple[str, ...], result: ContourResult
    ) -> ContourSummary:
        """The summary of a computed contour of ``axes``."""
        return cls.from_dict({"axes": list(axes), **result.to_summary()})
