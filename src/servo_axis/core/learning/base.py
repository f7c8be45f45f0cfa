"""The learning-law protocol and the memory a learning unit persists.

A learning law turns the tracking error of one period into the correction
of the next period:

* ``period = "cycle"``: repetitive control (paper 000): the reference
  repeats with the learning cycle and the correction carries over cycle to
  cycle;
* ``period = "trial"``: iterative learning control (paper 001): trials of
  ``N`` samples, each starting and ending at rest.

The correction acts on one side of the loop:

* ``side = "target"``: added to the target trajectory ``x_d`` before PTC
  (000 Fig. 5, 9): it shifts the feedforward and the feedback reference
  alike; published per reference instant as ``(position, velocity)``;
* ``side = "input"``: a current added to the control input (001 eq. (3)),
  per control sample.

A law is a module in this folder with a class that satisfies
:class:`LearningLaw`, plus its registration (``learning.law``) in
:mod:`servo_axis.params.factories`. The learning unit node does the rest
(collecting the error, persisting, publishing).

The memory is a JSON text: format tag, law, scenario, the parameters that
must match for it to be reused (``identity``), the law's ``state`` and a
SHA-256 of the state, so that a truncated, edited or foreign memory is
detected. Reading and writing the file is the caller's (core does no I/O).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import TableError

FloatArray = NDArray[np.float64]

MEMORY_FORMAT = "servo_axis learning memory v2"


class LearningLaw(Protocol):
    """What the learning unit needs from a learning law."""

    #: Registered name (``learning.law``).
    name: str
    #: ``"cycle"`` or ``"trial"``.
    period: str
    #: ``"target"`` or ``"input"``.
    side: str

    @property
    def samples_per_period(self) -> int:
        """Error samples per period (reference instants for a target-side law)."""
        ...

    @property
    def periods_learned(self) -> int:
        """Periods learned so far."""
        ...

    def learn(self, error: FloatArray, *, period: int | None = None) -> object:
        """Learn one period's error (``samples_per_period`` values).

        ``period`` is the 1-based number of the period (cycle, trial) the
        error was measured in; a trial law needs it (the reference of a trial
        may differ from the next one's), a cycle law may ignore it. The unit
        of the error is the law's (rad for ``rptc``, m at the table for the
        trial laws).
        """
        ...

    def next_correction(self, *, period: int | None = None) -> tuple[FloatArray, ...]:
        """The correction for period ``period`` (1-based; the next one).

        ``(position, velocity)`` per reference instant (target side) or
        ``(current,)`` per control sample (input side).
        """
        ...

    def identity(self) -> dict[str, Any]:
        """The parameters a memory must have been written with to be reused."""
        ...

    def state(self) -> dict[str, Any]:
        """The memory as JSON-able values."""
        ...

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore a memory written from :meth:`state` (checks lengths and values)."""
        ...


class IdentifyingLaw(LearningLaw, Protocol):
    """A law that also identifies the plant (projection-based ILC, paper 001 Sect. III-B/C)."""

    def physical_parameters(self) -> dict[str, float]:
        """``inertia_kgm2``, ``damping_Nms_per_rad``, ``coulomb_Nm`` as identified (001 eq. (14b))."""
        ...

    def friction_table(self) -> tuple[FloatArray, FloatArray]:
        """The data-based friction table (001 Fig. 8): ``x_r`` (m) and torque (N m); empty if none."""
        ...


def _digest(state: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(state, sort_keys=True).encode()).hexdigest()


def encode_memory(law: LearningLaw, *, scenario: str) -> str:
    """The memory text of ``law`` for ``scenario`` (exact float text)."""
    state = law.state()
    body = {
        "format": MEMORY_FORMAT,
        "law": law.name,
        "scenario": scenario,
        "identity": law.identity(),
        "periods_learned": law.periods_learned,
        "state": state,
        "sha256": _digest(state),
    }
    return json.dumps(body)


def decode_memory(
    text: str, law: LearningLaw, *, scenario: str, source: str = "memory"
) -> dict[str, Any]:
    """The state of a memory text after checking it belongs to ``law`` and ``scenario``.

    Raises
    ------
    TableError
        Naming ``source`` and what is wrong: not JSON or truncated, another
        format, a checksum mismatch, another law, scenario or parameters.
    """
    try:
        body = json.loads(text)
    except ValueError as err:
        raise TableError(
            f"{source}: not a readable memory file (corrupt or truncated): {err}"
        ) from None
    if not isinstance(body, dict) or body.get("format") != MEMORY_FORMAT:
        raise TableError(f"{source}: expected format {MEMORY_FORMAT!r}")
    state = body.get("state")
    if not isinstance(state, dict) or body.get("sha256") != _digest(state):
        raise TableError(f"{source}: the memory does not match its checksum (corrupt or edited)")
    # The file's own law and scenario come last: an identity that repeats
    # the law's name must not hide a file of another law.
    expected = {**law.identity(), "law": law.name, "scenario": scenario}
    identity = body.get("identity")
    got = {
        **(identity if isinstance(identity, dict) else {}),
        "law": body.get("law"),
        "scenario": body.get("scenario"),
    }
    for key, value in expected.items():
        if got.get(key) != value:
            raise TableError(f"{source}: {key} is {got.get(key)!r}, this run has {value!r}")
    return state
