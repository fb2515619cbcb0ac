"""Single uniform tank with a free outlet, seed 002 (Short & Selvakumar 2020), section 2.

State ``x = (h,)`` (liquid level), inputs ``u = (u, q_d)`` (pump/valve command and a disturbance
outflow), output ``y = (h,)``.

Model, seed 002 eq. (1)-(3), with a disturbance outflow added::

    A_T dh/dt = K_v u - A_o sqrt(2 g h)                                   (2)
    dh/dt     = b sat(u) - a' sqrt(h) - q_d                                (3a) + disturbance
    b  = K_v / A_T,   a' = A_o sqrt(2 g) / A_T                             (3b)

``sat`` clips the command to the pump's range ``[u_min, u_max]`` (a pump cannot run backwards,
hence ``u_min = 0`` by default). ``q_d`` is an extra outflow (a draw-off) expressed as a **level
rate**, i.e. volumetric flow divided by ``A_T``, in the level unit per second; negative values are
an extra inflow. Eq. (4) (``a(t) = a'/sqrt(h)``) is the paper's change of variables for the
controller design, not a different model.

Equilibrium for a level ``h_bar`` with ``q_d = 0``::

    u_bar = a' sqrt(h_bar) / b

Linearization at ``h > 0`` (tangent; note it is ``a'/(2 sqrt(h))``, half the "pole" ``a(t)`` of
eq. (4b), which is the secant ``a' sqrt(h) / h``)::

    d(dh)/dt = -a'/(2 sqrt(h)) dh + b du - dq_d

Parameter sets and units
------------------------
The paper does not state the level unit next to its models; we infer it from the set points it
applies to each, and every number of a scenario (levels, ``q_d``) must use the same unit:

* :data:`SIM_PARAMS`, eq. (22) (``b = 2.0``, ``a' = 0.5``): **h in mm**, t in s. The simulation
  study (section 4.1) commands 50, 100 and 150 mm. Read in mm the tank has an open-loop time
  constant ``2 sqrt(h)/a' = 40 s`` at 100 mm, and the 13 s design makes the loop ~3x faster than
  the tank, the same ratio as on the rig (285 s open loop at 0.5 m, 100 s design); read in m it
  would be a 1.3 s tank slowed down to 13 s, which is not what a level loop is designed for.
  ``u`` is dimensionless (the units of eq. (22)); ``u_bar`` is 1.77, 2.50 and 3.06 at the three
  levels. No pump range is given; we leave ``u_max`` unbounded.
* :data:`RIG_PARAMS`, eq. (24) (``b = 0.0122``, ``a' = 0.00497``): **h in m**, t in s, the
  laboratory rig of section 4.2 (set points 0.5 m and 1.0 m; ``u_bar`` = 0.288 and 0.407). The
  paper does not give the drive's range. We assume ``u`` in ``[0, 2]`` (:data:`RIG_U_MAX`): the
  100 s design then never saturates on the paper's steps from an empty tank (the command peaks
  at 1.41 on the first step and 1.56 on the second); with a drive normalized to ``[0, 1]`` both
  steps saturate, consistent with the paper's remark that 100 s was chosen to avoid (significant)
  saturation. ``bench/tank_study.py`` reports both.

Robustness of ``rhs`` near an empty tank
----------------------------------------
``sqrt(h)`` has an infinite derivative at ``h = 0``, so a fixed-step RK4 stage can step slightly
below zero when the tank drains to empty. ``rhs`` uses ``sqrt(max(h, 0))`` (no NaN) and, when
``h <= 0``, does not let the level fall further (``dh/dt = max(b sat(u) - q_d, 0)``: an empty tank
cannot drain). A step ending below zero is thus possible only by the RK4 combination of stages
(at most one step's truncation error, a few micro-units), it is never amplified, and
:meth:`Tank.outputs` reports ``max(h, 0)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    import control

__all__ = ["TankParams", "Tank", "SIM_PARAMS", "RIG_PARAMS", "RIG_U_MAX"]


class TankParams(BaseModel):
    """Parameters of seed 002 eq. (3) by the paper's symbol names, plus the pump's range."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    b: float = Field(gt=0, description="input gain K_v/A_T, level unit per second per unit u")
    a_prime: float = Field(
        gt=0, description="outflow coefficient a' = A_o sqrt(2g)/A_T, level unit^0.5 per second"
    )
    u_min: float = Field(default=0.0, description="lowest pump command (a pump cannot reverse)")
    u_max: float = Field(default=math.inf, description="highest pump command")

    @model_validator(mode="after")
    def _limits_ordered(self) -> TankParams:
        if not self.u_min < self.u_max:
            raise ValueError(f"u_min ({self.u_min}) must be below u_max ({self.u_max})")
        return self


