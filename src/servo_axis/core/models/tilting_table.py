"""Tilting table of a five-axis machine tool: unbalance torque and Coulomb friction.

The plant of paper 003 eq. (2)::

    J th'' + D th' + U sin(th) + C sgn(th') = T_m,    T_m = K_T i

with the values of its Table I ("System Plant": ``J = 50e-4 kg m^2``,
``D = 130e-4 N m s/rad``, ``U = 0.3 N m``, ``C = 0.02 N m``) and its sampling
period ``T_u = T_y = 0.4 ms``. The paper's input is the torque ``T_m``; on the
wire the plant, like every plant here, takes a current ``i`` (A), and the motor
torque is ``K_T i`` (``K_T = 1 N m/A`` by default, so the current in A reads as
the torque in N m). There is no dead time and no resonance: eq. (2) is the whole
model. ``th`` is the table (= motor) angle; there is no lead and no table
translation.

Integration (stick/slip switching, no smoothing of ``sgn``)
------------------------------------------------------------
The current, clipped at ``+-current_limit_A``, is held over the control period,
which is split into ``control_period_s / sim_step_s`` sub-steps of ``h``.

* At rest (``th' == 0.0`` exactly) the table sticks while the net torque
  ``|T_m - U sin th| <= C``: the angle is held bit for bit, the velocity stays
  exactly 0 and the static friction torque is ``T_m - U sin th``. ``T_m`` is
  constant over a period and ``th`` is frozen, so a table that sticks at any
  point of a period sticks to its end. Otherwise it breaks away in the
  direction ``s = sgn(T_m - U sin th)``.
* While sliding with direction ``s`` the friction is the constant ``C s`` and
  eq. (2) is smooth; it is stepped with the classical fixed-step RK4. If a
  step ends with a velocity of the other sign (or exactly 0), the velocity
  crossed zero inside it: the crossing time is found by a bracketed Newton
  iteration on the RK4 step length (started from linear interpolation of the
  velocity, bisection whenever Newton leaves the bracket; the derivative is
  the acceleration of eq. (2) at the trial end point), stopped when the
  correction is below ``1e-10 h``. The state is moved to that instant, the
  velocity is set to exactly 0 and the stick test above decides between
  sticking and sliding back for the rest of the sub-step. There is hence no
  chattering: a stopped table has ``th' == 0.0`` exactly and cannot creep.

Both loops are compiled, the same arithmetic
(:func:`~servo_axis.core.models.tilting_table_kernels.tilting_friction_period`,
:func:`~servo_axis.core.models.tilting_table_kernels.tilting_smooth_period`).

Error: between events the RK4 local error is ``O((w h)^5)`` with ``w`` the
largest rate of the motion (``sqrt(U/J) = 7.7 rad/s`` and ``D/J = 2.6 1/s``
for Table I, plus ``|th'|`` through ``sin th``): about ``3e-18`` relative per
sub-step at ``h = 40 us``, i.e. rounding dominates. Newton converges
quadratically, so the event time is located to well below the ``1e-10 h``
(4 fs) stopping threshold, in practice to the rounding of the velocity
(``~1e-16 |th'| / |th''|``). Linear interpolation of the crossing alone would
be off by up to ``h^2 |th'''| / (8 |th''|)`` (about 0.5 ns for Table I with a
crossing mid-sub-step), which after a reversal leaves a velocity error of that
times the new acceleration. Against scipy's DOP853 restarted at each ``v = 0``
event, Table I swings with reversals and a final stick agree to ~1e-11 rad/s
and ~1e-12 rad (~1e-8 rad/s with linear interpolation alone; see
test/unit/core/test_tilting_table.py). The one approximation: a table that
breaks away from rest with a net torque above ``C`` by so little that RK4
cannot resolve the motion over a sub-step (its velocity comes out with the
wrong sign) is held at rest for that sub-step, an error at the rounding level
of the angle.

Sensors: the encoder reads the angle plus uniform noise in
``[-noise_rad, +noise_rad)`` drawn from the seeded generator (one draw per
control sample, at :meth:`TiltingTablePlant.reset` and each
:meth:`TiltingTablePlant.step`, none when ``noise_rad == 0``; the draws are
taken from the generator :data:`NOISE_DRAWS` at a time, ahead of the samples:
the same numbers in the same order), then quantised to
``encoder_resolution_rad`` (nearest count) if that is > 0. There is no linear
scale: ``scale_m`` is 0.0, as are ``position_m`` and ``velocity_m_s``.
``friction_force_N`` carries the friction TORQUE in N m (the ``C sgn(th')``
term of eq. (2), or the static torque while stuck), since there is no lead to
turn it into a force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from servo_axis.core.errors import (
    ConfigError,
    require_finite,
    require_nonnegative,
    require_positive,
)
from servo_axis.core.models.base import (
    NominalModel,
    PlantOutput,
    clipped_current,
    plant_output,
    sim_steps,
    whole_ratio,
)

#: Encoder noise draws taken from the generator at a time (``Generator.random(n)``).
NOISE_DRAWS = 256

#: Newton iterations of the zero-velocity event location, at most.
_EVENT_ITERATIONS = 40
#: Relative (to the sub-step) size of the last Newton correction that ends the search.
_EVENT_TOLERANCE = 1e-10
#: Stick/slip events handled within one sub-step, at most.
_EVENTS_PER_SUBSTEP = 8


@dataclass(frozen=True, kw_only=True)
class TiltingTableParams:
    """Parameters of the tilting table, paper 003 eq. (2) (defaults: its Table I plant).

    Parameters
    ----------
    inertia_kgm2 : float
        ``J``, kg m^2, > 0 (50e-4).
    damping_Nms_per_rad : float
        ``D``, N m s/rad, >= 0 (130e-4).
    unbalance_Nm : float
        ``U = F R``, the largest unbalance torque, N m, >= 0 (0.3).
    coulomb_Nm : float
        ``C``, the Coulomb friction torque, N m, >= 0 (0.02).
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A, > 0 (1.0): the plant takes a current ``i`` (A) and the
        motor torque is ``T_m = K_T i``.
    control_period_s : float
        ``T_u = T_y``, s, > 0 (0.4e-3, Sec. V-A): the current is held over it.
    sim_step_s : float
        RK4 sub-step ``h``, s, > 0, dividing ``control_period_s`` (40e-6: ten
        sub-steps; RK4 error far below rounding for Table I, see the module).
    current_limit_A : float
        Amplifier saturation, A, > 0 (15.27: with ``K_T = 1`` the 15.27 N m
        peak torque of the test bench motor of Sec. V-A; our choice, the
        paper's simulation states no limit).
    initial_angle_rad, initial_velocity_rad_s : float
        State at step 0 (0, 0).
    noise_rad : float
        Half-width of the uniform encoder noise, rad, >= 0 (1e-5, Sec. IV-A:
        "measurement noise within +-1e-5 rad").
    encoder_resolution_rad : float
        Encoder count, rad, >= 0; 0 is an ideal encoder (0). Applied after
        the noise.
    """

    inertia_kgm2: float = 50e-4
    damping_Nms_per_rad: float = 130e-4
    unbalance_Nm: float = 0.3
    coulomb_Nm: float = 0.02
    torque_constant_Nm_per_A: float = 1.0
    control_period_s: float = 0.4e-3
    sim_step_s: float = 40e-6
    current_limit_A: float = 15.27
    initial_angle_rad: float = 0.0
    initial_velocity_rad_s: float = 0.0
    noise_rad: float = 1e-5
    encoder_resolution_rad: float = 0.0

    def __post_init__(self) -> None:
        require_positive("inertia_kgm2", self.inertia_kgm2)
        require_nonnegative("damping_Nms_per_rad", self.damping_Nms_per_rad)
        require_nonnegative("unbalance_Nm", self.unbalance_Nm)
        require_nonnegative("coulomb_Nm", self.coulomb_Nm)
        require_positive("torque_constant_Nm_per_A", self.torque_constant_Nm_per_A)
        sim_steps(self.control_period_s, self.sim_step_s)
        require_positive("current_limit_A", self.current_limit_A)
        require_finite("initial_angle_rad", self.initial_angle_rad)
        require_finite("initial_velocity_rad_s", self.initial_velocity_rad_s)
        require_nonnegative("noise_rad", self.noise_rad)
        require_nonnegative("encoder_resolution_rad", self.encoder_resolution_rad)

    @property
    def substeps(self) -> int:
        """RK4 sub-steps per control period."""
        return whole_ratio("control_period_s", self.control_period_s, self.sim_step_s, "sim_step_s")


def nominal(params: TiltingTableParams) -> NominalModel:
    """The linear part of eq. (2), ``K_T / (J s^2 + D s)``, for the controllers."""
    return NominalModel(
        inertia_kgm2=params.inertia_kgm2,
        damping_Nms_per_rad=params.damping_Nms_per_rad,
        torque_constant_Nm_per_A=params.torque_constant_Nm_per_A,
    )


class TiltingTablePlant:
    """Simulator of the tilting table, advanced one control period per call.

    Satisfies :class:`servo_axis.core.models.base.Plant`; see the module
    docstring for the integration, its error and the output conventions.
    Same parameters and same generator seed give the same outputs bit for bit.

    Parameters
    ----------
    params : TiltingTableParams
        Physical parameters.
    rng : numpy.random.Generator
        Source of the encoder noise (not drawn from when ``noise_rad == 0``;
        else :data:`NOISE_DRAWS` doubles at a time, so a generator shared with
        anything else is ahead of what the plant has used).
    """

    def __init__(self, params: TiltingTableParams, *, rng: np.random.Generator) -> None:
        if not isinstance(rng, np.random.Generator):
            raise ConfigError(f"rng: expected a numpy.random.Generator, got {rng!r}")
        self.params = params
        self._rng = rng
        self._n = params.substeps
        self._h = params.sim_step_s
        self._d = params.damping_Nms_per_rad / params.inertia_kgm2
        self._u = params.unbalance_Nm / params.inertia_kgm2
        # The sub-step loops (RK4, the zero-velocity events), compiled.
        from servo_axis.core.models.tilting_table_kernels import (
            tilting_friction_period,
            tilting_smooth_period,
        )

        self._kernel = tilting_friction_period if params.coulomb_Nm > 0.0 else tilting_smooth_period
        self._config = np.array(
            [
                self._n,
                self._h,
                params.coulomb_Nm,
                1.0 / params.inertia_kgm2,
                params.unbalance_Nm,
                self._d,
                self._u,
                _EVENT_TOLERANCE * self._h,
                _EVENT_ITERATIONS,
                _EVENTS_PER_SUBSTEP,
            ]
        )
        # Encoder noise uniform in [-noise, noise): numpy's Generator.uniform is
        # low + (high - low) * random(), one double per draw; done here with
        # random() that way (the same numbers, a third of the cost).
        self._noise_low = -params.noise_rad
        self._noise_span = params.noise_rad - -params.noise_rad
        # Generator.random() draws one double per call (0.3-0.4 us); random(n)
        # draws the same doubles of the stream in the same order, n at a time.
        self._draws: list[float] = []
        # The parameters the per-sample path reads, once (params is frozen).
        self._limit = params.current_limit_A
        self._kt = params.torque_constant_Nm_per_A
        self._inertia = params.inertia_kgm2
        self._coulomb = params.coulomb_Nm
        self._unbalance = params.unbalance_Nm
        self._noise = params.noise_rad
        self._resolution = params.encoder_resolution_rad
        self.reset()

    def reset(self) -> None:
        """Return to the initial state at step 0 (the generator is not reseeded)."""
        p = self.params
        self._step = 0
        self._th = float(p.initial_angle_rad)
        self._v = float(p.initial_velocity_rad_s)
        self._applied_A = 0.0
        self._torque_Nm = 0.0
        self._update_sample()

    @property
    def step_index(self) -> int:
        """Index of the current control sample."""
        return self._step

    def output(self) -> PlantOutput:
        """Readings and true state at the current control sample."""
        # plant_output: PlantOutput(...) without the frozen dataclass's __init__.
        return plant_output(
            self._step,
            self._encoder_rad,
            0.0,
            self._th,
            self._v,
            0.0,
            0.0,
            self._torque_Nm,
            self._friction_Nm,
        )

    def step(self, current_A: float) -> PlantOutput:
        """Hold ``current_A`` over one control period and advance to the next sample.

        Parameters
        ----------
        current_A : float
            Current for this period, A; clipped at ``+-current_limit_A``.

        Returns
        -------
        PlantOutput
            The state at the next control sample.
        """
        limit = self._limit
        # Inside the limits the saturation is the current itself (what clipped_current
        # gives it, without the call); outside them, or not finite, clipped_current.
        cmd = (
            float(current_A) if -limit <= current_A <= limit else clipped_current(current_A, limit)
        )
        torque = self._kt * cmd
        self._applied_A = cmd
        self._torque_Nm = torque
        if self._coulomb > 0.0:
            self._th, self._v = self._kernel(self._th, self._v, torque, self._config)
        else:
            # C = 0: eq. (2) is smooth; plain RK4 (a table at rest with zero net
            # torque is an exact equilibrium of the RK4 map too).
            b = torque / self._inertia
            self._th, self._v = self._kernel(self._th, self._v, b, self._config)
        self._step += 1
        self._update_sample()
        # output(), without the call.
        return plant_output(
            self._step,
            self._encoder_rad,
            0.0,
            self._th,
            self._v,
            0.0,
            0.0,
            self._torque_Nm,
            self._friction_Nm,
        )

    def _update_sample(self) -> None:
        # Friction torque at the sample (eq. (2) sign: it opposes the motion)
        # and the encoder reading, both fixed once per sample.
        c = self._coulomb
        if self._v != 0.0:
            self._friction_Nm = math.copysign(c, self._v) if c > 0.0 else 0.0
        else:
            net = self._torque_Nm - self._unbalance * math.sin(self._th)
            self._friction_Nm = min(max(net, -c), c)
        value = self._th
        if self._noise > 0.0:
            draws = self._draws
            if not draws:
                draws.extend(reversed(self._rng.random(NOISE_DRAWS).tolist()))
            value += self._noise_low + self._noise_span * draws.pop()
        res = self._resolution
        if res > 0.0:
            value = math.floor(value / res + 0.5) * res
        self._encoder_rad = value
