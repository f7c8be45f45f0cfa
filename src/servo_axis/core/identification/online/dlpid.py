"""Double-layer parameter identification, DLPID (paper 003, Sect. III-B, Figs. 3-4).

Model, eq. (2): ``J th'' + D th' + U sin th + C sgn th' = T_m``.

Signal chain (every control sample ``T_y``)
-------------------------------------------
The measured angle ``y_m`` goes through one 2nd-order filter family with a
double pole at ``w_c = 2 pi pd_cutoff_hz``::

    G_LPF(s) = w_c^2 / (s + w_c)^2         -> y    (filtered angle)
    G_PD1(s) = w_c^2 s / (s + w_c)^2       -> y'   (pseudo-differentiated)
    G_PD2(s) = w_c^2 s^2 / (s + w_c)^2     -> y''

i.e. the classical first-order pseudo-differentiator ``w_c s / (s + w_c)``
cascaded twice, all Tustin-discretised at ``T_y``
(:func:`servo_axis.core.feedback.discrete.tustin`). Second order is the least
that keeps ``s^2 G_LPF`` proper (``y''`` needs it); the double real pole has
no overshoot, so ``y'`` does not ring through zero at a reversal (which
``sgn y'`` would see). The applied torque ``u`` goes through the *same*
``G_LPF``: ``ubar = G_LPF u``. Then ``y'' = s^2 G_LPF y_m``, ``y' = s G_LPF y_m``
and ``ubar`` carry the same delay (about ``2 / w_c`` at low frequency), and
eq. (2) filtered by ``G_LPF`` reads ``ubar = J y'' + D y' + ...`` exactly for
the linear terms. Filtering only the angle would leave ``u`` ahead of the
regressor by ``2 / w_c`` and bias the estimates. (The nonlinear terms are
taken on the filtered signals, ``sin y`` and ``sgn y'``, as in Fig. 3/eq. (8);
``sin(G y_m)`` differs from ``G sin(y_m)`` only to second order in
``omega_motion / w_c``.)

Sampling convention
-------------------
``update(step, ...)`` is called with consecutive integer steps; the RLS
period is ``ratio = T_RLS / T_y`` samples and the layers run at the steps
with ``step % ratio == ratio - 1``, on the filtered signals of that step
(the last sample of the RLS period): ``Estimate.step`` is that step. The
filters are started at rest on the first sample (its angle and torque held
since forever), and for the first :attr:`DlpidParams.warmup_samples` samples
(12 / w_c, the filters' transient ``(1 + w_c t) e^{-w_c t}`` below 1e-4) the
layers are not run (an ``Estimate`` with nothing updated is still returned
at RLS steps).

Lower layer, eqs. (4)-(5) and (16), at each RLS step ``k``
-----------------------------------------------------------
``phi = [y'', y', sin y]``, ``u_lower = ubar - u_f`` with
``u_f = C_hat[k-1] sgn(y')``; conditional RLS
(:class:`~servo_axis.core.identification.online.rls.ConditionalRls`) with the
conditions of eq. (16) evaluated on the *filtered* signals: ``U`` when
``y > angle_min_rad``, ``D`` when ``|y'| > velocity_min_rad_s``, ``J`` when
``|y''| > acceleration_min_rad_s2``. The PE index of eq. (7)
(:class:`~servo_axis.core.identification.online.pe.PeIndex`) is fed every RLS step
with ``phi``; it is reported (``Estimate.kappa``), not used as a gate: the
per-parameter conditions (16) are the paper's PE conditions, ``kappa`` its
diagnostic (003 Fig. 6).

Upper layer, eq. (8)
--------------------
``u_RLS = J_hat[k-1] y'' + D_hat[k-1] y' + U_hat[k-1] sin y`` (the estimates
before this step's lower-layer update) and
``C_hat[k] = G_LPF[z, q] ((ubar - u_RLS) / sgn y')`` with a first-order
low-pass of ``q = friction_cutoff_hz`` running at ``T_RLS``, discretised with
the matched pole ``a = exp(-2 pi q T_RLS)``: ``C[k] = a C[k-1] + (1 - a) x``
(monotone step response, so inside the bounds for inputs inside the bounds,
and usable at ``q = 100 Hz`` with ``T_RLS = 4 ms`` where Tustin would ring).
The input ``x`` is clipped to ``friction_bounds`` and so is ``C_hat``. When
``|y'| <= friction_velocity_min_rad_s`` the quotient is not formed and
``C_hat`` is held (the sign of a filtered velocity near a reversal is not
that of the friction in ``ubar``). ``C_hat[0] = initial_friction_Nm``.

Coupling of the layers: if the lower layer fits ``ubar - C_hat sgn y'`` well,
the upper layer's input is ``C_hat`` itself, so ``C`` is only identified
through the part of ``sgn y'`` outside the span of ``[y'', y', sin y]``.
On a sinusoidal tilt ``sgn y'`` is mostly collinear with ``y'``: ``C_hat`` and
``D_hat`` then trade against each other and converge slowly (with Table I's
settings and exact data, tens of seconds; the lower layer alone, ``C = 0``,
takes a few seconds).

``mode = "single_layer"`` is the previous MARC (003 [11]): only the lower
layer, ``u_f = 0``, ``C`` neither modelled nor estimated (reported as 0).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from servo_axis.core.errors import (
    ConfigError,
    SignalError,
    require_nonnegative,
    require_positive,
)
from servo_axis.core.feedback.discrete import DiscreteFilter, tustin
from servo_axis.core.identification.online.pe import PeIndex
from servo_axis.core.identification.online.rls import ConditionalRls, RlsParams

MODES = ("double_layer", "single_layer")


@dataclass(frozen=True, kw_only=True)
class DlpidParams:
    """Parameters of :class:`Dlpid` (003 Sect. III-B, IV-A, V-A; Table I).

    Parameters
    ----------
    rls : RlsParams
        RLS of ``[J, D, U]`` (3 parameters, in that order): kg m^2,
        N m s/rad, N m. Table I: initial ``20e-4, 100e-4, 0.1``, forgetting
        ``0.999, 0.999, 0.995``.
    period_s : float
        ``T_y``, control (encoder) period, s, > 0 (003: 4e-4).
    rls_period_s : float
        ``T_RLS``, s, a whole multiple of ``period_s`` (003: 4e-3).
    pd_cutoff_hz : float
        Double-pole frequency of ``G_LPF`` / ``G_PD``, Hz, below the Nyquist
        frequency of ``T_y`` (the paper does not give it).
    friction_cutoff_hz : float
        ``q`` of eq. (8), Hz, below the Nyquist frequency of ``T_RLS``
        (003: 2 or 100 Hz in simulation, 1 Hz in the experiment).
    initial_friction_Nm : float
        ``C_hat[0]``, N m (Table I: 0.01), inside ``friction_bounds``.
    friction_bounds : (float, float)
        ``(C_min, C_max)``, N m, ``C_min < C_max``.
    angle_min_rad, velocity_min_rad_s, acceleration_min_rad_s2 : float
        Conditions of eq. (16), >= 0: ``U`` is updated when ``y > 0.1``,
        ``D`` when ``|y'| > 0.2``, ``J`` when ``|y''| > 0.5``.
    friction_velocity_min_rad_s : float
        ``C_hat`` is held when ``|y'|`` is at or below this, rad/s, > 0
        (default that of ``D``: the friction is identified in the same
        regime as the damping).
    pe_window : int
        ``W`` of eq. (7), RLS samples, >= 3 (003: 100).
    mode : {"double_layer", "single_layer"}
        Proposed DLPID, or the previous single-layer MARC (no friction).
    """

    rls: RlsParams
    period_s: float = 4e-4
    rls_period_s: float = 4e-3
    pd_cutoff_hz: float = 20.0
    friction_cutoff_hz: float = 2.0
    initial_friction_Nm: float = 0.01
    friction_bounds: tuple[float, float] = (0.0, 1.0)
    angle_min_rad: float = 0.1
    velocity_min_rad_s: float = 0.2
    acceleration_min_rad_s2: float = 0.5
    friction_velocity_min_rad_s: float = 0.2
    pe_window: int = 100
    mode: Literal["double_layer", "single_layer"] = "double_layer"

    def __post_init__(self) -> None:
        if not isinstance(self.rls, RlsParams) or self.rls.n != 3:
            raise ConfigError("rls: expected RlsParams of 3 parameters [J, D, U]")
        ty = require_positive("period_s", self.period_s)
        trls = require_positive("rls_period_s", self.rls_period_s)
        ratio = round(trls / ty)
        if ratio < 1 or abs(ratio * ty - trls) > 1e-9 * trls:
            raise ConfigError(
                f"rls_period_s: expected a whole multiple of period_s = {ty!r}, got {trls!r}"
            )
        fpd = require_positive("pd_cutoff_hz", self.pd_cutoff_hz)
        if fpd >= 0.5 / ty:
            raise ConfigError(
                f"pd_cutoff_hz: expected a value below the Nyquist frequency {0.5 / ty!r} Hz, "
                f"got {fpd!r}"
            )
        q = require_positive("friction_cutoff_hz", self.friction_cutoff_hz)
        if q >= 0.5 / trls:
            raise ConfigError(
                f"friction_cutoff_hz: expected a value below the Nyquist frequency of "
                f"rls_period_s, {0.5 / trls!r} Hz, got {q!r}"
            )
        try:
            lo, hi = (float(v) for v in self.friction_bounds)
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                f"friction_bounds: expected (min, max), got {self.friction_bounds!r}"
            ) from exc
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(
                f"friction_bounds: expected finite min < max, got {self.friction_bounds!r}"
            )
        c0 = float(self.initial_friction_Nm)
        if not lo <= c0 <= hi:
            raise ConfigError(
                f"initial_friction_Nm: expected a value inside friction_bounds [{lo!r}, {hi!r}], "
                f"got {self.initial_friction_Nm!r}"
            )
        for key in ("angle_min_rad", "velocity_min_rad_s", "acceleration_min_rad_s2"):
            require_nonnegative(key, getattr(self, key))
        require_positive("friction_velocity_min_rad_s", self.friction_velocity_min_rad_s)
        w = self.pe_window
        if isinstance(w, bool) or not isinstance(w, int) or w < 3:
            raise ConfigError(f"pe_window: expected an integer >= 3 (n), got {w!r}")
        if self.mode not in MODES:
            raise ConfigError(f"mode: expected one of {MODES}, got {self.mode!r}")
        object.__setattr__(self, "friction_bounds", (lo, hi))

    @property
    def ratio(self) -> int:
        """``T_RLS / T_y``, control samples per RLS period."""
        return round(self.rls_period_s / self.period_s)

    @property
    def warmup_samples(self) -> int:
        """Control samples before the layers run: ``ceil(12 / (w_c T_y))``."""
        return math.ceil(12.0 / (2.0 * math.pi * self.pd_cutoff_hz * self.period_s))


@dataclass(frozen=True)
class Estimate:
    """Output of one RLS step of :class:`Dlpid`.

    Attributes
    ----------
    step : int
        The last control sample used (the step the layers ran at).
    J, D, U, C : float
        ``J_hat`` (kg m^2), ``D_hat`` (N m s/rad), ``U_hat`` (N m),
        ``C_hat`` (N m; 0.0 in single-layer mode) after this step.
    kappa : float
        PE index of eq. (7) (0.0 until ``W`` RLS steps are in).
    updated : tuple of 4 bool
        Whether ``J, D, U`` (eq. (16)) and ``C`` (eq. (8)) were updated.
    """

    step: int
    J: float
    D: float
    U: float
    C: float
    kappa: float
    updated: tuple[bool, bool, bool, bool] = field(default=(False, False, False, False))


class Dlpid:
    """Double-layer parameter identification of 003 Fig. 4 with the filters of Fig. 3.

    Parameters
    ----------
    params : DlpidParams
        Periods, filters, RLS, friction layer, conditions, PE window, mode.
    """

    def __init__(self, params: DlpidParams) -> None:
        self.params = params
        self.rls = ConditionalRls(params.rls)
        self.pe = PeIndex(3, params.pe_window)
        wc = 2.0 * math.pi * params.pd_cutoff_hz
        den = np.array([1.0, 2.0 * wc, wc * wc])
        ty = params.period_s
        self._f_angle = tustin(np.array([wc * wc]), den, ty)
        self._f_vel = tustin(np.array([wc * wc, 0.0]), den, ty)
        self._f_acc = tustin(np.array([wc * wc, 0.0, 0.0]), den, ty)
        self._f_torque = tustin(np.array([wc * wc]), den, ty)
        self._pole_c = math.exp(-2.0 * math.pi * params.friction_cutoff_hz * params.rls_period_s)
        # The four filters run as one compiled call on these arrays (the same
        # arithmetic as DiscreteFilter.update); the filter objects hold the
        # coefficients and settle the state on the first sample.
        from servo_axis.core.identification.online.dlpid_kernels import second_order_bank

        self._bank = second_order_bank
        self._coef = np.array([[*f.b, *f.a[1:]] for f in self._filters])
        self._z = np.zeros((4, 2))
        self._ratio = params.ratio
        self._warmup = params.warmup_samples
        self.reset()

    @property
    def _filters(self) -> tuple[DiscreteFilter, ...]:
        return (self._f_angle, self._f_vel, self._f_acc, self._f_torque)

    def reset(self) -> None:
        """Back to the initial estimates, filters to be started on the next sample."""
        self.rls.reset()
        self.pe.reset()
        for f in self._filters:
            f.reset()
        self._z[:] = 0.0
        self._c_hat = self._c_initial()
        self._last_step: int | None = None
        self._samples = 0
        self._signals = (0.0, 0.0, 0.0, 0.0)  # y, y', y'', ubar of the last sample

    def _c_initial(self) -> float:
        return float(self.params.initial_friction_Nm) if self._double else 0.0

    @property
    def _double(self) -> bool:
        return self.params.mode == "double_layer"

    @property
    def ratio(self) -> int:
        """Control samples per RLS period (``T_RLS / T_y``)."""
        return self.params.ratio

    @property
    def last_step(self) -> int | None:
        """The last control sample taken (None before the first)."""
        return self._last_step

    @property
    def signals(self) -> tuple[float, float, float, float]:
        """Filtered ``(y, y', y'', ubar)`` of the last sample (rad, rad/s, rad/s^2, N m)."""
        return self._signals

    @property
    def friction(self) -> float:
        """``C_hat``, N m (0.0 in single-layer mode)."""
        return self._c_hat

    def estimate(self, step: int, updated: tuple[bool, bool, bool, bool]) -> Estimate:
        """The current estimates as an :class:`Estimate` stamped ``step``."""
        j, d, u = self.rls.theta.tolist()
        # Estimate(...) without the frozen dataclass's __init__ (one per RLS
        # step): its fields in order, an equal object (test_identification).
        out: Estimate = object.__new__(Estimate)
        out.__dict__.update(
            step=step, J=j, D=d, U=u, C=self._c_hat, kappa=self.pe.kappa, updated=updated
        )
        return out

    def update(self, step: int, angle_rad: float, torque_Nm: float) -> Estimate | None:
        """One control sample: filter, and at RLS steps run both layers.

        Parameters
        ----------
        step : int
            Control sample number, >= 0, consecutive from call to call.
        angle_rad : float
            Measured angle ``y_m[step]``, rad.
        torque_Nm : float
            Applied motor torque ``u[step] = T_m``, N m.

        Returns
        -------
        Estimate or None
            At ``step % ratio == ratio - 1`` the estimate after this step;
            None between RLS steps.
        """
        if type(step) is not int:  # the checks below, for anything but a plain int
            if isinstance(step, bool) or not isinstance(step, int | np.integer):
                raise SignalError(f"step: expected an integer >= 0, got {step!r}")
            step = int(step)
        if step < 0:
            raise SignalError(f"step: expected an integer >= 0, got {step!r}")
        if self._last_step is not None and step != self._last_step + 1:
            raise SignalError(
                f"step: expected consecutive samples, {self._last_step + 1}, got {step}"
            )
        y_m = angle_rad if type(angle_rad) is float else _finite("angle_rad", angle_rad)
        u = torque_Nm if type(torque_Nm) is float else _finite("torque_Nm", torque_Nm)
        if not (math.isfinite(y_m) and math.isfinite(u)):
            _finite("angle_rad", y_m)
            _finite("torque_Nm", u)
        if self._samples == 0:
            for i, (f, x) in enumerate(zip(self._filters, (y_m, y_m, y_m, u), strict=True)):
                f.settle(x)
                self._z[i] = f.state
        # G_LPF y_m, G_PD1 y_m, G_PD2 y_m, G_LPF u (Fig. 3), one compiled call.
        signals = self._signals = self._bank(self._coef, self._z, y_m, u)
        self._last_step = step
        self._samples += 1
        ratio = self._ratio
        if step % ratio != ratio - 1:
            return None
        if self._samples <= self._warmup:
            return self.estimate(step, (False, False, False, False))
        return self._layers(step, *signals)

    def _layers(self, step: int, y: float, yd: float, ydd: float, ubar: float) -> Estimate:
        p = self.params
        sin_y = math.sin(y)
        if not (math.isfinite(ydd) and math.isfinite(yd) and math.isfinite(sin_y)):
            raise SignalError(f"phi: expected finite values, got {[ydd, yd, sin_y]!r}")
        phi = np.array([ydd, yd, sin_y])  # eq. (4)
        sgn = 1.0 if yd > 0.0 else (-1.0 if yd < 0.0 else 0.0)  # np.sign(yd), yd finite
        u_rls = self.rls.predict_checked(phi)  # theta_hat[k-1]: eq. (8)
        u_f = self._c_hat * sgn if self._double else 0.0
        flag_j = abs(ydd) > p.acceleration_min_rad_s2
        flag_d = abs(yd) > p.velocity_min_rad_s
        flag_u = y > p.angle_min_rad
        # update_checked returns the mask it is given: the flags are these.
        self.rls.update_checked(phi, ubar - u_f, np.array([flag_j, flag_d, flag_u]))
        self.pe.update_checked(phi)
        c_updated = False
        if self._double and abs(yd) > p.friction_velocity_min_rad_s:
            lo, hi = p.friction_bounds
            x = min(max((ubar - u_rls) * sgn, lo), hi)  # / sgn = * sgn for sgn = +-1
            a = self._pole_c
            self._c_hat = min(max(a * self._c_hat + (1.0 - a) * x, lo), hi)
            c_updated = True
        return self.estimate(step, (flag_j, flag_d, flag_u, c_updated))

    def state(self) -> dict[str, Any]:
        """Everything needed to resume bit-identically (JSON-able, exact float text)."""
        return {
            "mode": self.params.mode,
            "rls": self.rls.state(),
            "pe": self.pe.state(),
            "filters": self._z.tolist(),
            "signals": list(self._signals),
            "friction_Nm": self._c_hat,
            "last_step": self._last_step,
            "samples": self._samples,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong mode, shape or value)."""
        if state.get("mode") != self.params.mode:
            raise SignalError(f"mode: expected {self.params.mode!r}, got {state.get('mode')!r}")
        filters = state.get("filters")
        sizes = [len(z) for z in self._z]
        if (
            not isinstance(filters, list)
            or [len(z) if isinstance(z, list) else -1 for z in filters] != sizes
        ):
            raise SignalError(f"filters: expected lists of {sizes} numbers")
        zs = [[_finite("filters", v) for v in z] for z in filters]
        signals = state.get("signals")
        if not isinstance(signals, list) or len(signals) != 4:
            raise SignalError("signals: expected 4 numbers")
        sig = tuple(_finite("signals", v) for v in signals)
        c = _finite("friction_Nm", state.get("friction_Nm"))
        lo, hi = self.params.friction_bounds
        if self._double and not lo <= c <= hi:
            raise SignalError(f"friction_Nm: expected a value inside [{lo!r}, {hi!r}], got {c!r}")
        if not self._double and c != 0.0:
            raise SignalError(f"friction_Nm: expected 0.0 in single_layer mode, got {c!r}")
        last, samples = state.get("last_step"), state.get("samples")
        if last is not None and (isinstance(last, bool) or not isinstance(last, int) or last < 0):
            raise SignalError(f"last_step: expected an integer >= 0 or null, got {last!r}")
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 0:
            raise SignalError(f"samples: expected an integer >= 0, got {samples!r}")
        rls_state, pe_state = state.get("rls"), state.get("pe")
        if not isinstance(rls_state, Mapping) or not isinstance(pe_state, Mapping):
            raise SignalError("rls, pe: expected mappings")
        rls = ConditionalRls(self.params.rls)
        rls.load_state(rls_state)
        pe = PeIndex(3, self.params.pe_window)
        pe.load_state(pe_state)
        self.rls, self.pe = rls, pe
        self._z = np.array(zs, dtype=float)
        self._signals = (sig[0], sig[1], sig[2], sig[3])
        self._c_hat = c
        self._last_step = last
        self._samples = samples


def _finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(value, bool) or not math.isfinite(v):
        raise SignalError(f"{name}: expected a finite number, got {value!r}")
    return v
