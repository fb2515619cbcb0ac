"""A train of ``n`` tanks in series, each seed 002's tank (Short & Selvakumar 2020, eq. (3)),
where part of each tank's free outflow runs into the next: ``n`` coupled level loops.

States ``x = (h0, ..., h{n-1})`` (levels), inputs ``u = (u0, ..., u{n-1})`` (the tanks' pump
commands), outputs ``y = (h0, ..., h{n-1})``. Tank ``i``'s pump and level make one loop; a
fraction ``c`` of tank ``i-1``'s outflow feeds tank ``i``, so every loop's move disturbs every
loop downstream of it, and none upstream.

Model (seed 002 eq. (3a) per tank, plus the inflow from upstream)::

    dh_0/dt = b sat(u_0)                        - a' sqrt(h_0)
    dh_i/dt = b sat(u_i) + c a' sqrt(h_{i-1})   - a' sqrt(h_i),      i = 1 .. n-1

with ``b``, ``a'`` of eq. (3b) (``plants.tank.SIM_PARAMS``: eq. (22), ``b = 2.0``,
``a' = 0.5``, h in mm, t in s) and ``sat`` the pump range ``[u_min, u_max]``. The rest of tank
``i-1``'s outflow, ``(1 - c) a' sqrt(h_{i-1})``, leaves the train; the last tank's leaves
entirely. ``c = 0`` gives ``n`` independent tanks of :mod:`plants.tank`.

Equilibrium for levels ``h_i*`` (all of them; ``h_{-1}* = 0``)::

    u_i* = (a' sqrt(h_i*) - c a' sqrt(h_{i-1}*)) / b

which the pump can give only if ``u_min <= u_i* <= u_max``: with ``u_min = 0``, a tank must be
held at ``h_i* >= c^2 h_{i-1}*`` (else the inflow from upstream alone overfills it).

Linearization at ``h > 0`` (lower bidiagonal: the coupling runs downstream only)::

    A[i, i]   = -a' / (2 sqrt(h_i))          (the tank's tangent, as in plants.tank)
    A[i, i-1] =  c a' / (2 sqrt(h_{i-1}))
    B = diag(b)      (0 where the pump is saturated),    C = I

Closed loop with seed 002's non-linear PI on every tank (``controllers.nlpi``, ``K_l = a'/b``):
the law cancels the tank's own outflow, leaving ``dh_i/dt = b (K_i I_i - K_p h_i) + c a'
sqrt(h_{i-1})``, i.e. each loop the designed second order driven by its upstream neighbour's
outflow as an inflow disturbance, which its integral rejects. The closed loop is block lower
triangular, so it is stable when every loop is; the pump saturates at 0 (then the law's
clamping holds its integral) when a downward step asks the level to fall faster than the net
outflow ``a' sqrt(h_i) - c a' sqrt(h_{i-1})`` allows.

Robustness near an empty tank, as :mod:`plants.tank`: ``sqrt(max(h, 0))`` everywhere (an empty
tank sends nothing downstream), and an empty tank cannot drain further (``dh_i/dt = max(inflow,
0)`` for ``h_i <= 0``); :meth:`TankTrain.outputs` reports ``max(h, 0)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from plants.tank import TankParams

if TYPE_CHECKING:
    import control

__all__ = ["TankTrainParams", "TankTrain"]


class TankTrainParams(TankParams):
    """Parameters of the train: seed 002 eq. (3b) per tank and its pump's range
    (:class:`~plants.tank.TankParams`), the number of tanks and the share of each outflow that
    feeds the next tank."""

    n: int = Field(ge=1, description="number of tanks in series (one loop each)")
    c: float = Field(
        ge=0, lt=1, description="share of tank i-1's outflow that flows into tank i, in [0, 1)"
    )


class TankTrain:
    """The train as a plant object: ``rhs``, ``outputs``, ``equilibrium``, ``linearize``."""

    def __init__(self, params: TankTrainParams) -> None:
        self.params = params
        n = params.n
        self.state_names: tuple[str, ...] = tuple(f"h{i}" for i in range(n))
        self.input_names: tuple[str, ...] = tuple(f"u{i}" for i in range(n))
        self.output_names: tuple[str, ...] = self.state_names
        self._n = n
        self._b = params.b
        self._a = params.a_prime
        self._c = params.c
        self._ca = params.c * params.a_prime
        self._u_min = params.u_min
        self._u_max = params.u_max

    # -- dynamics -------------------------------------------------------------------------------
    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """``dh_i/dt`` of every tank (the module's equations) under pump commands ``u``."""
        return np.array(self.rhs_tuple(t, tuple(x.tolist()), tuple(u.tolist())))

    def rhs_tuple(self, t: float, x: Sequence[float], u: Sequence[float]) -> tuple[float, ...]:
        """:meth:`rhs` on plain floats (what the fixed-step integrator calls)."""
        b, a, c, lo, hi = self._b, self._a, self._c, self._u_min, self._u_max
        out: list[float] = []
        upstream = 0.0  # the outflow of the tank before, a' sqrt(h_{i-1}); none for tank 0
        for h, cmd in zip(x, u, strict=True):
            cmd = lo if cmd < lo else (hi if cmd > hi else cmd)
            inflow = b * cmd + c * upstream
            if h > 0.0:
                outflow = a * math.sqrt(h)
                out.append(inflow - outflow)
            else:
                outflow = 0.0
                out.append(inflow if inflow > 0.0 else 0.0)  # empty: cannot drain further
            upstream = outflow
        return tuple(out)

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured levels ``(h0, ..., h{n-1})`` (never below zero)."""
        return np.maximum(np.asarray(x, dtype=float), 0.0)

    # -- equilibrium ----------------------------------------------------------------------------
    def equilibrium(
        self, y_bar: Mapping[str, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """State and inputs that hold every level at ``y_bar`` (the module's closed form).

        Parameters
        ----------
        y_bar : mapping
            ``{"h0": level, ..., "h{n-1}": level}``: every tank's.

        Returns
        -------
        x_bar, u_bar : ndarray
            The levels and ``u_i* = (a' sqrt(h_i*) - c a' sqrt(h_{i-1}*)) / b``.

        Raises
        ------
        ValueError
            If a level is missing or negative, or a pump cannot give its tank's ``u_i*``.
        """
        missing = [name for name in self.output_names if name not in y_bar]
        if missing:
            raise ValueError(f"TankTrain.equilibrium: set points missing for outputs {missing}")
        levels = [float(y_bar[name]) for name in self.output_names]
        for name, h in zip(self.output_names, levels, strict=True):
            if not h >= 0.0:
                raise ValueError(f"TankTrain.equilibrium: level {name}={h} must be >= 0")
        roots = [math.sqrt(h) for h in levels]
        u_bar = []
        for i, root in enumerate(roots):
            upstream = roots[i - 1] if i else 0.0
            u = (self._a * root - self._ca * upstream) / self._b
            if not self._u_min <= u <= self._u_max:
                raise ValueError(
                    f"TankTrain.equilibrium: holding {self.output_names[i]}={levels[i]} needs "
                    f"{self.input_names[i]}={u:.6g}, outside the pump range "
                    f"[{self._u_min}, {self._u_max}]"
                )
            u_bar.append(u)
        return np.array(levels), np.array(u_bar)

    # -- linearization --------------------------------------------------------------------------
    def jacobians(
        self, x: NDArray[np.float64], u: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``A = df/dh`` (lower bidiagonal) and ``B = df/du`` (diagonal) at ``(x, u)``, all
        ``h > 0``; ``B[i, i]`` is ``b`` inside the pump range and 0 where it is saturated."""
        levels = [float(v) for v in x]
        low = [name for name, h in zip(self.state_names, levels, strict=True) if not h > 0.0]
        if low:
            raise ValueError(
                f"TankTrain.linearize: levels {low} must be > 0 (sqrt(h) is not smooth at 0)"
            )
        n = self._n
        A = np.zeros((n, n))
        B = np.zeros((n, n))
        for i, h in enumerate(levels):
            A[i, i] = -self._a / (2.0 * math.sqrt(h))
            if i:
                A[i, i - 1] = self._ca / (2.0 * math.sqrt(levels[i - 1]))
            B[i, i] = self._b if self._u_min <= float(u[i]) <= self._u_max else 0.0
        return A, B

    def linearize(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
        """Small-signal model ``(A, B, C, D)`` at ``(x, u)`` as a ``control.StateSpace``."""
        import control

        A, B = self.jacobians(x, u)
        n = self._n
        return control.ss(
            A, B, np.eye(n), np.zeros((n, n)),
            states=list(self.state_names), inputs=list(self.input_names),
            outputs=list(self.output_names),
        )  # fmt: skip
