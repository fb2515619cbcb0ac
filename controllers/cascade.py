"""PI simple-feedback and PI-P cascade laws for the sampled cascade process (seed 004).

Seed 004, Figures 1 and 2. Both laws regulate about a set point ``r1`` of the primary variable;
the discrete PI is the paper's ``Q(q^-1) = (k0 - k1 q^-1)/(1 - q^-1)`` written with a gain and
an integral time (backward-Euler integration, so ``k0 = Kc (1 + dt/Ti)``, ``k1 = Kc``; the
paper's Example 4 law ``(0.144 - 0.138 q^-1)/(1 - q^-1)`` is ``Kc = 0.138``, ``Ti = 23 dt``):

* :class:`SFBPI` -- simple feedback (Fig. 1): ``u = Q (r1 - y1)``.
* :class:`PIPCascade` -- PI-P cascade (Fig. 2): ``r2 = Q1 (r1 - y1)`` (PI master) and
  ``u = Q2 (r2 - y2)`` with ``Q2 = Kc2`` (proportional slave, the industrial practice the paper
  follows, Remark 5: no integral action in the inner loop).
* :class:`LinearFeedback` -- any ``u = -K(q^-1) y`` (e.g. a minimum-variance law).

Each configuration's :meth:`feedback` gives the law as ``u = -sum_l K_l(q^-1) ym_l`` (the form
:func:`plants.cascade.model.closed_loop` takes): SFB ``{y1: Q}``, cascade
``{y2: Q2, y1: Q1 Q2}``.

Tuning
------
:func:`tune_sfb_pi` and :func:`tune_pi_p` minimize the analytic variance of the measured primary
(:func:`plants.cascade.variance.output_variance`) over ``(Kc, Ti)`` and ``(Kc1, Ti1, Kc2)`` by
Nelder-Mead: the paper's "PI achievable performance" for the SFB loop and "best CLPI achieved"
with the PI-P cascade (its Examples 1-2). The settings shipped for the examples
(:data:`EXAMPLE_SFB`, :data:`EXAMPLE_CASCADE`) are those optima, rounded
(``bench/monitor_examples.py --retune`` recomputes them). A variance-optimal PI-P is as tight as
a PI-P gets, so the cascade approaches its invariant bound (component 1a) as closely as the
restricted structure allows; it ignores the variance of ``u`` and robustness, like the paper.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from scipy.optimize import minimize

from controllers.pi import PI, PIConfig
from plants.cascade.model import CascadeProcessConfig
from plants.cascade.transfer import TF
from plants.cascade.variance import output_variance

__all__ = [
    "pi_tf",
    "SFBPIConfig",
    "SFBPI",
    "PIPSettings",
    "PIPCascadeConfig",
    "PIPCascade",
    "LinearFeedbackConfig",
    "LinearFeedback",
    "tune_sfb_pi",
    "tune_pi_p",
    "EXAMPLE_SFB",
    "EXAMPLE_CASCADE",
]


def pi_tf(kc: float, ti: float, dt: float = 1.0) -> TF:
    """``Q(q^-1) = Kc ((1 + dt/Ti) - q^-1) / (1 - q^-1)`` (backward-Euler PI)."""
    return TF([kc * (1.0 + dt / ti), -kc], [1.0, -1.0])


class SFBPIConfig(BaseModel):
    """Simple-feedback PI on one measurement (seed 004, Fig. 1)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type: Literal["sfb_pi"] = "sfb_pi"
    measurement: str = Field(min_length=1, description="name of the primary measurement")
    Kc: float = Field(description="controller gain, u units per y1 unit")
    Ti: float = Field(gt=0, description="integral time, time units")
    dt: float = Field(default=1.0, gt=0, description="sampling interval")
    setpoint: float = 0.0
    u_min: float = -math.inf
    u_max: float = math.inf

    @model_validator(mode="after")
    def _limits(self) -> SFBPIConfig:
        if not self.u_min < self.u_max:
            raise ValueError(f"u_min ({self.u_min}) must be below u_max ({self.u_max})")
        return self

    def feedback(self) -> dict[str, TF]:
        """``{measurement: Q}`` for ``u = -Q y1`` (about the set point)."""
        return {self.measurement: pi_tf(self.Kc, self.Ti, self.dt)}


class SFBPI:
    """Simple-feedback PI law; ``step(t, measurements) -> u``."""

    def __init__(self, config: SFBPIConfig) -> None:
        self.config = config
        self._pi = PI(
            PIConfig(
                Kp=config.Kc,
                Ki=config.Kc / config.Ti,
                u_min=config.u_min,
                u_max=config.u_max,
                integration="backward",
                feedforward="none",
            )
        )
        self.reset()

    def reset(self) -> None:
        """Forget the integral."""
        self._pi.reset()
        self._first = True

    def step(self, t: float, measurements: Mapping[str, float]) -> float:
        """One execution with the measurements by name; returns ``u``."""
        c = self.config
        e = c.setpoint - measurements[c.measurement]
        if self._first:  # backward Euler from the first sample on (controllers.pi skips it)
            self._pi.integral = c.Kc / c.Ti * e * c.dt
            self._first = False
        return self._pi.step(t, measurements[c.measurement], c.setpoint)


