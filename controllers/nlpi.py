"""Feedback-linearizing 2-DOF PI for tank level (seed 002, Short & Selvakumar 2020, section 3).

Plant (seed 002 eq. (3a)): ``dh/dt = b u - a' sqrt(h)``.

Non-linear PI of Fig. 3 (:class:`NonlinearPI`, ``type: nlpi``)
---------------------------------------------------------------
The control is a 2-DOF PI (integral of the error, proportional action on the measurement only) plus
the linearizing term ``u'' = K_l sqrt(h)``::

    u = K_i I - K_p h + K_l sqrt(h),     dI/dt = r - h
    K_p = 2 zeta w_n / b                                                     (10)
    K_l = a' / b                                                             (11)
    K_i = w_n^2 / b                                                          (12)
    zeta = sqrt(L^2 / (pi^2 + L^2)),  L = ln(os/100)                         (13)
    w_n = 4.6 / (zeta t_s)                                                   (14)

Substituting into eq. (3a) (eq. (15), corrected) gives ``dh/dt = b (K_i I - K_p h)``, i.e. for
every level ``h(s)/r(s) = w_n^2 / (s^2 + 2 zeta w_n s + w_n^2)`` (eq. (23) for the simulated tank)
and a disturbance outflow ``q_d`` (level rate) gives ``h/q_d = -s / (s (s^2 + 2 zeta w_n s +
w_n^2))``: the same response at every level, as long as the pump does not saturate. Eq. (14) is the
time for the envelope ``exp(-zeta w_n t)`` to fall to 1 % (``ln 100 = 4.6``): the 1 % band.

Discrete implementation, eq. (20)-(21) **as corrected**, with the actual interval between samples
(sampling periods change at run time)::

    dt_k = t_k - t_{k-1}
    I_k  = I_{k-1} + dt_k e_k           (backward Euler, the paper's e(k); default)
    I_k  = I_{k-1} + dt_k e_{k-1}       (forward Euler, ``integration: forward``)
    I_k  = I_{k-1} + dt_k (e_k + e_{k-1}) / 2    (``integration: trapezoidal``)
    u_k  = sat(K_i I_k - K_p h_k + K_l sqrt(max(h_k, 0)))

The rule shifts the sampled loop's damping by about ``+-w_n T_s / 4`` (backward: more damped):
on the simulated tank at ``T_s = 0.05 s`` the overshoot is 4.09 % (backward), 4.58 % (forward)
and 4.33 % (trapezoidal) for the designed 4.32 %; all tend to 4.32 % as ``T_s -> 0``.

At the first sample there is no previous one: ``dt = 0`` (the law never reads a clock). With
``start: rest`` (default) the integral is then set to the value that holds the measured level at
rest, ``I_0 = K_p h_0 / K_i = 2 zeta h_0 / w_n`` (zero for an empty tank, so the paper's
experiments are unchanged; bumpless for a loop that starts at equilibrium); ``start: zero`` sets 0.
Where the plant's equilibrium is not the design model's (an inflow the law does not know of, e.g.
from an upstream tank, :mod:`plants.tank_train`), ``u_start`` gives the command the loop holds
at the start, and the integral is set so that the first command is exactly that one,
``I_0 = (u_start + K_p h_0 - K_l sqrt(h_0)) / K_i`` (bumpless from the held input; it overrides
``start``).
Anti-windup by clamping the integrator at actuator saturation (section 3.4): an update that would
push the command past a limit is cut so that the command just reaches it (and dropped if the
command is already past it), so the integral never winds up beyond what holds the limit.

Misprints in seed 002 (what is implemented instead)
---------------------------------------------------
1. Eq. (6) prints the denominator ``s^2 + (a + b) K_p s + b K_i``; the closed loop of the 2-DOF PI
   on ``b/(s + a)`` is ``s^2 + (a + b K_p) s + b K_i``, which is what eq. (7a) solves.
2. Eq. (13) prints ``ln(os/100)^2``: it must be read ``[ln(os/100)]^2`` (``ln((os/100)^2)`` is
   negative and gives no real zeta). 4.321 % gives zeta = 0.7071 as the paper states.
3. Eq. (15c) prints ``K_i sqrt(h)`` for the linearizing term: it is ``K_l sqrt(h)`` (eq. (11)).
4. Eq. (20) prints ``I(k) = I(k-1) + (r(k) - h(k)) / T_s``: Euler integration *multiplies* by the
   sample time, ``I(k) = I(k-1) + T_s (r(k) - h(k))``; dividing would make the integral gain depend
   on ``1/T_s^2`` and break eq. (12).
5. Eq. (21) prints ``u(k) = k_i I(k) - k_p h(k) + k_i sqrt(h(k))``: the last gain is ``k_l``, as
   eq. (15) and Fig. 3 require; the sentence after it lists "k_p, k_i and k_i" for ``k_p, k_l,
   k_i``.
6. Eq. (25), the rig's reference model, repeats eq. (23) (``0.25/(s^2 + 0.7071 s + 0.25)``). With
   the rig design stated beside it (``w_n = 0.065``, ``zeta = 0.7071``, ``t_s = 100 s``) it is
   ``0.004225/(s^2 + 0.0919 s + 0.004225)`` (eq. (14) gives ``w_n = 0.06505``).
7. Section 4.2 says the PLC function block implements "Equations (16) and (17)" (the EW-RLS
   update); the fixed-gain controller it describes is eq. (20)-(21).

Conventional 2-DOF PI, the baseline (:class:`TwoDofPI`, ``type: pi2dof``)
------------------------------------------------------------------------
The structure of Fig. 2, ``u = K_i I - K_p h``, tuned by eq. (7) at one operating level
``h_design``::

    K_p = (2 zeta w_n - a) / b                                               (7a)
    K_i = w_n^2 / b                                                          (7b)

with ``a`` the small-signal pole of eq. (3a) at ``h_design``, ``a = a'/(2 sqrt(h_design))``
(``linearization: tangent``, default, what "tuned around an operating point" means in practice),
or the paper's eq. (4b) value ``a = a'/sqrt(h_design)`` (``linearization: secant``, which is exact
for the non-linear term in eq. (8) but is twice the small-signal pole). Same integration,
clamping and start rules as the non-linear PI; ``start: rest`` sets ``I_0 = (u_eq(h_0) + K_p
h_0)/K_i`` with ``u_eq = a' sqrt(h_0)/b`` from the design model.

Units: times (``settling_time``, ``t``) in the scenario's time unit (the paper's seconds); levels
in the plant's level unit (mm for seed 002's simulated tank, m for its rig: see
:mod:`plants.tank`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "damping_from_overshoot",
    "natural_frequency_from_settling",
    "nlpi_gains",
    "pi2dof_gains",
    "NLPIConfig",
    "NonlinearPI",
    "PI2DOFConfig",
    "TwoDofPI",
    "twodof_update",
]

SETTLING_LOG = 4.6
"""``ln(1/0.01)``: eq. (14)'s constant, the envelope falling to the 1 % band."""


