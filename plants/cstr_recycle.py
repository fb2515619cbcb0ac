"""Two non-isothermal CSTRs with recycle of seed 001 (Sun & El-Farra), section V.

Three parallel irreversible exothermic reactions ``A -> B``, ``A -> U``, ``A -> R`` take place in
both reactors. CSTR 1 is fed with fresh A (``F0, CA0, T0``) and the recycle from CSTR 2
(``Fr, CA2, T2``); CSTR 2 takes the outflow of CSTR 1 (``F1``) and a fresh stream
(``F3, CA03, T03``). States ``x = (T1, CA1, T2, CA2)``, inputs ``u = (Q1, CA0, Q2, CA03)``
(the manipulated variables of section V: heat inputs and feed concentrations), measured outputs
``y = (T1, T2)``. Time in hours.

Model, seed 001 eq. (10)::

    dT1/dt  = F0/V1 (T0 - T1) + Fr/V1 (T2 - T1) + sum_i G_i(T1) CA1 + Q1 / (rho cp V1)
    dCA1/dt = F0/V1 (CA0 - CA1) + Fr/V1 (CA2 - CA1) - sum_i R_i(T1) CA1
    dT2/dt  = F1/V2 (T1 - T2) + F3/V2 (T03 - T2) + sum_i G_i(T2) CA2 + Q2 / (rho cp V2)
    dCA2/dt = F1/V2 (CA1 - CA2) + F3/V2 (CA03 - CA2) - sum_i R_i(T2) CA2

    R_i(T) = k_i0 exp(-E_i / (R T)),   G_i(T) = (-dH_i) / (rho cp) R_i(T)

Linearized at a steady state it takes the two-unit form of eq. (11)::

    dx1/dt = A1 x1 + B1 u1 + A12 x2,   y1 = C1 x1,    x1 = (T1, CA1), u1 = (Q1, CA0)
    dx2/dt = A2 x2 + B2 u2 + A21 x1,   y2 = C2 x2,    x2 = (T2, CA2), u2 = (Q2, CA03)

(:meth:`CSTRRecycle.two_unit`), in deviation variables and physical units (K, kmol/m^3, kJ/h).
The paper calls its variables dimensionless without giving the scales; a diagonal scaling of
states and inputs is a similarity transformation of the closed loop for every gain design in
:mod:`controllers.qdc.design` (``K_ij`` is unique, ``L_i`` is unique for one measured output, and
the diagonal closed-loop design commutes with diagonal scalings), so it leaves the spectral radius
of the test matrix ``M(h)`` and ``h_max`` unchanged (checked in
``tests/unit/test_update_period.py``).

Parameter values
----------------
The seed takes them from Sun & El-Farra, Comp. & Chem. Eng. 32 (2008) 2016-2029 without printing
them; :data:`PAPER_PARAMS` are the values of public code of that plant. With ``Q1 = Q2 = 0`` and
nominal feed concentrations the plant has three steady states; the open-loop unstable one,
``(457.94284 K, 1.770164, 415.45847 K, 1.752205 kmol/m^3)``, is the operating point of section V
(the paper prints it rounded to ``(457.9, 1.77, 415.5, 1.75)``); its Jacobian eigenvalues are
about ``+32.1, -54.8, -17.2, -8.5 1/h``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field
from scipy.optimize import fsolve

if TYPE_CHECKING:
    import control

__all__ = [
    "CSTRRecycleParams",
    "CSTRRecycle",
    "TwoUnitLinearModel",
    "PAPER_PARAMS",
    "UNIT_STATES",
    "UNIT_INPUTS",
    "UNIT_OUTPUTS",
]

UNIT_STATES: tuple[tuple[int, ...], ...] = ((0, 1), (2, 3))
"""Indices of each reactor's states ``(T_i, CA_i)`` in the plant state vector."""
UNIT_INPUTS: tuple[tuple[int, ...], ...] = ((0, 1), (2, 3))
"""Indices of each reactor's inputs ``(Q_i, CA0 / CA03)`` in the plant input vector."""
UNIT_OUTPUTS: tuple[tuple[int, ...], ...] = ((0,), (1,))
"""Indices of each reactor's measured temperature in the output vector."""