class PIPSettings(BaseModel):
    """Gains and limits of a PI-P cascade: PI master ``(Kc1, Ti1)`` setting the secondary's set
    point ``r2`` within ``[r2_min, r2_max]``, P slave ``Kc2`` about ``u_bias`` within
    ``[u_min, u_max]`` (shared by :class:`PIPCascadeConfig` and the platform law's
    configuration, :class:`controllers.cascade_law.PIPCascadeLawConfig`)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    Kc1: float = Field(description="master gain, y2 set-point units per y1 unit")
    Ti1: float = Field(gt=0, description="master integral time, time units")
    Kc2: float = Field(description="slave (proportional) gain, u units per y2 unit")
    u_bias: float = Field(default=0.0, description="slave output at zero error")
    r2_min: float = -math.inf
    r2_max: float = math.inf
    u_min: float = -math.inf
    u_max: float = math.inf

    @model_validator(mode="after")
    def _limits(self) -> PIPSettings:
        if not self.r2_min < self.r2_max:
            raise ValueError(f"r2_min ({self.r2_min}) must be below r2_max ({self.r2_max})")
        if not self.u_min < self.u_max:
            raise ValueError(f"u_min ({self.u_min}) must be below u_max ({self.u_max})")
        return self


class PIPCascadeConfig(PIPSettings):
    """PI-P cascade (seed 004, Fig. 2): PI master on the primary, P slave on the secondary."""

    type: Literal["pi_p_cascade"] = "pi_p_cascade"
    primary: str = Field(min_length=1)
    secondary: str = Field(min_length=1)
    dt: float = Field(default=1.0, gt=0)
    setpoint: float = 0.0

    @model_validator(mode="after")
    def _check(self) -> PIPCascadeConfig:
        if self.primary == self.secondary:
            raise ValueError(f"secondary must differ from primary ({self.primary!r})")
        return self

    def feedback(self) -> dict[str, TF]:
        """``{secondary: Q2, primary: Q1 Q2}`` for ``u = -Q2 y2 - Q1 Q2 y1``."""
        q1 = pi_tf(self.Kc1, self.Ti1, self.dt)
        return {self.secondary: TF([self.Kc2]), self.primary: q1 * self.Kc2}


class PIPCascade:
    """PI-P cascade law; ``step(t, measurements) -> u``.

    The master's output (the slave's set point) is limited to ``[r2_min, r2_max]`` with the
    clamping anti-windup of :class:`controllers.pi.PI`.
    """

    def __init__(self, config: PIPCascadeConfig) -> None:
        self.config = config
        self._master = PI(
            PIConfig(
                Kp=config.Kc1,
                Ki=config.Kc1 / config.Ti1,
                u_min=config.r2_min,
                u_max=config.r2_max,
                integration="backward",
                feedforward="none",
            )
        )
        self.reset()

    def reset(self) -> None:
        """Forget the master's integral."""
        self._master.reset()
        self._first = True

    def step(
        self, t: float, measurements: Mapping[str, float], setpoint: float | None = None
    ) -> float:
        """One execution with the measurements by name; returns ``u``. ``setpoint`` overrides
        the configured set point ``r1`` (a set point that changes during a run)."""
        c = self.config
        r1 = c.setpoint if setpoint is None else setpoint
        y1 = measurements[c.primary]
        if self._first:
            self._master.integral = c.Kc1 / c.Ti1 * (r1 - y1) * c.dt
            self._first = False
        r2 = self._master.step(t, y1, r1)
        u = c.u_bias + c.Kc2 * (r2 - measurements[c.secondary])
        return min(max(u, c.u_min), c.u_max)