def damping_from_overshoot(overshoot_pct: float) -> float:
    """Damping ratio for a percent overshoot, seed 002 eq. (13) (read ``[ln(os/100)]^2``)."""
    if not 0.0 < overshoot_pct < 100.0:
        raise ValueError(f"overshoot_pct={overshoot_pct} must be in (0, 100)")
    log2 = math.log(overshoot_pct / 100.0) ** 2
    return math.sqrt(log2 / (math.pi**2 + log2))


def natural_frequency_from_settling(zeta: float, settling_time: float) -> float:
    """Natural frequency for a 1 % settling time, seed 002 eq. (14): ``4.6 / (zeta t_s)``."""
    if not settling_time > 0.0:
        raise ValueError(f"settling_time={settling_time} must be > 0")
    return SETTLING_LOG / (zeta * settling_time)


def nlpi_gains(b: float, a_prime: float, zeta: float, omega_n: float) -> tuple[float, float, float]:
    """``(K_p, K_l, K_i)`` of the non-linear PI, seed 002 eq. (10)-(12)."""
    if not b > 0.0:
        raise ValueError(f"b={b} must be > 0")
    return 2.0 * zeta * omega_n / b, a_prime / b, omega_n**2 / b


def pi2dof_gains(b: float, a: float, zeta: float, omega_n: float) -> tuple[float, float]:
    """``(K_p, K_i)`` of the 2-DOF PI on ``b/(s + a)``, seed 002 eq. (7)."""
    if not b > 0.0:
        raise ValueError(f"b={b} must be > 0")
    return (2.0 * zeta * omega_n - a) / b, omega_n**2 / b