class CSTRRecycleParams(BaseModel):
    """Physical parameters of the two-CSTR plant (seed 001, eq. (10)); units m^3, h, K, kJ, kmol."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    F0: float = Field(gt=0, description="fresh feed flow to CSTR 1, m^3/h")
    F1: float = Field(gt=0, description="flow from CSTR 1 to CSTR 2, m^3/h")
    F3: float = Field(ge=0, description="fresh feed flow to CSTR 2, m^3/h")
    Fr: float = Field(ge=0, description="recycle flow from CSTR 2 to CSTR 1, m^3/h")
    V1: float = Field(gt=0, description="volume of CSTR 1, m^3")
    V2: float = Field(gt=0, description="volume of CSTR 2, m^3")
    R: float = Field(gt=0, description="gas constant, kJ/(kmol K)")
    T0: float = Field(gt=0, description="fresh feed temperature to CSTR 1, K")
    T03: float = Field(gt=0, description="fresh feed temperature to CSTR 2, K")
    CA0s: float = Field(ge=0, description="nominal feed concentration to CSTR 1, kmol/m^3")
    CA03s: float = Field(ge=0, description="nominal feed concentration to CSTR 2, kmol/m^3")
    dH1: float = Field(description="enthalpy of reaction 1, kJ/kmol")
    dH2: float = Field(description="enthalpy of reaction 2, kJ/kmol")
    dH3: float = Field(description="enthalpy of reaction 3, kJ/kmol")
    k10: float = Field(gt=0, description="pre-exponential factor of reaction 1, 1/h")
    k20: float = Field(gt=0, description="pre-exponential factor of reaction 2, 1/h")
    k30: float = Field(gt=0, description="pre-exponential factor of reaction 3, 1/h")
    E1: float = Field(gt=0, description="activation energy of reaction 1, kJ/kmol")
    E2: float = Field(gt=0, description="activation energy of reaction 2, kJ/kmol")
    E3: float = Field(gt=0, description="activation energy of reaction 3, kJ/kmol")
    rho: float = Field(gt=0, description="density, kg/m^3")
    cp: float = Field(gt=0, description="heat capacity, kJ/(kg K)")


PAPER_PARAMS = CSTRRecycleParams(
    F0=4.998, F1=39.996, F3=30.0, Fr=34.998, V1=1.0, V2=3.0, R=8.314,
    T0=300.0, T03=300.0, CA0s=4.0, CA03s=2.0,
    dH1=-5.0e4, dH2=-5.2e4, dH3=-5.4e4,
    k10=3.0e6, k20=3.0e5, k30=3.0e5,
    E1=5.0e4, E2=7.53e4, E3=7.53e4,
    rho=1000.0, cp=0.231,
)  # fmt: skip
"""Sun & El-Farra (2008) values, as used by seed 001 section V."""


@dataclass(frozen=True)
class TwoUnitLinearModel:
    """Linearization in the two-unit form of seed 001 eq. (11) (deviation variables).

    ``A[i][j]`` is ``A_i`` for ``i == j`` and the interconnection ``A_ij`` otherwise; ``B[i]`` and
    ``C[i]`` are ``B_i`` and ``C_i``. Indices are 0-based (unit 0 is CSTR 1).
    """

    A: tuple[tuple[NDArray[np.float64], ...], ...]
    B: tuple[NDArray[np.float64], ...]
    C: tuple[NDArray[np.float64], ...]

    @property
    def A1(self) -> NDArray[np.float64]:  # noqa: N802 - the paper's symbol
        return self.A[0][0]

    @property
    def A2(self) -> NDArray[np.float64]:  # noqa: N802
        return self.A[1][1]

    @property
    def A12(self) -> NDArray[np.float64]:  # noqa: N802
        return self.A[0][1]

    @property
    def A21(self) -> NDArray[np.float64]:  # noqa: N802
        return self.A[1][0]


class CSTRRecycle:
    """The two-CSTR plant: ``rhs``, ``outputs``, steady states, ``linearize``, ``two_unit``."""

    state_names: tuple[str, ...] = ("T1", "CA1", "T2", "CA2")
    input_names: tuple[str, ...] = ("Q1", "CA0", "Q2", "CA03")
    output_names: tuple[str, ...] = ("T1", "T2")
    units: tuple[tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]], ...] = (
        (("T1", "CA1"), ("Q1", "CA0"), ("T1",)),
        (("T2", "CA2"), ("Q2", "CA03"), ("T2",)),
    )
    """The units of eq. (11) by name: ``(states, inputs, outputs)`` of each reactor (the
    decomposition :meth:`two_unit` uses; a networked law designs its local controllers on it)."""

    def __init__(self, params: CSTRRecycleParams = PAPER_PARAMS) -> None:
        self.params = params
        p = params
        self._k0 = (p.k10, p.k20, p.k30)
        self._e_r = (p.E1 / p.R, p.E2 / p.R, p.E3 / p.R)
        rc = p.rho * p.cp
        self._g0 = (-p.dH1 / rc * p.k10, -p.dH2 / rc * p.k20, -p.dH3 / rc * p.k30)
        self._q1 = 1.0 / (rc * p.V1)
        self._q2 = 1.0 / (rc * p.V2)

    # -- kinetics -------------------------------------------------------------------------------
    def _rates(self, temp: float) -> tuple[float, float, float, float]:
        """``sum_i R_i(T)``, ``sum_i G_i(T)`` and their derivatives with respect to ``T``."""
        r = g = dr = dg = 0.0
        for k0, er, g0 in zip(self._k0, self._e_r, self._g0, strict=True):
            ex = math.exp(-er / temp)
            d = er / (temp * temp)
            r += k0 * ex
            g += g0 * ex
            dr += k0 * ex * d
            dg += g0 * ex * d
        return r, g, dr, dg

    # -- dynamics -------------------------------------------------------------------------------
    def nominal_input(self) -> NDArray[np.float64]:
        """``(Q1, CA0, Q2, CA03) = (0, CA0s, 0, CA03s)``, the open-loop input of section V."""
        p = self.params
        return np.array((0.0, p.CA0s, 0.0, p.CA03s))

    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """Seed 001 eq. (10): ``d(T1, CA1, T2, CA2)/dt`` under inputs ``(Q1, CA0, Q2, CA03)``."""
        p = self.params
        t1, ca1, t2, ca2 = x.tolist()
        q1, ca0, q2, ca03 = u.tolist()
        r1, g1, _, _ = self._rates(t1)
        r2, g2, _, _ = self._rates(t2)
        a0, ar, b1, b3 = p.F0 / p.V1, p.Fr / p.V1, p.F1 / p.V2, p.F3 / p.V2
        return np.array(
            (
                a0 * (p.T0 - t1) + ar * (t2 - t1) + g1 * ca1 + q1 * self._q1,
                a0 * (ca0 - ca1) + ar * (ca2 - ca1) - r1 * ca1,
                b1 * (t1 - t2) + b3 * (p.T03 - t2) + g2 * ca2 + q2 * self._q2,
                b1 * (ca1 - ca2) + b3 * (ca03 - ca2) - r2 * ca2,
            )
        )

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured outputs ``(T1, T2)``."""
        return np.array((x[0], x[2]), dtype=float)

    # -- steady states --------------------------------------------------------------------------
    def equilibrium(
        self, guess: NDArray[np.float64] | tuple[float, ...], u: NDArray[np.float64] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Steady state near ``guess`` under input ``u`` (default :meth:`nominal_input`).

        Solves ``rhs(x, u) = 0`` by Newton's method (``scipy.optimize.fsolve`` with the analytic
        Jacobian) to ``|rhs| < 1e-8``.

        Returns
        -------
        x_s, u_s : ndarray
            Steady state ``(T1, CA1, T2, CA2)`` and the input it was computed for.

        Raises
        ------
        ValueError
            If the solver does not converge from ``guess``.
        """
        u_s = self.nominal_input() if u is None else np.asarray(u, dtype=float)
        x0 = np.asarray(guess, dtype=float)

        def f(z: NDArray[np.float64]) -> NDArray[np.float64]:
            return self.rhs(0.0, z, u_s)

        def jac(z: NDArray[np.float64]) -> NDArray[np.float64]:
            return self.jacobians(z, u_s)[0]

        x_s, _info, ier, msg = fsolve(f, x0, fprime=jac, xtol=1e-13, full_output=True)
        if ier != 1 or np.max(np.abs(f(x_s))) > 1e-8:
            raise ValueError(f"CSTRRecycle.equilibrium: no steady state found from {guess}: {msg}")
        return x_s, u_s

    def steady_states(self, u: NDArray[np.float64] | None = None) -> list[NDArray[np.float64]]:
        """All steady states with temperatures in ``[250, 1500] K``, sorted by ``T1``.

        Given the temperatures, the two concentration balances are linear in ``(CA1, CA2)``, so
        the problem reduces to two equations in ``(T1, T2)``; it is solved from a grid of starting
        temperatures and the distinct solutions are kept.
        """
        u_s = self.nominal_input() if u is None else np.asarray(u, dtype=float)
        p = self.params
        a0, ar, b1, b3 = p.F0 / p.V1, p.Fr / p.V1, p.F1 / p.V2, p.F3 / p.V2

        def reduced(z: NDArray[np.float64]) -> NDArray[np.float64]:
            t1, t2 = (min(max(float(v), 100.0), 2000.0) for v in z)
            ca1, ca2 = self._concentrations(t1, t2, u_s)
            g1, g2 = self._rates(t1)[1], self._rates(t2)[1]
            return np.array(
                (
                    a0 * (p.T0 - t1) + ar * (t2 - t1) + g1 * ca1 + u_s[0] * self._q1,
                    b1 * (t1 - t2) + b3 * (p.T03 - t2) + g2 * ca2 + u_s[2] * self._q2,
                )
            )

        found: list[NDArray[np.float64]] = []
        for t1 in np.linspace(300.0, 1100.0, 17):
            for t2 in np.linspace(300.0, 1100.0, 17):
                z, _info, ier, _msg = fsolve(reduced, (t1, t2), xtol=1e-12, full_output=True)
                if ier != 1 or not (250.0 <= z[0] <= 1500.0 and 250.0 <= z[1] <= 1500.0):
                    continue
                ca1, ca2 = self._concentrations(float(z[0]), float(z[1]), u_s)
                try:
                    x_s, _ = self.equilibrium((z[0], ca1, z[1], ca2), u_s)
                except ValueError:
                    continue
                if all(np.max(np.abs(x_s - y) / (1.0 + np.abs(y))) > 1e-6 for y in found):
                    found.append(x_s)
        return sorted(found, key=lambda z: float(z[0]))

    def _concentrations(self, t1: float, t2: float, u: NDArray[np.float64]) -> tuple[float, float]:
        """Steady ``(CA1, CA2)`` for given temperatures (linear balances of eq. (10))."""
        p = self.params
        r1 = self._rates(t1)[0]
        r2 = self._rates(t2)[0]
        m = np.array(
            [
                [(p.F0 + p.Fr) / p.V1 + r1, -p.Fr / p.V1],
                [-p.F1 / p.V2, (p.F1 + p.F3) / p.V2 + r2],
            ]
        )
        rhs = np.array([p.F0 / p.V1 * u[1], p.F3 / p.V2 * u[3]])
        ca1, ca2 = np.linalg.solve(m, rhs)
        return float(ca1), float(ca2)

    def unstable_steady_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The open-loop unstable steady state of section V (``Q1 = Q2 = 0``, nominal feeds)."""
        return self.equilibrium((457.9, 1.77, 415.5, 1.75))

    def operating_point(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The point a controller designed on the linearization regulates to: for this plant the
        unstable steady state of section V (:meth:`unstable_steady_state`)."""
        return self.unstable_steady_state()

    # -- linearization --------------------------------------------------------------------------
    def jacobians(
        self, x: NDArray[np.float64], u: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Analytic ``A = df/dx`` (4x4) and ``B = df/du`` (4x4) of eq. (10) at ``(x, u)``."""
        p = self.params
        t1, ca1, t2, ca2 = (float(v) for v in x)
        r1, g1, dr1, dg1 = self._rates(t1)
        r2, g2, dr2, dg2 = self._rates(t2)
        a0, ar, b1, b3 = p.F0 / p.V1, p.Fr / p.V1, p.F1 / p.V2, p.F3 / p.V2
        A = np.array(
            [
                [-a0 - ar + dg1 * ca1, g1, ar, 0.0],
                [-dr1 * ca1, -a0 - ar - r1, 0.0, ar],
                [b1, 0.0, -b1 - b3 + dg2 * ca2, g2],
                [0.0, b1, -dr2 * ca2, -b1 - b3 - r2],
            ]
        )
        B = np.diag([self._q1, a0, self._q2, b3])
        return A, B

    def output_matrix(self) -> NDArray[np.float64]:
        """``C`` with ``y = (T1, T2) = C x``."""
        C = np.zeros((2, 4))
        C[0, 0] = C[1, 2] = 1.0
        return C

    def linearize(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
        """Small-signal model ``(A, B, C, D)`` at ``(x, u)`` as a ``control.StateSpace``."""
        import control

        A, B = self.jacobians(x, u)
        return control.ss(
            A, B, self.output_matrix(), np.zeros((2, 4)),
            states=list(self.state_names), inputs=list(self.input_names),
            outputs=list(self.output_names),
        )  # fmt: skip

    def two_unit(self, x: NDArray[np.float64], u: NDArray[np.float64]) -> TwoUnitLinearModel:
        """Blocks ``A_i, A_ij, B_i, C_i`` of seed 001 eq. (11) at ``(x, u)``."""
        A, B = self.jacobians(x, u)
        C = self.output_matrix()
        blocks = tuple(tuple(A[np.ix_(si, sj)].copy() for sj in UNIT_STATES) for si in UNIT_STATES)
        b = tuple(B[np.ix_(si, ui)].copy() for si, ui in zip(UNIT_STATES, UNIT_INPUTS, strict=True))
        c = tuple(
            C[np.ix_(yi, si)].copy() for si, yi in zip(UNIT_STATES, UNIT_OUTPUTS, strict=True)
        )
        return TwoUnitLinearModel(A=blocks, B=b, C=c)
