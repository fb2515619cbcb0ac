"""The control laws the fast and chance methods model (issue 35, item 7): each executed
elementwise over the realizations (chance) or candidate items (fast) exactly as a controller node
executes it one sample at a time, and its linear form about an operating point.

Two families, by their configurations (:data:`MODELLED_LAWS`):

* :class:`PILaw`, seed 000's PI (:mod:`controllers.pi`): ``u = sat(u_bar + K_p e + I)``, the
  integral of ``K_i e`` over the actual interval between executions (forward or backward rule),
  clamping anti-windup and the loop's steady-state feedforward ``u_bar``; executed by
  :func:`controllers.pi.pi_update`.
* :class:`TwoDofLaw`, seed 002's 2-DOF laws (:mod:`controllers.nlpi`): ``u = sat(K_i I + s(h))``
  with ``I`` the integral of the error (backward, forward or trapezoidal rule), the static part
  ``s(h) = -K_p h + K_l sqrt(h)`` (``nlpi``, eq. (21)) or ``-K_p h`` (``pi2dof``), clamping, and
  the integral set at the first execution by the law's start rule (``rest``, ``zero`` or
  ``u_start``); executed by :func:`controllers.nlpi.twodof_update`. The linearising term runs as
  it is: in the chance method's realizations only the plant is linearised, and its non-linear
  check replays the law on the non-linear plant.

Linear form (the fast method's closure of a plant's other loops, the jitter margin): about the
level ``y_bar``, ``u ~ c + k_r r - k_y y + k_i q + u_bar`` with ``q`` the integral of ``e`` since
the loop's first execution (:class:`LinearForm`): PI ``(k_r, k_y, k_i, c) = (K_p, K_p, K_i, 0)``
(its feedforward is ``u_bar``); 2-DOF ``(0, -s'(y_bar), K_i, K_i I_0 + s(y_bar) + k_y y_bar)``
with ``I_0`` the integral its start rule sets at the initial level (no feedforward). For the
``nlpi``, ``k_y = K_p - K_l / (2 sqrt(y_bar))``: with ``K_l = a'/b`` the linearised closed loop is
eq. (23)'s at every level, as the law's design intends.

A law is designed on the plant the loop runs on (``b``, ``a'`` default to the plant's), so a
model draw of :mod:`agents.wncsca.uncertainty` gets its own gains: :func:`stack` puts the laws
of the draws side by side, one value per realization.

Laws the methods do not model, and why, are in :data:`REFUSED`; ``scenario.checks.
check_agent_method`` refuses them on load with the method that applies (``paper``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.nlpi import NLPIConfig, NonlinearPI, PI2DOFConfig, TwoDofPI, twodof_update
from controllers.pi import PIConfig, pi_update
from controllers.registry import build_law

__all__ = [
    "MODELLED_LAWS",
    "REFUSED",
    "LinearForm",
    "PILaw",
    "TwoDofLaw",
    "modelled_law",
    "stack",
    "unmodelled_law",
]

Values = NDArray[np.float64] | float

MODELLED_LAWS: tuple[type[Any], ...] = (PIConfig, NLPIConfig, PI2DOFConfig)
"""The law configurations the fast and chance methods model (the module docstring). The paper's
method judges a loop of any single-loop law, by simulating it."""

REFUSED: dict[str, str] = {
    "stnlpi": "it re-designs its own gains on line from its EW-RLS estimates (seed 002 eq. (16)-"
    "(19)), so no fixed law stands for it over the test",
    "mrac": "a multi-loop adaptive law: its gains move with its adaptation during the test",
    "qdc": "a multi-loop law whose units run on each other's models over links (the agent "
    "governs it through its links' update periods, links:)",
    "pip_cascade": "a multi-loop cascade: the agent judges single-loop controllers",
}
"""Law type -> why the fast and chance methods do not model it."""


def unmodelled_law(method: str, loop: str, law: Any) -> str:
    """Why ``method`` cannot judge ``loop``, whose law ``law`` is not in :data:`MODELLED_LAWS`."""
    kind = getattr(law, "type", type(law).__name__)
    modelled = ", ".join(repr(c.model_fields["type"].default) for c in MODELLED_LAWS)
    why = REFUSED.get(kind, "it has no modelled form yet")
    return (
        f"the {method} method cannot judge loop {loop!r}: its control law is {kind!r}, and "
        f"the {method} method models {modelled} loops ({kind!r}: {why}); method 'paper' "
        "judges any single-loop law by simulating it"
    )


@dataclass(frozen=True)
class LinearForm:
    """A law about an operating point: ``u ~ c + k_r r - k_y y + k_i q + u_bar``, ``q`` the
    integral of the error since the first execution (the module docstring)."""

    k_r: float
    k_y: float
    k_i: float
    c: float


@dataclass(frozen=True)
class PILaw:
    """Seed 000's PI (:class:`controllers.pi.PI`), elementwise; the gains may be arrays (one
    value per realization)."""

    kp: Values
    ki: Values
    u_min: Values
    u_max: Values
    forward: bool

    def increment(self, e: Values, e_prev: Values, dt: Values) -> Any:
        """The integral's update before clamping: ``K_i e dt`` with the rule's error."""
        return self.ki * (e_prev if self.forward else e) * dt

    def start(self, y: Values, integral: NDArray[np.float64]) -> NDArray[np.float64]:
        """The integral at the first execution: the PI starts from 0 (its feedforward holds)."""
        return integral

    def update(
        self,
        e: NDArray[np.float64],
        y: NDArray[np.float64],
        increment: NDArray[np.float64],
        integral: NDArray[np.float64],
        u_bar: Values,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One execution: ``(u, integral after)`` (:func:`controllers.pi.pi_update`)."""
        return pi_update(e, increment, integral, u_bar, self.kp, self.u_min, self.u_max)

    def linear(self, y_bar: float, y0: float) -> LinearForm:
        """``(K_p, K_p, K_i, 0)``: the PI is linear but for its limits."""
        kp, ki = float(np.max(self.kp)), float(np.max(self.ki))
        return LinearForm(kp, kp, ki, 0.0)


