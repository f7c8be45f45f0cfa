"""The Generalized Maxwell-Slip friction model (GMS), its parameter text and its fit.

The conventional GMS model of Al-Bender, Lampaert and Swevers (IEEE TAC
50(11), 2005; "Al-Bender et al. 2005" below) is the friction model that
paper 004 (Sect. II-A, Fig. 4(b); dashed line) fits to a slow 50 um,
0.05 Hz reversal of the ball-screw X axis and compensates with (its
Fig. 6), the baseline of its sigmoid law. N elementary state models in
parallel share the displacement; element ``i`` carries ``F_i``:

* sticking: ``dF_i/dt = k_i v`` (an elastic asperity junction);
* slipping: ``dF_i/dt = C (sgn(v) alpha_i s(v) - F_i)``, an exponential
  approach to ``sgn(v) alpha_i s(v)``;
* an element slips once ``|F_i|`` reaches ``alpha_i s(v)`` and sticks again
  when the velocity changes sign or is 0;

and the friction is ``F = sum_i F_i + sigma_2 v`` with the Stribeck curve
``s(v) = F_c + (F_s - F_c) exp(-|v / V_s|^delta)`` (``sum_i alpha_i = 1``).

Units: the displacement is the TABLE position (m) and the friction is the
motor torque (N m) that overcomes it, so ``k_i`` is in N m per m of table
travel. Sign: ``F`` has the sign of the motion in sliding (``+F_c`` at
``v > 0``): the torque the motor must supply, the convention of the
friction table (:mod:`servo_axis.core.feedforward.friction_table`), so that
a compensation adds it to the command as it is.

The slip rule: Al-Bender et al. 2005 write it
``dF_i/dt = sgn(v) C' (1 - F_i / (alpha_i s(v)))`` with ``C'`` in force per
second; taken literally it has no stable fixed point for ``v < 0``, so the
intended approach to ``sgn(v) alpha_i s(v)`` is written here with the rate
normalised by the element's level: ``C = C' / (alpha_i s(v))`` in 1/s, the
same time constant ``1/C`` for every element.

Nothing here reads a file, a clock or a logger.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import NoReturn

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from servo_axis.core.errors import (
    ConfigError,
    SignalError,
    TableError,
    require_finite,
    require_nonnegative,
    require_positive,
)

FloatArray = NDArray[np.float64]

#: First line of a GMS parameter file.
HEADER_LINE = "# servo_axis GMS parameters v1"

#: Most elements a model may have (each costs a few floating-point operations per sample).
MAX_ELEMENTS = 20

#: Tolerance on ``sum(weights) == 1``.
WEIGHT_SUM_TOLERANCE = 1e-9

#: Default ``C`` (1/s): a slipping element's deficit decays as ``exp(-C t)``, i.e. over
#: ``v / C`` of travel; five of these (0.7 % left) are 0.1 um at 10 mm/s, 1/100 of the
#: ~10 um pre-sliding distance of the ball-screw axis (docs/design.md section 7; 15 um in paper 004
#: Fig. 4(b)). At the slow reversals of an identification run it is the rate-independent
#: limit ``C -> infinity`` to a few nm.
DEFAULT_ATTRACTION_PER_S = 5e5


def _float_tuple(name: str, value: object) -> tuple[float, ...]:
    if isinstance(value, str | bytes) or not isinstance(value, Sequence | np.ndarray):
        raise ConfigError(f"{name}: expected a sequence of numbers, got {value!r}")
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}: expected a sequence of numbers, got {value!r}") from None
    return out


@dataclass(frozen=True, kw_only=True)
class GmsParams:
    """Parameters of the GMS model (Al-Bender et al. 2005), at the motor per m of table.

    Parameters
    ----------
    stiffness_Nm_per_m : tuple of float
        ``k_i``: the stiffness of each element while it sticks, N m of motor
        torque per m of table displacement, each > 0; 1..20 elements.
    weights : tuple of float
        ``alpha_i``: the share of the sliding level each element carries,
        each > 0, one per element, summing to 1 (within 1e-9). Element ``i``
        breaks away after ``alpha_i F_c / k_i`` (m) on the virgin curve.
    coulomb_Nm : float
        ``F_c``, the sliding level, N m, > 0 (3.2 N m for the ball-screw X
        axis of paper 001).
    static_Nm : float or None
        ``F_s``, the level at rest (Stribeck), N m, >= ``coulomb_Nm``.
        None (default): ``coulomb_Nm``, no Stribeck effect; the attribute
        holds that float after construction.
    stribeck_velocity_m_s : float
        ``V_s``, table velocity, m/s, > 0 (1e-3).
    stribeck_exponent : float
        ``delta`` of the Stribeck curve, > 0 (2.0, Gaussian).
    attraction_per_s : float
        ``C`` of the slip rule, 1/s, > 0: a slipping element approaches its
        level as ``exp(-C t)`` (see the module docstring for the relation to
        Al-Bender et al.'s ``C`` in N/s). Default
        :data:`DEFAULT_ATTRACTION_PER_S` (5e5: the level within 0.7 % after
        0.1 um at 10 mm/s).
    viscous_Nms_per_m : float
        ``sigma_2``, viscous friction, N m s per m of table, >= 0 (0).

    Raises
    ------
    ConfigError
        Naming the field at fault.
    """

    stiffness_Nm_per_m: tuple[float, ...]
    weights: tuple[float, ...]
    coulomb_Nm: float
    static_Nm: float | None = None
    stribeck_velocity_m_s: float = 1e-3
    stribeck_exponent: float = 2.0
    attraction_per_s: float = DEFAULT_ATTRACTION_PER_S
    viscous_Nms_per_m: float = 0.0

    def __post_init__(self) -> None:
        k = _float_tuple("stiffness_Nm_per_m", self.stiffness_Nm_per_m)
        if not 1 <= len(k) <= MAX_ELEMENTS:
            raise ConfigError(
                f"stiffness_Nm_per_m: expected 1..{MAX_ELEMENTS} elements, got {len(k)}"
            )
        for i, v in enumerate(k):
            require_positive(f"stiffness_Nm_per_m[{i}]", v)
        w = _float_tuple("weights", self.weights)
        if len(w) != len(k):
            raise ConfigError(
                f"weights: expected one per element ({len(k)}, as stiffness_Nm_per_m), got {len(w)}"
            )
        for i, v in enumerate(w):
            require_positive(f"weights[{i}]", v)
        total = math.fsum(w)
        if abs(total - 1.0) > WEIGHT_SUM_TOLERANCE:
            raise ConfigError(
                f"weights: expected a sum of 1 (within {WEIGHT_SUM_TOLERANCE:g}), got {total!r}"
            )
        fc = require_positive("coulomb_Nm", self.coulomb_Nm)
        fs = fc if self.static_Nm is None else require_finite("static_Nm", self.static_Nm)
        if fs < fc:
            raise ConfigError(
                f"static_Nm: expected a value >= coulomb_Nm ({fc!r}), got {self.static_Nm!r}"
            )
        vs = require_positive("stribeck_velocity_m_s", self.stribeck_velocity_m_s)
        delta = require_positive("stribeck_exponent", self.stribeck_exponent)
        c = require_positive("attraction_per_s", self.attraction_per_s)
        sigma2 = require_nonnegative("viscous_Nms_per_m", self.viscous_Nms_per_m)
        for name, value in (
            ("stiffness_Nm_per_m", k),
            ("weights", w),
            ("coulomb_Nm", fc),
            ("static_Nm", fs),
            ("stribeck_velocity_m_s", vs),
            ("stribeck_exponent", delta),
            ("attraction_per_s", c),
            ("viscous_Nms_per_m", sigma2),
        ):
            object.__setattr__(self, name, value)

    @property
    def elements(self) -> int:
        """Number of elements N."""
        return len(self.stiffness_Nm_per_m)

    @property
    def breakaway_m(self) -> tuple[float, ...]:
        """Virgin-curve break-away displacement ``alpha_i F_c / k_i`` of each element, m."""
        return tuple(
            a * self.coulomb_Nm / k
            for a, k in zip(self.weights, self.stiffness_Nm_per_m, strict=True)
        )

    def stribeck(self, velocity_m_s: ArrayLike) -> FloatArray:
        """``s(v) = F_c + (F_s - F_c) exp(-|v / V_s|^delta)``, N m, per table velocity (m/s)."""
        v = np.asarray(velocity_m_s, dtype=float)
        fs = self.coulomb_Nm if self.static_Nm is None else self.static_Nm
        return np.asarray(
            self.coulomb_Nm
            + (fs - self.coulomb_Nm)
            * np.exp(-(np.abs(v / self.stribeck_velocity_m_s) ** self.stribeck_exponent)),
            dtype=float,
        )

    def virgin_curve(self, displacement_m: ArrayLike) -> FloatArray:
        """Quasi-static torque from the virgin state, N m (``C -> infinity``, ``|v| << V_s``).

        ``F(d) = sum_i sgn(d) min(k_i |d|, alpha_i F_c)`` (odd in ``d``, m).
        """
        d = np.asarray(displacement_m, dtype=float)
        out = np.zeros_like(d)
        for k, a in zip(self.stiffness_Nm_per_m, self.weights, strict=True):
            out = out + np.minimum(k * np.abs(d), a * self.coulomb_Nm)
        return np.asarray(np.sign(d) * out, dtype=float)

    def reversal_curve(self, displacement_m: ArrayLike) -> FloatArray:
        """Quasi-static torque after a reversal from full sliding, N m (``C -> infinity``).

        For motion in the positive direction after sliding in the negative
        one, against the displacement ``d >= 0`` (m) from the reversal:
        ``F(d) = sum_i [-alpha_i F_c + k_i min(d, 2 alpha_i F_c / k_i)]``, from
        ``-F_c`` to ``+F_c``; Masing's rule makes it ``-F_c + 2 F_virgin(d / 2)``.
        """
        d = np.asarray(displacement_m, dtype=float)
        out = np.zeros_like(d)
        for k, a in zip(self.stiffness_Nm_per_m, self.weights, strict=True):
            level = a * self.coulomb_Nm
            out = out - level + k * np.minimum(d, 2.0 * level / k)
        return out

    def to_text(self, *, plant_model: str, plant_fingerprint: str) -> str:
        """The parameters as the line-based text :func:`gms_from_text` reads.

        ``plant_model`` and ``plant_fingerprint`` name the plant the fit was
        made on (one line each, not empty). Floats are written with ``repr``
        so that a round trip is exact.
        """
        for name, value in (("plant_model", plant_model), ("plant_fingerprint", plant_fingerprint)):
            if not isinstance(value, str) or not value.strip() or value != value.strip():
                raise ConfigError(f"{name}: expected a non-empty string, got {value!r}")
            if "\n" in value or "\r" in value:
                raise ConfigError(f"{name}: expected one line, got {value!r}")
        lines = [
            HEADER_LINE,
            f"plant_model = {plant_model}",
            f"plant_fingerprint = {plant_fingerprint}",
        ]
        for f in fields(self):
            value = getattr(self, f.name)
            text = ", ".join(repr(v) for v in value) if isinstance(value, tuple) else repr(value)
            lines.append(f"{f.name} = {text}")
        return "\n".join(lines) + "\n"


_TUPLE_KEYS = ("stiffness_Nm_per_m", "weights")
_FLOAT_KEYS = (
    "coulomb_Nm",
    "static_Nm",
    "stribeck_velocity_m_s",
    "stribeck_exponent",
    "attraction_per_s",
    "viscous_Nms_per_m",
)
_TEXT_KEYS = ("plant_model", "plant_fingerprint", *_TUPLE_KEYS, *_FLOAT_KEYS)


def _number(source: str, number: int, key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TableError(
            f"{source}: line {number}: {key}: expected a number, got {text.strip()!r}"
        ) from None
    if not math.isfinite(value):
        raise TableError(f"{source}: line {number}: {key}: expected a finite number, got {value!r}")
    return value


def gms_from_text(text: str, *, source: str) -> tuple[GmsParams, str, str]:
    """Read the text :meth:`GmsParams.to_text` writes.

    Parameters
    ----------
    text : str
        The file's content.
    source : str
        What the text came from (a file name), for the messages.

    Returns
    -------
    tuple
        ``(params, plant_model, plant_fingerprint)``.

    Raises
    ------
    TableError
        Naming ``source`` and what is wrong: a wrong header, a line that is
        not ``key = value``, an unknown, repeated or missing key, a bad or
        non-finite number, lists of unequal lengths or any other value the
        parameters refuse (the field named).
    """
    lines = text.splitlines()
    if not lines or lines[0].strip() != HEADER_LINE:
        got = lines[0].strip() if lines else ""
        raise TableError(f"{source}: line 1: expected header {HEADER_LINE!r}, got {got!r}")
    raw: dict[str, tuple[int, str]] = {}
    for number, line in enumerate(lines[1:], start=2):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        key, sep, value = stripped.partition("=")
        key = key.strip()
        if not sep or not key:
            raise TableError(f"{source}: line {number}: expected 'key = value', got {stripped!r}")
        if key not in _TEXT_KEYS:
            raise TableError(f"{source}: line {number}: unknown key {key!r}")
        if key in raw:
            raise TableError(f"{source}: line {number}: key {key!r} given twice")
        raw[key] = (number, value.strip())
    missing = [k for k in _TEXT_KEYS if k not in raw]
    if missing:
        raise TableError(f"{source}: missing key(s) {', '.join(missing)}")
    for key in ("plant_model", "plant_fingerprint"):
        if not raw[key][1]:
            raise TableError(f"{source}: line {raw[key][0]}: {key}: expected a non-empty value")
    tuples = {
        key: tuple(_number(source, raw[key][0], key, part) for part in raw[key][1].split(","))
        for key in _TUPLE_KEYS
    }
    floats = {key: _number(source, raw[key][0], key, raw[key][1]) for key in _FLOAT_KEYS}
    k, w = tuples["stiffness_Nm_per_m"], tuples["weights"]
    if len(k) != len(w):
        raise TableError(
            f"{source}: unequal lengths: stiffness_Nm_per_m has {len(k)} values, weights {len(w)}"
        )
    try:
        params = GmsParams(
            stiffness_Nm_per_m=k,
            weights=w,
            coulomb_Nm=floats["coulomb_Nm"],
            static_Nm=floats["static_Nm"],
            stribeck_velocity_m_s=floats["stribeck_velocity_m_s"],
            stribeck_exponent=floats["stribeck_exponent"],
            attraction_per_s=floats["attraction_per_s"],
            viscous_Nms_per_m=floats["viscous_Nms_per_m"],
        )
    except ConfigError as err:
        raise TableError(f"{source}: {err}") from err
    return params, raw["plant_model"][1], raw["plant_fingerprint"][1]


class GmsModel:
    """The GMS model (Al-Bender et al. 2005) stepped one sample at a time.

    Each element keeps its force ``F_i`` (N m) and whether it slips. Per
    sample (:meth:`update`), for the position increment ``dx`` since the
    previous sample and the velocity ``v`` of this one:

    * when ``v`` changes sign or is 0, every element sticks;
    * a sticking element takes ``F_i + k_i dx``; once ``|F_i|`` reaches
      ``alpha_i s(v)`` it is held there and slips from then on (the level is
      the slip rule's fixed point, so this is exact for constant ``v``);
    * a slipping element follows the slip rule integrated exactly over the
      sample for constant ``v``:
      ``F_i <- L + (F_i - L) exp(-C T)``, ``L = sgn(v) alpha_i s(v)``.

    The torque is ``sum_i F_i + sigma_2 v``. Plain float arithmetic on at
    most 20 elements: deterministic and cheap.

    Parameters
    ----------
    params : GmsParams
        The model.
    compiled : bool
        Step :meth:`update_many` with the compiled
        :func:`~servo_axis.core.friction.gms_kernels.gms_block` (the same numbers; it
        loads numba when the model is built), else with :meth:`update`.
    """

    def __init__(self, params: GmsParams, *, compiled: bool = False) -> None:
        self.params = params
        self._k = list(params.stiffness_Nm_per_m)
        self._alpha = list(params.weights)
        self._fc = params.coulomb_Nm
        self._fs = params.coulomb_Nm if params.static_Nm is None else params.static_Nm
        self._vs = params.stribeck_velocity_m_s
        self._delta = params.stribeck_exponent
        self._c = params.attraction_per_s
        self._sigma2 = params.viscous_Nms_per_m
        n = len(self._k)
        self._force = [0.0] * n
        self._slipping = [False] * n
        self._last: float | None = None
        self._sign = 0
        # Per sample the same few values recur: the decay of the slip rule for the
        # period (one period in a run), and the elements' levels alpha_i s(v) for the
        # Stribeck level (F_c without a Stribeck effect). Each is kept with what it
        # was computed from, and computed again (the same floats) when that changes.
        self._decay_period = 0.0
        self._decay = 1.0
        self._levels_of: float | None = None
        self._pairs = [(k, 0.0) for k in self._k]  # (k_i, alpha_i s) once computed
        self._stribeck = self._fs != self._fc
        self._sticking = (False,) * n
        self._block: Callable[..., None] | None = None
        if compiled:
            from servo_axis.core.friction.gms_kernels import gms_block

            self._block = gms_block

    def reset(self) -> None:
        """Relax every element (virgin state); the next :meth:`update` sets the position."""
        n = len(self._k)
        self._force[:] = [0.0] * n
        self._slipping[:] = [False] * n
        self._last = None
        self._sign = 0

    @property
    def forces_Nm(self) -> tuple[float, ...]:
        """The element forces ``F_i``, N m."""
        return tuple(self._force)

    @property
    def slipping(self) -> tuple[bool, ...]:
        """Whether each element slips."""
        return tuple(self._slipping)

    def update(self, position_m: float, velocity_m_s: float, period_s: float) -> float:
        """Advance one sample and return the friction torque, N m.

        Parameters
        ----------
        position_m : float
            Table position at this sample, m. The first call after
            construction or :meth:`reset` only sets it (no increment).
        velocity_m_s : float
            Table velocity at this sample, m/s (its sign decides the
            direction of slip and the re-sticking; its size the Stribeck
            level and the viscous term).
        period_s : float
            Time since the previous sample, s, > 0 (the slip rule's step).

        Raises
        ------
        SignalError
            For a non-finite argument or ``period_s <= 0``, naming it.
        """
        isfinite = math.isfinite
        if not (
            isfinite(position_m) and isfinite(velocity_m_s) and isfinite(period_s) and period_s > 0
        ):
            self._refuse(position_m, velocity_m_s, period_s)
        v = velocity_m_s
        sign = 1 if v > 0.0 else (-1 if v < 0.0 else 0)
        force = self._force
        slipping = self._slipping
        if sign != self._sign or sign == 0:
            slipping[:] = self._sticking
        self._sign = sign
        last = self._last
        self._last = position_m
        if last is None:
            return math.fsum(force) + self._sigma2 * v
        dx = position_m - last
        s = self._fc
        if self._stribeck:
            s += (self._fs - self._fc) * math.exp(-(abs(v / self._vs) ** self._delta))
        if period_s != self._decay_period:
            self._decay = math.exp(-self._c * period_s)
            self._decay_period = period_s
        decay = self._decay
        if s != self._levels_of:
            self._pairs = [(k, a * s) for k, a in zip(self._k, self._alpha, strict=True)]
            self._levels_of = s
        i = 0
        for k, level in self._pairs:
            if slipping[i]:
                target = sign * level
                force[i] = target + (force[i] - target) * decay
            else:
                f = force[i] + k * dx
                # Break-away: held at the level, and slipping only in the direction of motion
                # (a position step against the velocity's sign, which consistent inputs never
                # give, must not start a slip towards the other level).
                if f >= level:
                    f = level
                    slipping[i] = sign > 0
                elif f <= -level:
                    f = -level
                    slipping[i] = sign < 0
                force[i] = f
            i += 1
        return math.fsum(force) + self._sigma2 * v

    def update_many(
        self, positions_m: list[float], velocities_m_s: list[float], periods_s: list[float]
    ) -> list[float]:
        """:meth:`update` of each sample in turn: the torques, N m (the same numbers).

        Compiled (``compiled=True``) when every argument is finite and every
        period > 0; else sample by sample, which raises at the first bad one.
        """
        block = self._block
        pos = np.array(positions_m, dtype=float)
        vel = np.array(velocities_m_s, dtype=float)
        per = np.array(periods_s, dtype=float)
        if (
            block is None
            or not (len(pos) == len(vel) == len(per))
            or not (np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(per).all())
            or not (per > 0.0).all()
        ):
            return [
                self.update(p, v, t)
                for p, v, t in zip(positions_m, velocities_m_s, periods_s, strict=True)
            ]
        force = np.array(self._force, dtype=float)
        slipping = np.array(self._slipping, dtype=bool)
        state = np.array(
            [
                0.0 if self._last is None else 1.0,
                0.0 if self._last is None else self._last,
                self._sign,
                self._fc,
                self._fs,
                self._vs,
                self._delta,
                self._c,
                self._sigma2,
                1.0 if self._stribeck else 0.0,
            ]
        )
        out = np.empty(len(pos))
        block(
            np.array(self._k, dtype=float),
            np.array(self._alpha, dtype=float),
            force,
            slipping,
            state,
            pos,
            vel,
            per,
            out,
            np.empty(len(force) + 1),
        )
        self._force[:] = force.tolist()
        self._slipping[:] = slipping.tolist()
        if state[0] != 0.0:
            self._last = float(state[1])
        self._sign = int(state[2])
        torques: list[float] = out.tolist()
        return torques

    @staticmethod
    def _refuse(position_m: float, velocity_m_s: float, period_s: float) -> NoReturn:
        """Raise the SignalError of :meth:`update` for the first argument at fault."""
        if not math.isfinite(position_m):
            raise SignalError(f"position_m: expected a finite number, got {position_m!r}")
        if not math.isfinite(velocity_m_s):
            raise SignalError(f"velocity_m_s: expected a finite number, got {velocity_m_s!r}")
        raise SignalError(f"period_s: expected a finite value > 0, got {period_s!r}")


def simulate_gms(
    params: GmsParams, position_m: ArrayLike, velocity_m_s: ArrayLike, *, period_s: float
) -> FloatArray:
    """GMS torque (N m) along a sampled path, from the virgin state.

    Parameters
    ----------
    params : GmsParams
        The model.
    position_m, velocity_m_s : array, shape (n,)
        Table position (m) and velocity (m/s) at each sample.
    period_s : float
        Sample period, s, > 0.
    """
    pos = np.asarray(position_m, dtype=float)
    vel = np.asarray(velocity_m_s, dtype=float)
    if pos.ndim != 1 or pos.shape != vel.shape:
        raise SignalError(
            f"position_m, velocity_m_s: expected 1-D arrays of one length, "
            f"got shapes {pos.shape} and {vel.shape}"
        )
    model = GmsModel(params)
    update = model.update
    return np.array(
        [update(p, v, period_s) for p, v in zip(pos.tolist(), vel.tolist(), strict=True)],
        dtype=float,
    )


# --------------------------------------------------------------------------- fit


#: A fit simulates at most this many samples per evaluation (longer paths are subsampled)...
MAX_FIT_SAMPLES = 5000
#: ... and at most this many element-samples, but never fewer than 1000 samples: the cost
#: of one evaluation and the number of them both grow with the elements (20 elements on
#: 1000 samples take about 5 s, 4 elements on 5000 samples below 1 s).
FIT_ELEMENT_SAMPLES = 20000

_MIN_SAMPLES = 8


@dataclass(frozen=True)
class GmsFit:
    """A GMS model fitted to a slow reversal (:func:`fit_gms`).

    Attributes
    ----------
    params : GmsParams
        The fitted model, elements in order of increasing break-away
        displacement ``alpha_i F_c / k_i``.
    rms_residual_Nm : float
        RMS of measured minus model torque over the samples from the first
        reversal on, at the full rate, N m.
    model_torque_Nm : ndarray
        The fitted model's torque along the whole given path (from the
        virgin state at its first sample), N m.
    """

    params: GmsParams
    rms_residual_Nm: float
    model_torque_Nm: FloatArray


def _signal(name: str, value: ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SignalError(f"{name}: expected a 1-D array of numbers") from None
    if arr.ndim != 1:
        raise SignalError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SignalError(f"{name}: expected finite values, got NaN or inf")
    return arr


def _directions(velocity: FloatArray) -> NDArray[np.int64]:
    """The direction of motion per sample, a zero velocity taking the last non-zero sign."""
    sign = np.sign(velocity).astype(np.int64)
    moving = np.flatnonzero(sign)
    if moving.size == 0:
        return sign
    # Forward-fill the zeros with the previous sign (the leading ones with the first).
    last = np.maximum.accumulate(np.where(sign != 0, np.arange(sign.size), -1))
    last[last < 0] = moving[0]
    return sign[last]


def _initial_guess(
    position: FloatArray,
    torque: FloatArray,
    direction: NDArray[np.int64],
    reversals: NDArray[np.int64],
    elements: int,
) -> tuple[float, list[float], list[float]]:
    """``(F_c, k_i, alpha_i)`` to start from, read off the data.

    The sliding level is first taken roughly from the far half of each
    branch, the pre-sliding distance ``x_s`` as the median over the branches
    of the displacement where the signed torque first reaches 90 % of it;
    then ``F_c`` is the median ``|torque|`` beyond ``3 x_s`` and the
    elements share it equally with break-away points spread evenly over
    ``(0, x_s / 2]`` (a reversal sweeps twice the virgin curve's range).
    """
    n = position.size
    first = int(reversals[0])
    anchor = np.empty(n)
    bounds = [*reversals.tolist(), n]
    for start, stop in itertools.pairwise(bounds):
        anchor[start:stop] = position[start - 1]
    d = np.abs(position[first:] - anchor[first:])
    y = direction[first:] * torque[first:]
    far = d >= 0.5 * float(d.max())
    rough = float(np.median(y[far]))
    if not rough > 0.0:
        raise SignalError(
            "torque_Nm: the torque does not follow the direction of motion in sliding "
            f"(median signed level {rough!r} N m); expected the torque that overcomes friction"
        )
    reach: list[float] = []
    for start, stop in itertools.pairwise(bounds):
        hit = np.flatnonzero(y[start - first : stop - first] >= 0.9 * rough)
        if hit.size:
            reach.append(float(d[start - first + hit[0]]))
    x_s = float(np.median(reach)) if reach else 0.5 * float(d.max())
    if not x_s > 0.0:
        x_s = 0.5 * float(d.max())
    sliding = d > 3.0 * x_s
    fc = float(np.median(np.abs(torque[first:][sliding]))) if sliding.any() else rough
    weights = [1.0 / elements] * elements
    breakaway = [0.5 * x_s * (i + 1) / elements for i in range(elements)]
    stiffness = [a * fc / b for a, b in zip(weights, breakaway, strict=True)]
    return fc, stiffness, weights


def fit_gms(
    position_m: ArrayLike,
    torque_Nm: ArrayLike,
    *,
    elements: int,
    period_s: float,
    initial: GmsParams | None = None,
) -> GmsFit:
    """Fit ``k_i``, ``alpha_i`` and ``F_c`` of a GMS model to a slow reversal (paper 004 Fig. 4(b)).

    The model is simulated along the measured position path (velocity
    ``np.gradient(position, period)``) from the virgin state, and the
    squared torque residual is minimised with
    :func:`scipy.optimize.least_squares` over ``log k_i``, ``log F_c`` and
    the weights as a softmax of ``N - 1`` free logits. Only the samples
    from the first reversal on count: the model starts virgin, the axis in
    an unknown state, and the sliding before a reversal wipes out that
    difference (every element slips) provided the motion before the first
    reversal exceeds the pre-sliding distance. Paths longer than
    :data:`MAX_FIT_SAMPLES` (fewer with many elements,
    :data:`FIT_ELEMENT_SAMPLES`) are subsampled for the search, so that a
    fit takes at most a few seconds (stick increments add up exactly, so
    the quasi-static model is the same at the samples kept); the residual
    reported is at the full rate. Deterministic: one start read off the
    data (see :func:`_initial_guess`), no restarts.

    ``F_s`` (kept equal to ``F_c``), ``V_s``, ``delta``, ``C`` and
    ``sigma_2`` are not fitted: a slow reversal never leaves the
    quasi-static regime, where the torque depends only on the displacement
    path, so they are not identifiable from it. They keep their defaults,
    or those of ``initial`` (``F_s`` then at the same ratio to ``F_c``).

    Parameters
    ----------
    position_m : array, shape (n,)
        Table position at each sample, m (the reference of an
        identification run: its sign changes mark the reversals, so it
        should be free of noise).
    torque_Nm : array, shape (n,)
        Friction torque estimate at each sample, N m, with the sign of the
        motion in sliding.
    elements : int
        Number of elements N, 1..20.
    period_s : float
        Sample period, s, > 0.
    initial : GmsParams or None
        Start of the search (N elements) instead of the one read off the data.

    Returns
    -------
    GmsFit

    Raises
    ------
    SignalError
        Arrays of different lengths, non-finite, too short, without motion
        or without a reversal (the argument named).
    ConfigError
        ``elements``, ``period_s`` or ``initial`` out of range.
    """
    pos = _signal("position_m", position_m)
    tq = _signal("torque_Nm", torque_Nm)
    if pos.size != tq.size:
        raise SignalError(
            f"position_m, torque_Nm: expected arrays of one length, got {pos.size} and {tq.size}"
        )
    if isinstance(elements, bool) or not isinstance(elements, int):
        raise ConfigError(f"elements: expected an integer, got {elements!r}")
    if not 1 <= elements <= MAX_ELEMENTS:
        raise ConfigError(f"elements: expected 1..{MAX_ELEMENTS}, got {elements!r}")
    period = require_positive("period_s", period_s)
    if initial is not None and initial.elements != elements:
        raise ConfigError(
            f"initial: expected {elements} elements (as elements), got {initial.elements}"
        )
    n_free = 2 * elements
    if pos.size < _MIN_SAMPLES:
        raise SignalError(f"position_m: expected at least {_MIN_SAMPLES} samples, got {pos.size}")
    vel = np.gradient(pos, period)
    direction = _directions(vel)
    if not np.any(vel != 0.0):
        raise SignalError("position_m: expected motion, the position never changes")
    reversals = np.flatnonzero(direction[1:] != direction[:-1]) + 1
    if reversals.size == 0:
        raise SignalError("position_m: no reversal in the data (the motion never changes sign)")
    first = int(reversals[0])
    budget = min(MAX_FIT_SAMPLES, max(1000, FIT_ELEMENT_SAMPLES // elements))
    stride = max(1, math.ceil(pos.size / budget))
    kept = np.arange(0, pos.size, stride)
    counted = kept >= first
    if int(counted.sum()) < 4 * n_free:
        raise SignalError(
            f"position_m: too short after the first reversal (sample {first}): expected at "
            f"least {4 * n_free * stride} samples there for {elements} elements, "
            f"got {pos.size - first}"
        )

    if initial is None:
        fc0, k0, w0 = _initial_guess(pos, tq, direction, reversals, elements)
        fixed = GmsParams(stiffness_Nm_per_m=(1.0,), weights=(1.0,), coulomb_Nm=1.0)
    else:
        fc0, k0, w0 = (
            initial.coulomb_Nm,
            list(initial.stiffness_Nm_per_m),
            list(initial.weights),
        )
        fixed = initial
    fs_ratio = (fixed.static_Nm or fixed.coulomb_Nm) / fixed.coulomb_Nm

    def params_of(x: FloatArray) -> GmsParams:
        k = np.exp(x[:elements])
        logits = np.concatenate((x[elements : 2 * elements - 1], [0.0]))
        e = np.exp(logits - logits.max())
        w = e / e.sum()
        fc = float(np.exp(x[-1]))
        return GmsParams(
            stiffness_Nm_per_m=tuple(k.tolist()),
            weights=tuple(w.tolist()),
            coulomb_Nm=fc,
            static_Nm=fs_ratio * fc,
            stribeck_velocity_m_s=fixed.stribeck_velocity_m_s,
            stribeck_exponent=fixed.stribeck_exponent,
            attraction_per_s=fixed.attraction_per_s,
            viscous_Nms_per_m=fixed.viscous_Nms_per_m,
        )

    log_w0 = np.log(np.asarray(w0))
    x0 = np.concatenate((np.log(k0), log_w0[:-1] - log_w0[-1], [math.log(fc0)]))
    # Bounds keep every trial model valid (finite stiffness, weights > 0 after rounding).
    spread = np.concatenate((np.full(elements, 25.0), np.full(elements - 1, 30.0), [5.0]))
    lower = x0 - spread
    upper = x0 + spread
    lower[elements : 2 * elements - 1] = -30.0
    upper[elements : 2 * elements - 1] = 30.0
    x0 = np.clip(x0, lower + 1e-9, upper - 1e-9)
    p_sub, v_sub, t_sub = pos[kept], vel[kept], tq[kept][counted]
    period_sub = period * stride

    def residual(x: FloatArray) -> FloatArray:
        model = simulate_gms(params_of(x), p_sub, v_sub, period_s=period_sub)
        return np.asarray(model[counted] - t_sub, dtype=float)

    solution = least_squares(
        residual, x0, bounds=(lower, upper), method="trf", x_scale="jac", max_nfev=200 * n_free
    )
    best = params_of(np.asarray(solution.x, dtype=float))
    order = sorted(range(elements), key=lambda i: best.breakaway_m[i])
    best = GmsParams(
        stiffness_Nm_per_m=tuple(best.stiffness_Nm_per_m[i] for i in order),
        weights=tuple(best.weights[i] for i in order),
        coulomb_Nm=best.coulomb_Nm,
        static_Nm=best.static_Nm,
        stribeck_velocity_m_s=best.stribeck_velocity_m_s,
        stribeck_exponent=best.stribeck_exponent,
        attraction_per_s=best.attraction_per_s,
        viscous_Nms_per_m=best.viscous_Nms_per_m,
    )
    model = simulate_gms(best, pos, vel, period_s=period)
    rms = float(np.sqrt(np.mean((tq[first:] - model[first:]) ** 2)))
    return GmsFit(params=best, rms_residual_Nm=rms, model_torque_Nm=model)
