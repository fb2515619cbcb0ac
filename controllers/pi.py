"""Discrete PI controller with feedforward, for sampled loops with varying sampling periods.

Seed 000, section III.B and Fig. 2: the plant input is the feedforward ``u_bar`` (the steady-state
input that holds the set point, eq. (5)-(7)) plus a feedback correction ``delta_u`` from a PI law
on the error ``e = r - y``::

    u_k = sat(u_bar + Kp e_k + I_k)

The integral uses the *actual* time between executions ``dt_k = t_k - t_{k-1}`` (sampling periods
change at run time, and delivery jitter makes them uneven):

* ``integration: forward`` (default, the forward-Euler integrator of Simulink's discrete PI block,
  which the paper's simulator used): ``I_k = I_{k-1} + Ki e_{k-1} dt_k``;
* ``integration: backward``: ``I_k = I_{k-1} + Ki e_k dt_k``.

Anti-windup by conditional integration (clamping): an integral update is discarded when the
output is saturated and the update would drive it further into saturation.

:class:`PI` is the law a controller node runs, one execution at a time; :func:`pi_update` is the
same execution elementwise over arrays, for the agent's vectorised trials
(:mod:`agents.wncsca.batch`, :mod:`agents.wncsca.chance`, :mod:`agents.wncsca.fast.predictor`),
bit-equal to :meth:`PI.step` (``tests/unit/test_pi_update.py`` pins the two together).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["PIConfig", "PI", "pi_update"]

_Values = NDArray[np.float64] | float


class PIConfig(BaseModel):
    """Configuration of one PI loop (seed 000's symbol names ``Kp``, ``Ki``)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type: Literal["pi"] = "pi"
    Kp: float = Field(description="proportional gain, input units per output unit")
    Ki: float = Field(description="integral gain, input units per (output unit x time unit)")
    u_min: float = Field(default=-math.inf, description="lower actuator limit")
    u_max: float = Field(default=math.inf, description="upper actuator limit")
    integration: Literal["forward", "backward"] = "forward"
    feedforward: Literal["steady_state", "none"] = Field(
        default="steady_state",
        description="steady_state: u_bar from the plant's equilibrium at the set points "
        "(seed 000 eq. (5)-(7)); none: u_bar = 0",
    )

    @model_validator(mode="after")
    def _limits_ordered(self) -> PIConfig:
        if not self.u_min < self.u_max:
            raise ValueError(f"u_min ({self.u_min}) must be below u_max ({self.u_max})")
        return self


class PI:
    """Discrete PI law with feedforward and clamping anti-windup.

    Parameters
    ----------
    config : PIConfig
        Gains, limits and integration rule.
    u_bar : float
        Initial feedforward; change it with :meth:`set_feedforward` when set points change.
    """

    def __init__(self, config: PIConfig, *, u_bar: float = 0.0) -> None:
        self.config = config
        self.u_bar = float(u_bar)
        self.reset()

    def reset(self) -> None:
        """Forget the integral and the previous execution."""
        self.integral = 0.0
        self._t_prev: float | None = None
        self._e_prev = 0.0

    def resume(self, t: float) -> None:
        """The loop was open (output held) until ``t``: the next execution integrates from ``t``,
        not over the whole open interval (bumpless re-closing)."""
        if self._t_prev is not None:
            self._t_prev = t

    def set_feedforward(self, u_bar: float) -> None:
        """Set the steady-state component ``u_bar`` (seed 000, eq. (5)-(7))."""
        self.u_bar = float(u_bar)

    def step(self, t: float, y: float, r: float) -> float:
        """One execution at time ``t`` with measurement ``y`` and set point ``r``; returns ``u``."""
        c = self.config
        e = r - y
        if self._t_prev is None:
            increment = 0.0
        else:
            dt = t - self._t_prev
            if dt < 0.0:
                raise ValueError(f"PI.step: time went backwards ({self._t_prev} -> {t})")
            increment = c.Ki * (self._e_prev if c.integration == "forward" else e) * dt
        v = self.u_bar + c.Kp * e + self.integral + increment
        if (v > c.u_max and increment > 0.0) or (v < c.u_min and increment < 0.0):
            increment = 0.0  # clamping: do not wind further into saturation
        self.integral += increment
        v = self.u_bar + c.Kp * e + self.integral
        self._t_prev = t
        self._e_prev = e
        return min(max(v, c.u_min), c.u_max)


def pi_update(
    e: NDArray[np.float64],
    increment: NDArray[np.float64],
    integral: NDArray[np.float64],
    u_bar: _Values,
    kp: _Values,
    u_min: _Values,
    u_max: _Values,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One execution of :meth:`PI.step` elementwise: ``(u, integral after)``.

    ``e`` is the error ``r - y`` of this execution and ``increment`` the integral's update
    before clamping, ``Ki e dt`` with the error the integration rule takes (``e`` or the previous
    execution's; zero at a loop's first execution); the clamp, the integral and the saturated
    output follow :meth:`PI.step` operation by operation, so the values are bit-equal to it.
    Elements the caller does not execute are its to mask (pass a zero increment and discard
    ``u``).
    """
    base = u_bar + kp * e
    v = base + integral + increment
    if not (
        np.fmin.reduce(v - u_min, axis=None) >= 0.0 and np.fmax.reduce(v - u_max, axis=None) <= 0.0
    ):
        # some output saturates (or is NaN): clamping, as PI.step
        wind = ((v > u_max) & (increment > 0.0)) | ((v < u_min) & (increment < 0.0))
        increment = np.where(wind, 0.0, increment)
    integral = integral + increment
    return np.minimum(np.maximum(base + integral, u_min), u_max), integral
