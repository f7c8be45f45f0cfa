"""Inverse-model disturbance observer on the motor angle (paper 004 Sect. II, Fig. 5), and what enters outside it."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive
from servo_axis.core.feedback.discrete import DiscreteFilter, tustin
from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock


class DisturbanceObserver:
    """Inverse-model disturbance observer on the motor angle with a first-order LPF.

    ``d_hat = Q(s) [ (J s + D) / K_T * w - u_prev ]`` with
    ``Q(s) = w_q / (s + w_q)``, where ``w[k] = (theta[k] - theta[k-1]) / T``
    (the angle is differenced once because ``P_n^-1`` is improper by two and
    ``Q`` is first order) and ``u_prev = u[k-1]`` is the total current of
    the previous sample. Each part is Tustin-discretised. ``d_hat`` is the
    input disturbance in current units with ``y = P_n (u + d)``; the caller
    applies ``u = u_ref - d_hat``.

    Parameters
    ----------
    inertia_kgm2, damping_Nms_per_rad, torque_constant_Nm_per_A : float
        Nominal model.
    cutoff_hz : float
        LPF cut-off ``w_q / 2 pi``, Hz, > 0 (80 Hz in paper 004).
    period_s : float
        Control period, s, > 0.
    """

    def __init__(
        self,
        *,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
        cutoff_hz: float,
        period_s: float,
    ) -> None:
        j = require_positive("inertia_kgm2", inertia_kgm2)
        d = require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad)
        kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        wq = 2.0 * math.pi * require_positive("cutoff_hz", cutoff_hz)
        self.period_s = require_positive("period_s", period_s)
        check_cutoff(cutoff_hz=cutoff_hz, period_s=period_s)
        self._inverse = tustin(np.array([wq * j / kt, wq * d / kt]), np.array([1.0, wq]), period_s)
        self._lpf = observer_lowpass(cutoff_hz, period_s)
        self._last_angle: float | None = None

    def reset(self) -> None:
        """Zero the observer state."""
        self._inverse.reset()
        self._lpf.reset()
        self._last_angle = None

    def update(self, angle_rad: float, previous_current_A: float) -> float:
        """Disturbance estimate (A) after this sample's angle (rad)."""
        last = angle_rad if self._last_angle is None else self._last_angle
        self._last_angle = angle_rad
        velocity = (angle_rad - last) / self.period_s
        return self._inverse.update(velocity) - self._lpf.update(previous_current_A)


def check_cutoff(*, cutoff_hz: float, period_s: float) -> None:
    """The observer's cut-off (Hz) below the Nyquist frequency of its period ``period_s`` (s > 0).

    Raises
    ------
    ConfigError
        Naming ``cutoff_hz`` when it is at or above ``0.5 / period_s``.
    """
    if cutoff_hz >= 0.5 / period_s:
        raise ConfigError(f"cutoff_hz: expected below the Nyquist frequency, got {cutoff_hz!r}")


def observer_lowpass(cutoff_hz: float, period_s: float) -> DiscreteFilter:
    """The observer's ``Q(s) = w_q / (s + w_q)``, Tustin-discretised: one definition."""
    wq = 2.0 * math.pi * require_positive("cutoff_hz", cutoff_hz)
    return tustin(np.array([wq]), np.array([1.0, wq]), require_positive("period_s", period_s))


class ObserverBypass:
    """What a current added outside the observer's view must be when the loop adds it inside.

    Paper 004 Fig. 5 adds the friction compensation ``F_c`` after the point
    where the DOB reads the current: the DOB then sees ``F_c`` as part of the
    disturbance and leaves it alone above its bandwidth. The loop's DOB reads
    the whole current ``u[k-1]`` (which must include the PTC feedforward, the
    nominal input); a current ``c`` added there would be cancelled twice below
    the cut-off. Adding instead ``c'[k] = c[k] - Q(c)[k-1]`` (``Q`` the DOB's
    own discrete low-pass, fed one sample late as the DOB feeds ``u``) gives
    the same current command sample for sample as adding ``c`` outside the
    DOB: the DOB's estimate differs by exactly ``Q(c)[k-1]``, which ``c'``
    returns (linearity of ``Q``).

    Parameters
    ----------
    cutoff_hz, period_s : float
        The DOB's cut-off (Hz, > 0) and control period (s, > 0).
    """

    def __init__(self, *, cutoff_hz: float, period_s: float) -> None:
        check_cutoff(cutoff_hz=cutoff_hz, period_s=require_positive("period_s", period_s))
        self._lpf = observer_lowpass(cutoff_hz, period_s)
        self._filtered_previous = 0.0

    def reset(self) -> None:
        """Zero the filter state."""
        self._lpf.reset()
        self._filtered_previous = 0.0

    def update(self, current_A: float) -> float:
        """``c'[k]`` for ``c[k] = current_A`` (A); call once per sample, in order."""
        out = current_A - self._filtered_previous
        self._filtered_previous = self._lpf.update(current_A)
        return out

    def update_many(self, currents_A: list[float]) -> list[float]:
        """:meth:`update` of each of ``currents_A`` in turn (A), the list of results.

        The low-pass is first order (:func:`observer_lowpass`), so its update
        (``DiscreteFilter.update`` of order 1) is written out here, the same
        operations in the same order on its own state: a feedforward block
        (hundreds of samples) in one call. The same floats as :meth:`update`
        (``test_observer_bypass`` compares them).
        """
        lpf = self._lpf
        if lpf.order != 1:  # pragma: no cover - observer_lowpass is first order
            return [self.update(c) for c in currents_A]
        (b0, b1), (_, a1) = lpf.b, lpf.a
        z = lpf._z
        z0 = z[0]
        previous = self._filtered_previous
        out = []
        for c in currents_A:
            out.append(c - previous)
            previous = b0 * c + z0
            z0 = b1 * c - a1 * previous + 0.0
        z[0] = z0
        self._filtered_previous = previous
        return out


class OutsideObserver:
    """The sum of some terms, added outside the disturbance observer (paper 004 Fig. 5).

    With the DOB on, friction compensation enters the plant after the point
    where the DOB reads the current; the feedback loop adds every
    feedforward current inside it, so the sum goes through
    :class:`ObserverBypass` of the DOB's own
    low-pass, which makes the two the same current command.

    Parameters
    ----------
    terms : list of FeedforwardTerm
        The terms, summed.
    cutoff_hz, period_s : float
        The feedback's DOB cut-off (Hz) and the control period (s).
    """

    def __init__(self, terms: list[FeedforwardTerm], *, cutoff_hz: float, period_s: float) -> None:
        self._terms = list(terms)
        self._bypass = ObserverBypass(cutoff_hz=cutoff_hz, period_s=period_s)

    def currents(self, block: ReferenceBlock) -> NDArray[np.float64]:
        total = np.zeros(len(block.step))
        for term in self._terms:
            total += term.currents(block)
        return np.array(self._bypass.update_many(total.tolist()), dtype=float)

    def set_parameters(self, **kwargs: float) -> None:
        """Pass online estimates on to the terms that take them."""
        self._each("set_parameters", **kwargs)

    def forget_before(self, step: int) -> None:
        """Pass on to the terms that keep estimates by step."""
        self._each("forget_before", step)

    def _each(self, method: str, *args: object, **kwargs: float) -> None:
        for term in self._terms:
            call = getattr(term, method, None)
            if call is not None:
                call(*args, **kwargs)
