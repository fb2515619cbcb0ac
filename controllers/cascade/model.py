"""The paper twin of seed 004's laws: PI simple feedback and the PI-P cascade, sample by sample.

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

These laws run on the sampled processes of :mod:`plants.cascade`
(:func:`plants.cascade.routine.simulate`); the bus runs the PI-P cascade as
:mod:`controllers.cascade.law`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from controllers.pi import PI, PIConfig
from plants.cascade.transfer import TF

__all__ = [
    "pi_tf",
    "SFBPIConfig",
    "SFBPI",
    "PIPSettings",
    "PIPCascadeConfig",
    "PIPCascade",
    "LinearFeedbackConfig",
    "LinearFeedback",
]


def _check_below(lo_name: str, lo: float, hi_name: str, hi: float) -> None:
    """Refuse a lower limit that is not below its upper one (``ValueError`` naming both)."""
    if not lo < hi:
        raise ValueError(f"{lo_name} ({lo}) must be below {hi_name} ({hi})")


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
        _check_below("u_min", self.u_min, "u_max", self.u_max)
        return self

    def feedback(self) -> dict[str, TF]:
        """``{measurement: Q}`` for ``u = -Q y1`` (about the set point)."""
        return {self.measurement: pi_tf(self.Kc, self.Ti, self.dt)}


class _BackwardPI:
    """:class:`controllers.pi.PI` (backward-Euler integral, no feedforward, output limits
    ``[lo, hi]``) that also integrates its first sample, ``Kc/Ti e dt`` (controllers.pi skips it):
    the paper's ``Q(q^-1)`` from the first sample on."""

    def __init__(self, kc: float, ti: float, dt: float, lo: float, hi: float) -> None:
        self._kc, self._ti, self._dt = kc, ti, dt
        self._pi = PI(
            PIConfig(
                Kp=kc,
                Ki=kc / ti,
                u_min=lo,
                u_max=hi,
                integration="backward",
                feedforward="none",
            )
        )
        self.reset()

    def reset(self) -> None:
        """Forget the integral."""
        self._pi.reset()
        self._first = True

    def step(self, t: float, y: float, r: float) -> float:
        """One execution on measurement ``y`` and set point ``r``."""
        if self._first:
            self._pi.integral = self._kc / self._ti * (r - y) * self._dt
            self._first = False
        return self._pi.step(t, y, r)


class SFBPI:
    """Simple-feedback PI law; ``step(t, measurements) -> u``."""

    def __init__(self, config: SFBPIConfig) -> None:
        self.config = config
        self._pi = _BackwardPI(config.Kc, config.Ti, config.dt, config.u_min, config.u_max)

    def reset(self) -> None:
        """Forget the integral."""
        self._pi.reset()

    def step(self, t: float, measurements: Mapping[str, float]) -> float:
        """One execution with the measurements by name; returns ``u``."""
        c = self.config
        return self._pi.step(t, measurements[c.measurement], c.setpoint)


class PIPSettings(BaseModel):
    """Gains and limits of a PI-P cascade: PI master ``(Kc1, Ti1)`` setting the secondary's set
    point ``r2`` within ``[r2_min, r2_max]``, P slave ``Kc2`` about ``u_bias`` within
    ``[u_min, u_max]`` (shared by :class:`PIPCascadeConfig` and the platform law's
    configuration, :class:`controllers.cascade.law.PIPCascadeLawConfig`)."""

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
        _check_below("r2_min", self.r2_min, "r2_max", self.r2_max)
        _check_below("u_min", self.u_min, "u_max", self.u_max)
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
        self._master = _BackwardPI(config.Kc1, config.Ti1, config.dt, config.r2_min, config.r2_max)

    def reset(self) -> None:
        """Forget the master's integral."""
        self._master.reset()

    def step(
        self, t: float, measurements: Mapping[str, float], setpoint: float | None = None
    ) -> float:
        """One execution with the measurements by name; returns ``u``. ``setpoint`` overrides
        the configured set point ``r1`` (a set point that changes during a run)."""
        c = self.config
        r1 = c.setpoint if setpoint is None else setpoint
        r2 = self._master.step(t, measurements[c.primary], r1)
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