@dataclass(frozen=True)
class TwoDofLaw:
    """Seed 002's 2-DOF laws (:class:`controllers.nlpi.NonlinearPI`, :class:`~controllers.nlpi.
    TwoDofPI`), elementwise: ``u = sat(K_i I - K_p h + K_l sqrt(h))`` (``K_l = 0``: the 2-DOF PI);
    ``a_prime / b`` give the 2-DOF PI's rest integral (0 for the non-linear PI, whose rest
    integral is ``K_p h / K_i``)."""

    kp: Values
    ki: Values
    kl: Values
    u_min: Values
    u_max: Values
    integration: str
    start_rule: str
    u_start: float | None
    a_prime: Values = 0.0
    b: Values = 1.0

    def static(self, y: Values) -> Any:
        """The command without the integral at the level ``y``."""
        return -self.kp * y + self.kl * np.sqrt(np.maximum(y, 0.0))

    def increment(self, e: Values, e_prev: Values, dt: Values) -> Any:
        """The integral's update before clamping (the rule's ``dt e``)."""
        if self.integration == "backward":
            return dt * e
        if self.integration == "forward":
            return dt * e_prev
        return 0.5 * dt * (e + e_prev)

    def start(self, y: Values, integral: NDArray[np.float64]) -> NDArray[np.float64]:
        """The integral at the first execution at level ``y``: the one that gives ``u_start``,
        or holds ``y`` at rest (``start: rest``), or 0."""
        shape = np.shape(integral)
        if self.u_start is not None:
            out = (self.u_start - self.static(y)) / self.ki
        elif self.start_rule == "rest":
            u_eq = self.a_prime * np.sqrt(np.maximum(y, 0.0)) / self.b
            out = (u_eq + self.kp * y) / self.ki
        else:
            out = np.zeros(shape)
        return np.broadcast_to(np.asarray(out, dtype=float), shape).copy()

    def update(
        self,
        e: NDArray[np.float64],
        y: NDArray[np.float64],
        increment: NDArray[np.float64],
        integral: NDArray[np.float64],
        u_bar: Values,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One execution: ``(u, integral after)`` (:func:`controllers.nlpi.twodof_update`; the
        law takes no feedforward, ``u_bar`` is not used)."""
        return twodof_update(self.static(y), increment, integral, self.ki, self.u_min, self.u_max)

    def linear(self, y_bar: float, y0: float) -> LinearForm:
        """The tangent at ``y_bar``, the integral counted from its start at level ``y0``."""
        kp, ki, kl = (float(np.max(v)) for v in (self.kp, self.ki, self.kl))
        if kl and not y_bar > 0.0:
            raise ValueError(
                f"the non-linear PI has no linear form at level {y_bar:g}: its linearising term "
                "K_l sqrt(h) has an infinite slope at 0 (judge a test whose set points are above 0)"
            )
        k_y = kp - (0.5 * kl / math.sqrt(y_bar) if kl else 0.0)
        i0 = float(self.start(np.array([y0]), np.zeros(1))[0])
        s_bar = float(self.static(y_bar))
        return LinearForm(0.0, k_y, ki, ki * i0 + s_bar + k_y * y_bar)


Law = PILaw | TwoDofLaw


def modelled_law(config: Any, plant: Any, loop: str = "", method: str = "fast") -> Law:
    """The law of configuration ``config`` designed on the plant model ``plant`` (as the
    controller node builds it), in its modelled form.

    Raises
    ------
    ValueError
        If the law is not modelled (:func:`unmodelled_law` says why and what applies).
    """
    if isinstance(config, PIConfig):
        return PILaw(
            config.Kp, config.Ki, config.u_min, config.u_max, config.integration == "forward"
        )
    if isinstance(config, NLPIConfig | PI2DOFConfig):
        law = build_law(config, u_bar=0.0, plant=plant, tau_s=1.0)
        common = {
            "ki": law.Ki,
            "u_min": law.u_min,
            "u_max": law.u_max,
            "integration": law.integration,
            "start_rule": law.start,
            "u_start": law.u_start,
        }
        if isinstance(law, NonlinearPI):
            return TwoDofLaw(kp=law.Kp, kl=law.Kl, **common)
        assert isinstance(law, TwoDofPI)
        return TwoDofLaw(kp=law.Kp, kl=0.0, a_prime=law.a_prime, b=law.b, **common)
    raise ValueError(unmodelled_law(method, loop, config))


def stack(laws: list[Law], index: NDArray[np.int64]) -> Law:
    """The laws of several model draws as one: each numeric field that differs between them
    becomes an array with realization ``r``'s value at ``r`` (``index[r]``: its draw)."""
    first = laws[0]
    if all(law == first for law in laws[1:]):
        return first
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(first):
        values = [getattr(law, f.name) for law in laws]
        if isinstance(values[0], float | int) and not isinstance(values[0], bool):
            if any(v != values[0] for v in values[1:]):
                changes[f.name] = np.asarray(values, dtype=float)[index]
        elif any(v != values[0] for v in values[1:]):
            raise ValueError(f"the model draws' laws differ in {f.name!r}")
    return dataclasses.replace(first, **changes)