# -- configurations -----------------------------------------------------------------------------
class _SpecConfig(BaseModel):
    """Design specification and limits shared by the tank laws."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    overshoot_pct: float = Field(gt=0, lt=100, description="percent overshoot (eq. (13))")
    settling_time: float = Field(gt=0, description="1 % settling time, scenario time unit (14)")
    u_min: float | None = Field(default=None, description="lower limit; None: the plant's pump's")
    u_max: float | None = Field(default=None, description="upper limit; None: the plant's pump's")
    integration: Literal["backward", "forward", "trapezoidal"] = Field(
        default="backward",
        description="backward: eq. (20) with e(k); forward: e(k-1); trapezoidal: their mean",
    )
    start: Literal["rest", "zero"] = Field(
        default="rest", description="rest: integral set at the first sample to hold y at rest"
    )
    u_start: float | None = Field(
        default=None,
        description="command at the first sample (bumpless from the plant's held input): the "
        "integral starts where it gives this command; None: as start says",
    )

    @model_validator(mode="after")
    def _limits_ordered(self) -> _SpecConfig:
        if self.u_min is not None and self.u_max is not None and not self.u_min < self.u_max:
            raise ValueError(f"u_min ({self.u_min}) must be below u_max ({self.u_max})")
        return self


class NLPIConfig(_SpecConfig):
    """Non-linear PI of seed 002 Fig. 3, designed from the overshoot and settling time."""

    type: Literal["nlpi"] = "nlpi"
    b: float | None = Field(
        default=None, gt=0, description="design value of b (eq. (3b)); None: the plant's"
    )
    a_prime: float | None = Field(
        default=None, ge=0, description="design value of a' (eq. (3b)); None: the plant's"
    )


class PI2DOFConfig(_SpecConfig):
    """Fixed-gain 2-DOF PI of seed 002 Fig. 2, tuned by eq. (7) at one level (the baseline)."""

    type: Literal["pi2dof"] = "pi2dof"
    h_design: float = Field(gt=0, description="operating level the gains are tuned at")
    b: float | None = Field(default=None, gt=0, description="design b; None: the plant's")
    a_prime: float | None = Field(default=None, ge=0, description="design a'; None: the plant's")
    linearization: Literal["tangent", "secant"] = Field(
        default="tangent",
        description="tangent: a = a'/(2 sqrt(h_design)) (small-signal pole); "
        "secant: a = a'/sqrt(h_design) (eq. (4b))",
    )


def _plant_param(plant: Any, name: str, law: str) -> float:
    value = getattr(getattr(plant, "params", None), name, None)
    if value is None:
        raise ValueError(
            f"{law}: the plant has no parameter {name!r}; give {name} in the law's configuration"
        )
    return float(value)


def _limits(config: _SpecConfig, plant: Any) -> tuple[float, float]:
    params = getattr(plant, "params", None)
    lo = config.u_min if config.u_min is not None else getattr(params, "u_min", -math.inf)
    hi = config.u_max if config.u_max is not None else getattr(params, "u_max", math.inf)
    if not lo < hi:
        raise ValueError(f"u_min ({lo}) must be below u_max ({hi})")
    return float(lo), float(hi)


@dataclass(frozen=True)
class TwoDofOptions:
    """How a tank law integrates, clamps and starts (shared by both laws and the self-tuning one).

    Attributes
    ----------
    u_min, u_max : float
        Command limits (clamping, section 3.4).
    integration : {"backward", "forward", "trapezoidal"}
        Integration rule (``backward`` is eq. (20) as corrected).
    start : {"rest", "zero"}
        Integral at the first sample.
    u_start : float, optional
        Command at the first sample (bumpless from a held input); overrides ``start``.
    """

    u_min: float = -math.inf
    u_max: float = math.inf
    integration: Literal["backward", "forward", "trapezoidal"] = "backward"
    start: Literal["rest", "zero"] = "rest"
    u_start: float | None = None

    @classmethod
    def of(cls, config: _SpecConfig, plant: Any) -> TwoDofOptions:
        """The options of ``config``, with limits defaulting to ``plant``'s pump's."""
        u_min, u_max = _limits(config, plant)
        return cls(u_min, u_max, config.integration, config.start, config.u_start)


def design_targets(config: _SpecConfig) -> tuple[float, float]:
    """``(zeta, omega_n)`` of the configured overshoot and settling time (eq. (13)-(14))."""
    zeta = damping_from_overshoot(config.overshoot_pct)
    return zeta, natural_frequency_from_settling(zeta, config.settling_time)


# -- laws ---------------------------------------------------------------------------------------
class _TwoDofBase:
    """Integrator, clamping and sample-interval bookkeeping shared by both laws."""

    Kp: float
    Ki: float

    def __init__(self, options: TwoDofOptions) -> None:
        if not options.u_min < options.u_max:
            raise ValueError(f"u_min ({options.u_min}) must be below u_max ({options.u_max})")
        self.u_min = float(options.u_min)
        self.u_max = float(options.u_max)
        self.integration = options.integration
        self.start = options.start
        self.u_start = None if options.u_start is None else float(options.u_start)
        self.reset()

    def reset(self) -> None:
        """Forget the integral and the previous execution."""
        self.integral = 0.0
        self._t_prev: float | None = None
        self._e_prev = 0.0

    def _static(self, y: float) -> float:
        """The command without the integral (``-K_p h (+ K_l sqrt(h))``)."""
        raise NotImplementedError

    def _rest_integral(self, y: float) -> float:
        raise NotImplementedError

    def resume(self, t: float) -> None:
        """The loop was open (output held) until ``t``: integrate from ``t`` on re-closing."""
        if self._t_prev is not None:
            self._t_prev = t

    def step(self, t: float, y: float, r: float) -> float:
        """One execution at time ``t`` with measured level ``y`` and set point ``r``; returns ``u``.

        Raises
        ------
        ValueError
            If ``t`` is earlier than the previous execution's.
        """
        e = r - y
        if self._t_prev is None:
            if self.u_start is not None:
                self.integral = (self.u_start - self._static(y)) / self.Ki
            elif self.start == "rest":
                self.integral = self._rest_integral(y)
            increment = 0.0
        else:
            dt = t - self._t_prev
            if dt < 0.0:
                raise ValueError(
                    f"{type(self).__name__}.step: time went backwards ({self._t_prev} -> {t})"
                )
            if self.integration == "backward":
                increment = dt * e
            elif self.integration == "forward":
                increment = dt * self._e_prev
            else:
                increment = 0.5 * dt * (e + self._e_prev)
        static = self._static(y)
        integral = self.integral + increment
        v = self.Ki * integral + static
        # clamping (section 3.4): the integral may bring the command to a limit, never past it
        if v > self.u_max and increment > 0.0:
            integral = max(self.integral, (self.u_max - static) / self.Ki)
        elif v < self.u_min and increment < 0.0:
            integral = min(self.integral, (self.u_min - static) / self.Ki)
        self.integral = integral
        v = self.Ki * integral + static
        self._t_prev = t
        self._e_prev = e
        return self.u_min if v < self.u_min else (self.u_max if v > self.u_max else v)


class NonlinearPI(_TwoDofBase):
    """Non-linear 2-DOF PI of seed 002 Fig. 3, eq. (10)-(14), (20)-(21) as corrected.

    Parameters
    ----------
    zeta, omega_n : float
        Closed-loop damping ratio and natural frequency (eq. (13)-(14)).
    b, a_prime : float
        Plant parameters the law is designed with (eq. (3b)).
    options : TwoDofOptions
        Limits, integration rule and start.
    """

    def __init__(
        self,
        *,
        zeta: float,
        omega_n: float,
        b: float,
        a_prime: float,
        options: TwoDofOptions = TwoDofOptions(),
    ) -> None:
        if not (zeta > 0.0 and omega_n > 0.0):
            raise ValueError(f"zeta={zeta} and omega_n={omega_n} must be > 0")
        self.zeta = float(zeta)
        self.omega_n = float(omega_n)
        self.set_model(b, a_prime)
        super().__init__(options)

    @classmethod
    def from_config(
        cls, config: NLPIConfig, *, u_bar: float = 0.0, plant: Any = None, tau_s: float = 1.0
    ) -> NonlinearPI:
        """Build from a configuration; ``b``, ``a'`` and limits default to the plant's.

        ``u_bar`` and ``tau_s`` are not used: the law has no feedforward and integrates over the
        actual intervals.
        """
        b = config.b if config.b is not None else _plant_param(plant, "b", "nlpi")
        a = config.a_prime if config.a_prime is not None else _plant_param(plant, "a_prime", "nlpi")
        zeta, omega_n = design_targets(config)
        return cls(
            zeta=zeta, omega_n=omega_n, b=b, a_prime=a, options=TwoDofOptions.of(config, plant)
        )

    def set_model(self, b: float, a_prime: float) -> None:
        """Redesign the gains for new plant parameters (eq. (10)-(12)); the integral is kept.

        The integral is the integral of the error (level x time), so the steady state it holds,
        ``I = K_p h / K_i = 2 zeta h / w_n``, does not depend on ``b`` or ``a'``: a redesign at rest
        moves the command only through ``K_l``.
        """
        if not a_prime >= 0.0:
            raise ValueError(f"a_prime={a_prime} must be >= 0")
        self.b = float(b)
        self.a_prime = float(a_prime)
        self.Kp, self.Kl, self.Ki = nlpi_gains(self.b, self.a_prime, self.zeta, self.omega_n)

    def _static(self, y: float) -> float:
        return -self.Kp * y + self.Kl * math.sqrt(y if y > 0.0 else 0.0)

    def _rest_integral(self, y: float) -> float:
        return self.Kp * y / self.Ki


class TwoDofPI(_TwoDofBase):
    """Conventional 2-DOF PI of seed 002 Fig. 2 with fixed gains from eq. (7) (the baseline).

    Parameters
    ----------
    Kp, Ki : float
        Gains (see :func:`pi2dof_gains`).
    b, a_prime : float
        Design model, used only for the ``start: rest`` integral.
    options : TwoDofOptions
        Limits, integration rule and start.
    """

    def __init__(
        self,
        *,
        Kp: float,
        Ki: float,
        b: float,
        a_prime: float,
        options: TwoDofOptions = TwoDofOptions(),
    ) -> None:
        if not Ki > 0.0:
            raise ValueError(f"Ki={Ki} must be > 0")
        self.Kp = float(Kp)
        self.Ki = float(Ki)
        self.b = float(b)
        self.a_prime = float(a_prime)
        super().__init__(options)

    @classmethod
    def from_config(
        cls, config: PI2DOFConfig, *, u_bar: float = 0.0, plant: Any = None, tau_s: float = 1.0
    ) -> TwoDofPI:
        """Build from a configuration: eq. (7) at ``h_design``; model and limits default to the
        plant's. ``u_bar`` and ``tau_s`` are not used."""
        b = config.b if config.b is not None else _plant_param(plant, "b", "pi2dof")
        ap = (
            config.a_prime
            if config.a_prime is not None
            else _plant_param(plant, "a_prime", "pi2dof")
        )
        root = math.sqrt(config.h_design)
        a = ap / (2.0 * root) if config.linearization == "tangent" else ap / root
        kp, ki = pi2dof_gains(b, a, *design_targets(config))
        return cls(Kp=kp, Ki=ki, b=b, a_prime=ap, options=TwoDofOptions.of(config, plant))

    def _static(self, y: float) -> float:
        return -self.Kp * y

    def _rest_integral(self, y: float) -> float:
        u_eq = self.a_prime * math.sqrt(y if y > 0.0 else 0.0) / self.b
        return (u_eq + self.Kp * y) / self.Ki


