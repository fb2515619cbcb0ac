"""Jacketed continuous stirred-tank reactor (JCSTR) of seed 000 (Taylor & Ibrahim), section III.

States ``x = (H, T, T_j)`` (mixture level, mixture temperature, jacket temperature), control inputs
``u = (F_out, F_jin)`` (mixture outflow, jacket inflow), exogenous inputs ``F_in, T_in, T_jin``
held constant as parameters, outputs ``y = (H, T)``.

Model, seed 000 eq. (1) written out as eq. (4)::

    dH/dt   = (F_in - F_out) / A_B
    dT/dt   = F_in (T_in - T) / (A_B H) + U A_H (T_j - T) / (rho C_p A_B H)
    dT_j/dt = F_jin (T_jin - T_j) / V_j - U A_H (T_j - T) / (rho C_p V_j)
    A_H     = A_B + pi D H

Equilibrium for set points ``(H_bar, T_bar)``, seed 000 eq. (5)-(7), with ``alpha = U/(rho C_p)``::

    u1_bar = F_in
    x3_bar = T_bar + F_in (T_bar - T_in) / (alpha (A_B + pi D H_bar))      (6)
    u2_bar = F_in (T_bar - T_in) / (T_jin - x3_bar)                        (7)

Parameter values
----------------
The paper's values are in an internal memo (its ref. [9]) that is not public. The values in
:data:`BENCHMARK_PARAMS` (mirroring ``scenarios/jcstr_benchmark.yaml``, which is what runs) are
**ours**: per-unit level and time as the paper uses, temperatures in degrees C::

    A_B  = 1.0 pu^2          D     = 2 sqrt(A_B / pi) = 1.1284 pu   (circular base of area A_B)
    U    = 0.1713            rho   = C_p = 1.0                      (per-unit)
    V_j  = 0.126 pu^3        F_in  = 9.69 pu^3/pu
    T_in = 46.4 C            T_jin = 298.0 C

How they were found (``bench/calibrate_jcstr.py`` reproduces the search; the README section "The
JCSTR calibration" has the numbers): ``U`` follows from eq. (6) so that the paper's initial jacket
temperature ``x30 = 143 C`` is the equilibrium jacket temperature at the first set points
(0.70 pu, 52 C); ``F_in``, ``T_in``, ``V_j`` and ``T_jin`` were fitted by Nelder-Mead together
with the temperature PI gains to the overshoots of section III.C (benchmark 11.0 %, 28.5 % at
``tau_s = 0.3`` pu, the temperature delay limit, point A of section III.E), inside a plausibility
box. The level loop depends only on ``Kp/A_B`` and ``Ki/A_B``; those gains were solved for the
level figures (10.8 % at the benchmark, 24.9 % at ``tau_s = 0.25`` pu). The gains live in the
scenario: level ``Kp = -4.376``, ``Ki = -2.530``; temperature ``Kp = 0.05929``, ``Ki = 0.2366``;
both PI laws integrate by backward Euler, which fits the paper better than forward Euler.

Consequences of these values: the mixture residence time ``A_B H / F_in`` is about 0.07 pu and
the thermal time constants are 0.065-0.14 pu, fast compared with the sampling periods; the
steady-state feedforward makes most of a set-point change and the PI trims it. At the benchmark
set points the equilibrium jacket temperature is 139-204 C, below ``T_jin``; in the benchmark run
``F_jin`` stays within 0.33-1.32 (limits 0-5) and ``F_out`` within 9.46-9.69 (limits 0-19).

Notes
-----
``U``, ``rho`` and ``C_p`` enter the model only through ``alpha = U / (rho C_p)`` (the jacket
fluid is taken with the mixture's ``rho C_p``, as eq. (1) prints it).

For robustness the temperature equation uses ``max(H, H_MIN)`` in its denominators, and the
tank cannot drain below empty: a documented guard, inactive in every scenario we ship.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

if TYPE_CHECKING:
    import control

__all__ = ["JCSTRParams", "JCSTR", "BENCHMARK_PARAMS", "H_MIN"]

H_MIN = 1e-3
"""Smallest level (pu) used in the temperature equation's denominators."""