class Tank:
    """The tank as a plant object: ``rhs``, ``outputs``, ``equilibrium``, ``linearize``."""

    state_names: tuple[str, ...] = ("h",)
    input_names: tuple[str, ...] = ("u", "q_d")
    output_names: tuple[str, ...] = ("h",)

    def __init__(self, params: TankParams) -> None:
        self.params = params
        self._b = params.b
        self._a = params.a_prime
        self._u_min = params.u_min
        self._u_max = params.u_max

    # -- dynamics -------------------------------------------------------------------------------
    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """Seed 002 eq. (3a) with pump saturation and disturbance outflow: ``dh/dt``.

        ``u`` is ``(u, q_d)``; a one-element ``u`` means ``q_d = 0``.
        """
        h = x.tolist()[0]
        inputs = u.tolist()
        cmd = inputs[0]
        q_d = inputs[1] if len(inputs) > 1 else 0.0
        cmd = self._u_min if cmd < self._u_min else (self._u_max if cmd > self._u_max else cmd)
        inflow = self._b * cmd - q_d
        if h > 0.0:
            return np.array((inflow - self._a * math.sqrt(h),))
        return np.array((inflow if inflow > 0.0 else 0.0,))  # empty: cannot drain further

    def batch_params(self) -> tuple[float, ...]:
        """The constants :meth:`rhs_batch` takes, one value each."""
        return (self._b, self._a, self._u_min, self._u_max)

    @staticmethod
    def rhs_batch(
        p: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]],
        u: Sequence[NDArray[np.float64]],
    ) -> tuple[NDArray[np.float64], ...]:
        """:meth:`rhs` on many tanks at once: ``p`` (:meth:`batch_params`), ``x`` and ``u`` hold
        one array per constant, state and input, one element per tank; the same operations
        element by element (the agent's batched checks, ``agents/wncsca/batch.py``)."""
        return Tank.rhs_batch_held(p, x, Tank.rhs_batch_inputs(p, u))

    @staticmethod
    def rhs_batch_inputs(
        p: Sequence[NDArray[np.float64]],
        u: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]] | None = None,
        span: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], ...]:
        """What :meth:`rhs_batch` computes from the inputs alone (the inflow), once for a
        segment they hold; ``x`` and ``span`` are not needed."""
        b, _, u_min, u_max = p
        # the clip of rhs (u_min < u_max; NaN stays NaN, as in rhs)
        cmd = np.minimum(np.maximum(u[0], u_min), u_max)
        return (b * cmd - u[1] if len(u) > 1 else b * cmd,)

    @staticmethod
    def rhs_batch_held(
        p: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]],
        held: tuple[NDArray[np.float64], ...],
    ) -> tuple[NDArray[np.float64], ...]:
        """:meth:`rhs_batch` with the inflow of :meth:`rhs_batch_inputs`."""
        a = p[1]
        (h,) = x
        (inflow,) = held
        if np.minimum.reduce(h) > 0.0:  # every tank holds water (False with a NaN level)
            return (inflow - a * np.sqrt(h),)
        full = inflow - a * np.sqrt(np.where(h > 0.0, h, 0.0))
        return (np.where(h > 0.0, full, np.where(inflow > 0.0, inflow, 0.0)),)

    @staticmethod
    def outputs_batch(x: Sequence[NDArray[np.float64]]) -> tuple[NDArray[np.float64], ...]:
        """:meth:`outputs` of many tanks at once (one array per state)."""
        return (np.where(x[0] > 0.0, x[0], 0.0),)

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured level ``(h,)`` (never below zero)."""
        h = float(x[0])
        return np.array((h if h > 0.0 else 0.0,))

    # -- equilibrium ----------------------------------------------------------------------------
    def equilibrium(
        self, y_bar: Mapping[str, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """State and input that hold the level at ``y_bar["h"]`` with ``q_d = 0``.

        Parameters
        ----------
        y_bar : mapping
            ``{"h": level}``.

        Returns
        -------
        x_bar, u_bar : ndarray
            ``(h_bar,)`` and ``(a' sqrt(h_bar) / b, 0)``.

        Raises
        ------
        ValueError
            If ``h`` is missing or negative, or the pump cannot deliver the inflow.
        """
        if "h" not in y_bar:
            raise ValueError("Tank.equilibrium: set point missing for output 'h'")
        h_bar = float(y_bar["h"])
        if not h_bar >= 0.0:
            raise ValueError(f"Tank.equilibrium: level h={h_bar} must be >= 0")
        u_bar = self._a * math.sqrt(h_bar) / self._b
        if not self._u_min <= u_bar <= self._u_max:
            raise ValueError(
                f"Tank.equilibrium: holding h={h_bar} needs u={u_bar:.6g}, outside the pump "
                f"range [{self._u_min}, {self._u_max}]"
            )
        return np.array((h_bar,)), np.array((u_bar, 0.0))

    # -- linearization --------------------------------------------------------------------------
    def jacobians(
        self, x: NDArray[np.float64], u: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``A = df/dh = -a'/(2 sqrt(h))`` and ``B = (b, -1)`` at ``(x, u)``, for ``h > 0``.

        ``B[0, 0]`` is ``b`` inside the pump range and 0 where the command is saturated.
        """
        h = float(x[0])
        if not h > 0.0:
            raise ValueError(
                f"Tank.linearize: level h={h} must be > 0 (sqrt(h) is not smooth at 0)"
            )
        cmd = float(u[0])
        inside = self._u_min <= cmd <= self._u_max
        A = np.array([[-self._a / (2.0 * math.sqrt(h))]])
        B = np.array([[self._b if inside else 0.0, -1.0]])
        return A, B

    def linearize(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
        """Small-signal model ``(A, B, C, D)`` at ``(x, u)`` as a ``control.StateSpace``."""
        import control

        A, B = self.jacobians(x, u)
        return control.ss(
            A, B, np.array([[1.0]]), np.zeros((1, 2)),
            states=list(self.state_names), inputs=list(self.input_names),
            outputs=list(self.output_names),
        )  # fmt: skip


SIM_PARAMS = TankParams(b=2.0, a_prime=0.5)
"""Seed 002 eq. (22), the simulated tank of section 4.1: h in mm, t in s, pump range [0, inf)."""

RIG_U_MAX = 2.0
"""Our assumption for the rig's drive range ``[0, RIG_U_MAX]`` (the paper gives none)."""

RIG_PARAMS = TankParams(b=0.0122, a_prime=0.00497, u_min=0.0, u_max=RIG_U_MAX)
"""Seed 002 eq. (24), the laboratory rig of section 4.2: h in m, t in s, drive range [0, 2]."""