def twodof_update(
    static: NDArray[np.float64],
    increment: NDArray[np.float64],
    integral: NDArray[np.float64],
    ki: NDArray[np.float64] | float,
    u_min: NDArray[np.float64] | float,
    u_max: NDArray[np.float64] | float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One execution of the 2-DOF laws' :meth:`~_TwoDofBase.step` elementwise (the coordination
    agent's vectorised trials, :mod:`agents.wncsca.laws`): ``(u, integral after)``.

    ``static`` is the command without the integral at the measured level (``-K_p h + K_l
    sqrt(h)`` or ``-K_p h``), ``increment`` the integral's update before clamping (the rule's
    ``dt e``; zero at the first execution, whose integral the caller sets by the start rule).
    The clamp and the saturated output follow :meth:`~_TwoDofBase.step` operation by operation,
    so the values are bit-equal to it (``tests/unit/test_twodof_update.py``).
    """
    trial = integral + increment
    v = ki * trial + static
    up = (v > u_max) & (increment > 0.0)
    down = (v < u_min) & (increment < 0.0)
    new = np.where(
        up,
        np.maximum(integral, (u_max - static) / ki),
        np.where(down, np.minimum(integral, (u_min - static) / ki), trial),
    )
    v = ki * new + static
    return np.minimum(np.maximum(v, u_min), u_max), new