class LinearFeedbackConfig(BaseModel):
    """``u = -num(q^-1)/den(q^-1) y`` on one measurement (e.g. a minimum-variance law)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type: Literal["linear_feedback"] = "linear_feedback"
    measurement: str = Field(min_length=1)
    num: tuple[float, ...] = Field(min_length=1)
    den: tuple[float, ...] = Field(default=(1.0,))
    setpoint: float = 0.0

    @field_validator("den")
    @classmethod
    def _monic(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if len(v) == 0 or v[0] != 1.0:
            raise ValueError("den must be monic: first coefficient 1.0")
        return v

    def feedback(self) -> dict[str, TF]:
        return {self.measurement: TF(self.num, self.den)}


class LinearFeedback:
    """Difference-equation law ``den u = -num (y - r)``."""

    def __init__(self, config: LinearFeedbackConfig) -> None:
        self.config = config
        self.reset()

    def reset(self) -> None:
        self._eh = [0.0] * len(self.config.num)
        self._uh = [0.0] * (len(self.config.den) - 1)

    def step(self, t: float, measurements: Mapping[str, float]) -> float:
        c = self.config
        self._eh.pop()
        self._eh.insert(0, measurements[c.measurement] - c.setpoint)
        u = -sum(b * e for b, e in zip(c.num, self._eh, strict=True))
        u -= sum(a * x for a, x in zip(c.den[1:], self._uh, strict=True))
        if self._uh:
            self._uh.pop()
            self._uh.insert(0, u)
        return u


# ------------------------------------------------------------------------------------------------
# Variance-optimal tuning on the analytic model
# ------------------------------------------------------------------------------------------------
_PENALTY = 1e300


def _optimize(fun, grid: Sequence[Sequence[float]], n_starts: int = 3) -> tuple[np.ndarray, float]:
    """Nelder-Mead in log-parameters from the best ``n_starts`` points of a coarse grid (the
    variance surface of restricted-structure controllers has several local minima)."""
    pts = np.array(np.meshgrid(*[np.log(np.asarray(g, dtype=float)) for g in grid])).reshape(
        len(grid), -1
    )
    vals = np.array([fun(pts[:, i]) for i in range(pts.shape[1])])
    best_x, best_f = None, math.inf
    for i in np.argsort(vals)[:n_starts]:
        res = minimize(
            fun,
            pts[:, i],
            method="Nelder-Mead",
            options={"xatol": 1e-4, "fatol": 1e-10, "maxiter": 4000, "maxfev": 8000},
        )
        if res.fun < best_f:
            best_x, best_f = res.x, float(res.fun)
    return np.exp(best_x), best_f


def tune_sfb_pi(process: CascadeProcessConfig) -> tuple[SFBPIConfig, float]:
    """PI on the primary minimizing the analytic variance of the measured primary.

    Returns the configuration and the variance it achieves. ``Kc`` is searched positive (the
    examples have positive process gains); multi-start Nelder-Mead in ``log(Kc), log(Ti)``.
    """
    primary, dt = process.primary, process.dt

    def fun(x: np.ndarray) -> float:
        kc, ti = np.exp(x)
        v = output_variance(process, {primary: pi_tf(kc, ti, dt)})
        return v if math.isfinite(v) else _PENALTY

    grid = ([0.1, 0.3, 1.0, 3.0], [dt * t for t in (3.0, 10.0, 30.0, 100.0)])
    (kc, ti), var = _optimize(fun, grid)
    return SFBPIConfig(measurement=primary, Kc=float(kc), Ti=float(ti), dt=dt), var


def tune_pi_p(process: CascadeProcessConfig, secondary: str) -> tuple[PIPCascadeConfig, float]:
    """PI-P cascade minimizing the analytic variance of the measured primary (best CLPI);
    multi-start Nelder-Mead in ``log(Kc1), log(Ti1), log(Kc2)``."""
    primary, dt = process.primary, process.dt

    def fun(x: np.ndarray) -> float:
        kc1, ti1, kc2 = np.exp(x)
        cfg = {secondary: TF([kc2]), primary: pi_tf(kc1, ti1, dt) * kc2}
        v = output_variance(process, cfg)
        return v if math.isfinite(v) else _PENALTY

    grid = ([0.1, 0.3, 1.0, 3.0], [dt * t for t in (3.0, 10.0, 30.0, 100.0)], [0.3, 1, 3, 10])
    (kc1, ti1, kc2), var = _optimize(fun, grid)
    cfg = PIPCascadeConfig(
        primary=primary,
        secondary=secondary,
        Kc1=float(kc1),
        Ti1=float(ti1),
        Kc2=float(kc2),
        dt=dt,
    )
    return cfg, var


# Settings for plants.cascade.examples.EXAMPLE_1..3 (variance-optimal, rounded; see module doc).
EXAMPLE_SFB: dict[str, SFBPIConfig] = {
    "example_1": SFBPIConfig(measurement="y1", Kc=1.75, Ti=36.1),
    "example_2": SFBPIConfig(measurement="y1", Kc=0.886, Ti=25.0),
    "example_3": SFBPIConfig(measurement="y1", Kc=1.41, Ti=83.8),
}
"""Variance-optimal PI of each example's simple-feedback loop (the loop the monitor analyses)."""

EXAMPLE_CASCADE: dict[str, dict[str, PIPCascadeConfig]] = {
    "example_1": {
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.87, Ti1=27.6, Kc2=4.05),
    },
    "example_2": {
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.13, Ti1=18.6, Kc2=3.82),
    },
    "example_3": {
        "y3": PIPCascadeConfig(primary="y1", secondary="y3", Kc1=1.88, Ti1=44.3, Kc2=3.92),
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.51, Ti1=27.5, Kc2=3.29),
    },
}
"""Variance-optimal PI-P cascade of each example for each candidate secondary."""