class JCSTRParams(BaseModel):
    """Physical parameters of the JCSTR, by the paper's symbol names (seed 000, eq. (1))."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    A_B: float = Field(gt=0, description="area of the tank base, pu^2 (level in pu)")
    D: float = Field(gt=0, description="diameter of the tank base, pu")
    U: float = Field(gt=0, description="overall heat-transfer coefficient, per-unit")
    rho: float = Field(gt=0, description="mixture density, per-unit")
    C_p: float = Field(gt=0, description="mixture heat capacity, per-unit")
    V_j: float = Field(gt=0, description="jacket fluid volume, pu^3")
    F_in: float = Field(ge=0, description="mixture inflow (exogenous), pu^3/pu time")
    T_in: float = Field(description="mixture feed temperature (exogenous), degC")
    T_jin: float = Field(description="jacket inflow temperature (exogenous), degC")


class JCSTR:
    """The JCSTR as a plant object: ``rhs``, ``outputs``, ``equilibrium``, ``linearize``."""

    state_names: tuple[str, ...] = ("H", "T", "T_j")
    input_names: tuple[str, ...] = ("F_out", "F_jin")
    output_names: tuple[str, ...] = ("H", "T")

    def __init__(self, params: JCSTRParams) -> None:
        self.params = params
        p = params
        self._alpha = p.U / (p.rho * p.C_p)
        self._pi_d = math.pi * p.D

    # -- dynamics -------------------------------------------------------------------------------
    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """Seed 000 eq. (4): time derivative of ``(H, T, T_j)`` under inputs ``(F_out, F_jin)``."""
        return np.array(self.rhs_tuple(t, tuple(x.tolist()), tuple(u.tolist())))

    def rhs_tuple(
        self, t: float, x: Sequence[float], u: Sequence[float]
    ) -> tuple[float, float, float]:
        """:meth:`rhs` on plain floats (what the fixed-step integrator calls)."""
        p = self.params
        h, temp, temp_j = x
        f_out, f_jin = u
        dh = (p.F_in - f_out) / p.A_B
        if h <= 0.0 and dh < 0.0:
            dh = 0.0  # an empty tank cannot drain further
        h_eff = h if h > H_MIN else H_MIN
        q = self._alpha * (p.A_B + self._pi_d * h_eff) * (temp_j - temp)  # U A_H (Tj-T)/(rho Cp)
        d_temp = (p.F_in * (p.T_in - temp) + q) / (p.A_B * h_eff)
        d_temp_j = (f_jin * (p.T_jin - temp_j) - q) / p.V_j
        return (dh, d_temp, d_temp_j)

    def batch_params(self) -> tuple[float, ...]:
        """The constants :meth:`rhs_batch` takes, one value each."""
        p = self.params
        return (p.F_in, p.A_B, self._alpha, self._pi_d, p.T_in, p.T_jin, p.V_j)

    @staticmethod
    def rhs_batch(
        p: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]],
        u: Sequence[NDArray[np.float64]],
    ) -> tuple[NDArray[np.float64], ...]:
        """:meth:`rhs_tuple` on many plants at once: ``p`` (:meth:`batch_params`), ``x`` and
        ``u`` hold one array per constant, state and input, one element per plant. The same
        operations in the same order, element by element (IEEE float64), so each element is
        bit-identical to :meth:`rhs_tuple` (the agent's batched checks,
        ``agents/wncsca/batch.py``)."""
        return JCSTR.rhs_batch_held(p, x, JCSTR.rhs_batch_inputs(p, u))

    @staticmethod
    def rhs_batch_inputs(
        p: Sequence[NDArray[np.float64]],
        u: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]] | None = None,
        span: NDArray[np.float64] | None = None,
    ) -> tuple[Any, ...]:
        """What :meth:`rhs_batch` computes from the inputs alone, once for a segment they hold
        (the RK4 steps call :meth:`rhs_batch_held` with it): ``dh`` (the level's derivative
        while the tank holds liquid), ``F_jin`` and whether a level may come down to ``H_MIN``
        within ``span`` from ``x`` (without ``x``: assumed). While it holds liquid the level
        moves at ``dh`` alone, so over ``span`` it stays above ``h + span * min(dh, 0)``; twice
        that margin above ``H_MIN`` rules out, for the segment, the empty-tank clamp and the
        ``H_MIN`` floor (``max(h, H_MIN)`` is then ``h``)."""
        f_in, a_b = p[0], p[1]
        f_out, f_jin = u
        dh = (f_in - f_out) / a_b
        low = True
        if x is not None and span is not None:
            low = not np.fmin.reduce(x[0] + 2.0 * span * np.minimum(dh, 0.0)) > H_MIN + 1e-9
        return (dh, f_jin, low)

    @staticmethod
    def rhs_batch_held(
        p: Sequence[NDArray[np.float64]],
        x: Sequence[NDArray[np.float64]],
        held: tuple[Any, ...],
    ) -> tuple[NDArray[np.float64], ...]:
        """:meth:`rhs_batch` with the inputs' terms of :meth:`rhs_batch_inputs`."""
        f_in, a_b, alpha, pi_d, t_in, t_jin, v_j = p
        h, temp, temp_j = x
        dh, f_jin, low = held
        h_eff = h  # every level above H_MIN (a NaN level stays NaN either way)
        if low:
            if np.fmin.reduce(h) <= 0.0:  # some h <= 0 (fmin skips NaN)
                dh = np.where((h <= 0.0) & (dh < 0.0), 0.0, dh)
            h_eff = np.maximum(h, H_MIN)  # rhs_tuple's choice for every non-NaN level
        q = alpha * (a_b + pi_d * h_eff) * (temp_j - temp)
        d_temp = (f_in * (t_in - temp) + q) / (a_b * h_eff)
        d_temp_j = (f_jin * (t_jin - temp_j) - q) / v_j
        return (dh, d_temp, d_temp_j)

    @staticmethod
    def outputs_batch(x: Sequence[NDArray[np.float64]]) -> tuple[NDArray[np.float64], ...]:
        """:meth:`outputs` of many plants at once (one array per state)."""
        return (x[0], x[1])

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured outputs ``(H, T)``."""
        return np.array((x[0], x[1]), dtype=float)

    # -- equilibrium ----------------------------------------------------------------------------
    def equilibrium(
        self, y_bar: Mapping[str, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """State and input that hold the outputs at ``y_bar`` (seed 000, eq. (5)-(7)).

        Parameters
        ----------
        y_bar : mapping
            Set points by output name: ``{"H": ..., "T": ...}``.

        Returns
        -------
        x_bar, u_bar : ndarray
            ``(H, T, T_j)`` and ``(F_out, F_jin)``.

        Raises
        ------
        ValueError
            If an output is missing or no positive jacket flow can hold the temperature.
        """
        missing = [n for n in self.output_names if n not in y_bar]
        if missing:
            raise ValueError(f"JCSTR.equilibrium: set points missing for outputs {missing}")
        p = self.params
        h_bar, t_bar = float(y_bar["H"]), float(y_bar["T"])
        x3 = t_bar + p.F_in * (t_bar - p.T_in) / (self._alpha * (p.A_B + self._pi_d * h_bar))
        if p.T_jin <= x3:
            raise ValueError(
                f"JCSTR.equilibrium: jacket inlet T_jin={p.T_jin} must exceed the required jacket "
                f"temperature {x3:.3f} to hold T={t_bar}"
            )
        u2 = p.F_in * (t_bar - p.T_in) / (p.T_jin - x3)
        return np.array((h_bar, t_bar, x3)), np.array((p.F_in, u2))

    # -- linearization --------------------------------------------------------------------------
    def jacobians(
        self, x: NDArray[np.float64], u: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Analytic ``A = df/dx`` and ``B = df/du`` of eq. (4) at ``(x, u)`` (for ``H > H_MIN``)."""
        p = self.params
        h, temp, temp_j = (float(v) for v in x)
        f_jin = float(u[1])
        a, pd = self._alpha, self._pi_d
        area = p.A_B + pd * h
        dtemp = temp_j - temp
        num = p.F_in * (p.T_in - temp) + a * area * dtemp  # d(T)/dt * A_B h
        A = np.zeros((3, 3))
        # dT/dt = num / (A_B h)
        A[1, 0] = (a * pd * dtemp) / (p.A_B * h) - num / (p.A_B * h * h)
        A[1, 1] = (-p.F_in - a * area) / (p.A_B * h)
        A[1, 2] = a * area / (p.A_B * h)
        # dTj/dt = (F_jin (T_jin - Tj) - a area dtemp) / V_j
        A[2, 0] = -a * pd * dtemp / p.V_j
        A[2, 1] = a * area / p.V_j
        A[2, 2] = (-f_jin - a * area) / p.V_j
        B = np.zeros((3, 2))
        B[0, 0] = -1.0 / p.A_B
        B[2, 1] = (p.T_jin - temp_j) / p.V_j
        return A, B

    def linearize(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
        """Small-signal model ``(A, B, C, D)`` at ``(x, u)`` as a ``control.StateSpace``."""
        import control

        A, B = self.jacobians(x, u)
        C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        return control.ss(
            A,
            B,
            C,
            np.zeros((2, 2)),
            states=list(self.state_names),
            inputs=list(self.input_names),
            outputs=list(self.output_names),
        )


BENCHMARK_PARAMS = JCSTRParams(
    A_B=1.0,
    D=1.1283791670955126,
    U=0.1713,
    rho=1.0,
    C_p=1.0,
    V_j=0.126,
    F_in=9.69,
    T_in=46.4,
    T_jin=298.0,
)
"""Our per-unit parameter set for the seed 000 benchmark (see "Parameter values" above)."""
