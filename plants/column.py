"""Pseudo-binary distillation column of seed 003 (LPG / naphtha stabilizer), appendix C.

Reflux ``L`` and boilup ``V`` are the inputs (L-V structure, section 3.4), the light-key liquid
mole fractions ``x_1 ... x_16`` the states, the top and bottom compositions ``(x_D, x_B) =
(x_16, x_1)`` the outputs. Stages are numbered from the bottom (assumption 7 of C.4): ``n = 1``
reboiler, ``n = 2 ... 15`` the 14 theoretical trays ("tray 1 ... tray 14"), ``n = 16`` the total
condenser and reflux drum. The feed enters at "tray 7" (``n = f = 8``): its liquid part on stage
``f``, its vapour part on stage ``f + 1``. Time in hours, flows in kmol/h, holdups in kmol.

Model (constant relative volatility, constant holdups, constant molar overflow; eq. C.27-C.35
written as the component balance C.5 of each stage, which is what the per-tray list of C.6 prints)::

    y_n = alpha x_n / (1 + (alpha - 1) x_n)                                    (C.27)
    M_D dx_16/dt = (V + V_F) y_15 - (L + D) x_16                              (C.28) condenser
    M   dx_n/dt  = (V + V_F)(y_n-1 - y_n) + L (x_n+1 - x_n),  n = f+2..15     (C.29)
    M   dx_9/dt  = V y_8 + V_F y_F - (V + V_F) y_9 + L (x_10 - x_9)           (C.30) n = f+1
    M   dx_8/dt  = V (y_7 - y_8) + L x_9 + L_F x_F - (L + L_F) x_8            (C.31) n = f
    M   dx_n/dt  = V (y_n-1 - y_n) + (L + L_F)(x_n+1 - x_n),  n = 2..f-1       (C.32)
    M_B dx_1/dt  = (L + L_F) x_2 - V y_1 - B x_1                              (C.33) reboiler
    D = V + V_F - L,   B = L + L_F - V,   y_F = alpha x_F / (1 + (alpha-1) x_F)  (C.34-C.35)

Misprints and inconsistencies of the thesis (all checked in ``tests/unit/test_column.py``)
-----------------------------------------------------------------------------------------
* **C.30 and C.31** print ``(V + V_F)(y_n-1 - y_n) + L (x_n+1 - x_n)`` for *both* stages next to
  the feed, plus the feed term. That does not conserve mass (stage ``f`` receives vapour ``V``
  from below and sends ``L + L_F`` down). The per-tray list of C.6 has the balances right; we
  implement those (above).
* **Eq. (3.3) = (C.42)**, the numeric model, does not follow from the appendix's own flows
  ``L = 75.6380, V = 66.1139, L_F = 104.2491, V_F = 98.5152, x_F = 0.2609, y_F = 0.6672``:

  ===================  ==============================  =====================================
  line                 printed                         from C.28-C.33 with those flows
  ===================  ==============================  =====================================
  condenser, x_16      ``-(75.6380 + 92.7597) x_16``   ``-(L + D) x_16 = -164.6291 x_16``
                       (``L + D = 168.3977``)          (total condenser: ``L + D = V + V_F``)
  n = 9, y_9           ``-156.38 y_9``                 ``-(V + V_F) y_9 = -164.6291 y_9``
  n = 9, constant      ``+59.95``                      ``V_F y_F = 65.7306``
  n = 8, x_8           ``-188.59 x_8``                 ``-(L + L_F) x_8 = -179.8871 x_8``
  n = 8, constant      ``+33.99``                      ``L_F x_F = 27.1986``
  reboiler, B          ``110.9235``                    ``L + L_F - V = 113.7732``
  ===================  ==============================  =====================================

  and the printed ``D + B = 203.6832`` is not the feed ``F = L_F + V_F = 202.7643``.
  :func:`printed_model_rhs` is eq. (3.3) exactly as printed.
* Other numbers of appendix C: ``M_D = 5 (75.30 + 82.15) / 60`` is 13.12, not the 14.03 printed
  (14.03 is ``5 (L + D) / 60`` with the printed ``L + D = 168.40``); the "average vapour flow"
  ``(66.8871 + V_f) / 2 = 66.3407`` is not the ``V = 66.1139`` used.
* **Table 3.2 is reproduced by none of the printed sets** (maximum deviation over the 16 liquid
  compositions): eq. (3.3) as printed 0.157; the appendix flows in the consistent model 0.168;
  the appendix flows with the printed ``D, B`` 0.077. Keeping the printed feed and fitting the two
  inputs by least squares to the 16 compositions gives :data:`FITTED_PARAMS`, ``L = 75.5822``,
  ``V = 69.7855`` (maximum deviation 0.0035, at ``x_16``: a total condenser has ``x_16 = y_15``
  at steady state while the table has ``x_16 = 0.9851 < y_15 = 0.9880``). The fitted flows
  agree with the thesis's other numbers: they give ``D = 92.7185`` (printed ``D = 92.7597``,
  0.04 % off; ``L = 75.6380`` with the printed ``D`` gives ``V = 69.8825``), and the
  sub-diagonal of the appendix E Jacobian (``K_n V / M``) is 5 % above the value for
  ``V = 66.1139`` on every stripping stage, i.e. it was computed with ``V`` of about 69.4.
  :data:`THESIS_PARAMS` keeps the appendix flows as printed.
* Appendix E: ``M_16`` is printed as ``M_B = 24.88`` but the matrix uses ``M_D = 14.03``
  (``a_16,16 = -168.40 / 14.03 = -12.0``); the input vector is printed ``u = [dx_1 ... dx_16]``
  (it is ``(dL, dV)``); its ``B`` treats ``D`` and ``B`` as constant (``b_16,1 = -x_16/M_D``)
  although ``D = V + V_F - L``; its outputs are ordered ``(x_B, x_D)``.

The reduced model of section 4.3 (:func:`balanced_reduction`)
--------------------------------------------------------------
The thesis's ``A_m, B_m, C_m`` (:data:`THESIS_A_M` ...) are reproduced to all printed digits by
**balanced residualization** (singular perturbation, MATLAB ``modred`` default ``'MatchDC'``) of
the appendix E matrices (:data:`APPENDIX_E_A` ...), not by the truncation ``modred(sysb, 3:16,
'del')`` that the text prints: truncation gives eigenvalues ``(-9.845, -0.499)`` instead of
``(-6.5832, -0.4606)``. The Hankel singular values of the appendix E model, ``(4.734e-3,
1.587e-3)``, equal the Gramians of ``(A_m, B_m, C_m)``, which is balanced. The consistent model
here, linearized at :data:`FITTED_PARAMS`, has Hankel singular values ``(4.82e-3, 1.23e-3)`` but
reduced eigenvalues ``(-0.915, -0.328)`` (residualized; truncated ``(-0.879, -0.299)``), near its
slowest full-order ones ``(-0.914, -0.329)`` (see ``bench/mrac_study.py``): the
appendix E Jacobian is not the Jacobian of the appendix's model (condenser and reboiler inputs,
``a_11 = -23.0`` where its own formula gives -18.1), so the thesis's reduction cannot be
reproduced from a consistent linearization. python-control's ``balred`` needs slycot, which is not
installed; :func:`balanced_reduction` is the square-root method with SciPy (``balred`` is used in
the tests for a cross-check when slycot is present).

The plant of section 6.3.1 (:class:`PerturbedReducedPlant`)
-------------------------------------------------------------
The thesis's test plant is ``(A_m, B_m, C_m)`` with each element moved by ``+-`` half its spread
(``a11 = -6.7941 + 0.67 (rand() % 2 - 0.5)`` ...), stepped by forward Euler, eq. (5.1). The C++
program builds a new plant object at *every* step (Fig. 6.11 prints "Plant model has been created
with random parameters" between samples), and this is the "random disturbance" of appendix G:
the plant re-drawn at every step reproduces Table G.1 to within its rounding
(:data:`APPENDIX_G_SIGNS`, found by trying the 256 sign patterns of ``A, B`` at each step; median
one-step residual 2.3e-6 against 1.1e-4 for noise-perturbed data).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.integrate import solve_ivp
from scipy.linalg import null_space, solve_continuous_lyapunov
from scipy.optimize import fsolve

if TYPE_CHECKING:
    import control

__all__ = [
    "ColumnParams",
    "Column",
    "THESIS_PARAMS",
    "FITTED_PARAMS",
    "TABLE_3_2_X",
    "TABLE_3_2_Y",
    "printed_model_rhs",
    "APPENDIX_E_A",
    "APPENDIX_E_B",
    "APPENDIX_E_C",
    "THESIS_A_M",
    "THESIS_B_M",
    "THESIS_C_M",
    "ReducedModel",
    "balanced_reduction",
    "SECTION_631_SPREAD",
    "PerturbedReducedPlant",
    "APPENDIX_G_SIGNS",
    "appendix_g_signs",
]

Array = NDArray[np.float64]

TABLE_3_2_X: tuple[float, ...] = (
    0.0111, 0.0303, 0.0666, 0.1196, 0.1765, 0.2203, 0.2461, 0.2591,
    0.2715, 0.2993, 0.3637, 0.4889, 0.6665, 0.8319, 0.9354, 0.9851,
)  # fmt: skip
"""Table 3.2: steady-state liquid compositions ``x_1 ... x_16`` (reboiler to condenser)."""
TABLE_3_2_Y: tuple[float, ...] = (
    0.0599, 0.1507, 0.2884, 0.4355, 0.5490, 0.6161, 0.6496, 0.6651,
    0.6792, 0.7081, 0.7645, 0.8446, 0.9190, 0.9656, 0.9880, 0.9974,
)  # fmt: skip
"""Table 3.2: the vapour compositions (``y = VLE(x)`` to 6e-5)."""


class ColumnParams(BaseModel):
    """Data of the column (seed 003, appendix C.5-C.6), by the thesis's symbols.

    ``L`` and ``V`` are the nominal inputs (the operating point); the plant takes its inputs as
    absolute flows, not deviations.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    alpha: float = Field(gt=1.0, description="relative volatility (C.27)")
    n_stages: int = Field(default=16, ge=4, description="stages incl. reboiler and condenser")
    feed_stage: int = Field(
        default=8, ge=2, description="stage n = f receiving the liquid feed (vapour on f + 1)"
    )
    M_D: float = Field(gt=0, description="condenser / reflux drum holdup, kmol")
    M: float = Field(gt=0, description="holdup of each tray, kmol")
    M_B: float = Field(gt=0, description="reboiler / column base holdup, kmol")
    L_F: float = Field(ge=0, description="liquid part of the feed, kmol/h")
    V_F: float = Field(ge=0, description="vapour part of the feed, kmol/h")
    x_F: float = Field(gt=0, lt=1, description="light-key fraction of the liquid feed (C.34)")
    L: float = Field(gt=0, description="nominal reflux, kmol/h")
    V: float = Field(gt=0, description="nominal boilup, kmol/h")

    @model_validator(mode="after")
    def _consistent(self) -> ColumnParams:
        if not self.feed_stage <= self.n_stages - 2:
            raise ValueError(
                f"feed_stage ({self.feed_stage}) must leave a tray above it: "
                f"at most n_stages - 2 = {self.n_stages - 2}"
            )
        d = self.V + self.V_F - self.L
        b = self.L + self.L_F - self.V
        if d <= 0:
            raise ValueError(f"L and V: distillate D = V + V_F - L = {d:.4g} must be positive")
        if b <= 0:
            raise ValueError(f"L and V: bottoms B = L + L_F - V = {b:.4g} must be positive")
        return self

    @property
    def y_F(self) -> float:
        """Vapour composition of the feed, the flash equation (C.35)."""
        return self.alpha * self.x_F / (1.0 + (self.alpha - 1.0) * self.x_F)

    @property
    def F(self) -> float:
        """Feed rate ``L_F + V_F``, kmol/h."""
        return self.L_F + self.V_F


_FEED = dict(alpha=5.68, M_D=14.03, M=5.80, M_B=24.88, L_F=104.2491, V_F=98.5152, x_F=0.2609)

THESIS_PARAMS = ColumnParams(**_FEED, L=75.6380, V=66.1139)
"""Appendix C.6 as printed (its ``D = 92.7597, B = 110.9235`` are not used: C.28/C.33 with
constant molar overflow fix ``D = V + V_F - L = 88.9911`` and ``B = L + L_F - V = 113.7732``).
Its steady state misses Table 3.2 by up to 0.168."""

FITTED_PARAMS = ColumnParams(**_FEED, L=75.5822, V=69.7855)
"""Printed feed and holdups, ``L, V`` fitted by least squares to Table 3.2 (max. deviation
0.0035): the nominal operating point. ``D = 92.7185, B = 110.0458``."""


def _vle(alpha: float, x: Array) -> Array:
    return alpha * x / (1.0 + (alpha - 1.0) * x)


def printed_model_rhs(t: float, x: Array, u: Array | None = None) -> Array:
    """Eq. (3.3) = (C.42) exactly as printed (its inputs are frozen in its coefficients).

    Kept to show what the printed numbers give; ``u`` is ignored.
    """
    y = _vle(5.68, np.asarray(x, dtype=float))
    dx = np.empty(16)
    dx[15] = (164.6291 * y[14] - 75.6380 * x[15] - 92.7597 * x[15]) / 14.03
    dx[9:15] = (164.6291 * (y[8:14] - y[9:15]) + 75.6380 * (x[10:16] - x[9:15])) / 5.8
    dx[8] = (66.1139 * y[7] - 156.38 * y[8] + 75.6380 * (x[9] - x[8]) + 59.95) / 5.8
    dx[7] = (66.1139 * (y[6] - y[7]) + 75.6380 * x[8] - 188.59 * x[7] + 33.99) / 5.8
    dx[1:7] = (66.1139 * (y[0:6] - y[1:7]) + 179.8871 * (x[2:8] - x[1:7])) / 5.8
    dx[0] = (179.8871 * x[1] - 110.9235 * x[0] - 66.1139 * y[0]) / 24.88
    return dx


class Column:
    """The column as a plant object: ``rhs``, ``outputs``, ``steady_state``, ``equilibrium``,
    ``jacobian``, ``linearize``.

    Parameters
    ----------
    params : ColumnParams
        Column data; defaults to :data:`FITTED_PARAMS` (the operating point of Table 3.2).
    """

    input_names: tuple[str, ...] = ("L", "V")
    output_names: tuple[str, ...] = ("x_D", "x_B")

    def __init__(self, params: ColumnParams = FITTED_PARAMS) -> None:
        self.params = p = params
        n, f = p.n_stages, p.feed_stage
        self.n = n
        self.state_names: tuple[str, ...] = tuple(f"x{i}" for i in range(1, n + 1))
        stage = np.arange(1, n + 1)
        # Each stage flow = coefficient_L * L + coefficient_V * V + constant (CMO, C.4).
        tray = (stage >= 2) & (stage <= n - 1)
        below = stage <= f  # stages whose vapour leaving is V (reboiler .. feed tray)
        # vapour leaving stage n (the condenser sends none)
        self._vo_V = np.where(stage <= n - 1, 1.0, 0.0)
        self._vo_0 = np.where((stage > f) & (stage <= n - 1), p.V_F, 0.0)
        # liquid leaving stage n: reboiler B = L + L_F - V; trays 2..f L + L_F; trays f+1..n-1 L;
        # condenser L + D = V + V_F
        self._lo_L = np.where(stage <= n - 1, 1.0, 0.0)
        self._lo_V = np.where(stage == 1, -1.0, np.where(stage == n, 1.0, 0.0))
        self._lo_0 = np.where(stage <= f, p.L_F, 0.0) + np.where(stage == n, p.V_F, 0.0)
        # liquid entering stage n from n + 1 (the liquid leaving n + 1 downwards): stages 1..n-1
        self._li_L = np.where(stage <= n - 1, 1.0, 0.0)
        self._li_0 = np.where(stage <= f - 1, p.L_F, 0.0)
        self._feed = np.zeros(n)
        self._feed[f - 1] = p.L_F * p.x_F
        self._feed[f] = p.V_F * p.y_F
        self._hold = np.where(stage == 1, p.M_B, np.where(stage == n, p.M_D, p.M))
        self._inv_hold = 1.0 / self._hold
        del tray, below

    # -- dynamics -------------------------------------------------------------------------------
    def flows(self, u: Sequence[float] | Array) -> dict[str, float]:
        """Internal flows at inputs ``u = (L, V)``: ``D, B`` and the section flows."""
        p = self.params
        lr, vb = float(u[0]), float(u[1])
        return {
            "D": vb + p.V_F - lr,
            "B": lr + p.L_F - vb,
            "L_rect": lr,
            "V_rect": vb + p.V_F,
            "L_strip": lr + p.L_F,
            "V_strip": vb,
        }

    def _stage_flows(self, u: Array) -> tuple[Array, Array, Array]:
        lr, vb = float(u[0]), float(u[1])
        v_out = self._vo_V * vb + self._vo_0
        l_out = self._lo_L * lr + self._lo_V * vb + self._lo_0
        l_in = self._li_L * lr + self._li_0
        return v_out, l_out, l_in

    def rhs(self, t: float, x: Array, u: Array) -> Array:
        """Eq. (C.28)-(C.33): time derivative of ``x_1 ... x_N`` at inputs ``u = (L, V)``."""
        a = self.params.alpha
        y = a * x / (1.0 + (a - 1.0) * x)
        v_out, l_out, l_in = self._stage_flows(u)
        acc = self._feed - v_out * y - l_out * x
        acc[1:] += v_out[:-1] * y[:-1]
        acc[:-1] += l_in[:-1] * x[1:]
        return acc * self._inv_hold

    def outputs(self, x: Array) -> Array:
        """Measured outputs ``(x_D, x_B) = (x_N, x_1)``."""
        return np.array((x[-1], x[0]), dtype=float)

    def jacobian(self, x: Array, u: Array) -> tuple[Array, Array]:
        """Analytic Jacobians ``(df/dx, df/du)`` of :meth:`rhs` (appendix E.1, done consistently).

        ``df/du`` includes the dependence of ``D`` and ``B`` on ``L`` and ``V`` (the thesis's
        appendix E leaves it out).
        """
        a = self.params.alpha
        x = np.asarray(x, dtype=float)
        y = a * x / (1.0 + (a - 1.0) * x)
        k = a / (1.0 + (a - 1.0) * x) ** 2  # dy/dx, the linearized VLE constant K_n
        v_out, l_out, l_in = self._stage_flows(np.asarray(u, dtype=float))
        n = self.n
        jac = np.zeros((n, n))
        idx = np.arange(n)
        jac[idx, idx] = -(v_out * k + l_out)
        jac[idx[1:], idx[:-1]] = v_out[:-1] * k[:-1]
        jac[idx[:-1], idx[1:]] = l_in[:-1]
        jac *= self._inv_hold[:, None]
        bu = np.zeros((n, 2))
        # d/dL: liquid into stages 1..n-1 and out of stages 1..n-1 (condenser: L + D fixed by V)
        bu[:, 0] = -self._lo_L * x
        bu[:-1, 0] += self._li_L[:-1] * x[1:]
        # d/dV: vapour out of stages 1..n-1, into stages 2..n; B falls and L + D rises with V
        bu[:, 1] = -self._vo_V * y - self._lo_V * x
        bu[1:, 1] += self._vo_V[:-1] * y[:-1]
        bu *= self._inv_hold[:, None]
        return jac, bu

    def linearize(self, x: Array, u: Array) -> control.StateSpace:
        """Linear model in deviation variables at ``(x, u)``, outputs ``(x_D, x_B)``."""
        import control

        jac, bu = self.jacobian(x, u)
        c = np.zeros((2, self.n))
        c[0, -1] = 1.0
        c[1, 0] = 1.0
        return control.ss(jac, bu, c, np.zeros((2, 2)))

    # -- steady states --------------------------------------------------------------------------
    def nominal_input(self) -> Array:
        """The operating point's inputs ``(L, V)`` from the parameters."""
        return np.array((self.params.L, self.params.V))

    def _initial_profile(self) -> Array:
        if self.n == len(TABLE_3_2_X):
            return np.array(TABLE_3_2_X)
        return np.linspace(0.02, 0.98, self.n)

    def steady_state(self, u: Array | None = None, x0: Array | None = None) -> Array:
        """Steady-state compositions at inputs ``u = (L, V)`` (default: nominal).

        Newton's method (``scipy.optimize.fsolve`` with the analytic Jacobian) from ``x0``
        (default: Table 3.2's profile), after a stiff transient from ``x0`` if it does not
        converge.

        Raises
        ------
        ValueError
            If no steady state with compositions in ``[0, 1]`` is found.
        """
        u = self.nominal_input() if u is None else np.asarray(u, dtype=float)
        p = self.params
        if u[1] + p.V_F - u[0] <= 0 or u[0] + p.L_F - u[1] <= 0:
            raise ValueError(f"steady_state: u = {tuple(u)} gives D <= 0 or B <= 0")
        x0 = self._initial_profile() if x0 is None else np.asarray(x0, dtype=float)

        def f(x: Array) -> Array:
            return self.rhs(0.0, x, u)

        def jac(x: Array) -> Array:
            return self.jacobian(x, u)[0]

        def solved(x: Array) -> bool:
            return bool(
                np.all(np.isfinite(x))
                and np.max(np.abs(f(x))) < 1e-9
                and np.all((x >= 0.0) & (x <= 1.0))
            )

        x = fsolve(f, x0, fprime=jac, xtol=1e-13)
        if not solved(x):
            sol = solve_ivp(
                lambda t, z: f(z),
                (0.0, 200.0),
                x0,
                method="BDF",
                jac=lambda t, z: jac(z),
                rtol=1e-8,
                atol=1e-11,
            )
            x = fsolve(f, sol.y[:, -1], fprime=jac, xtol=1e-13)
        if not solved(x):
            raise ValueError(f"steady_state: no steady state found at u = {tuple(u)}")
        return x

    def equilibrium(self, y_bar: Mapping[str, float]) -> tuple[Array, Array]:
        """State and inputs ``(L, V)`` that hold ``(x_D, x_B)`` at ``y_bar``.

        Parameters
        ----------
        y_bar : mapping
            ``{"x_D": ..., "x_B": ...}``.

        Returns
        -------
        x_bar, u_bar : ndarray
            Compositions ``x_1 ... x_N`` and inputs ``(L, V)``.

        Raises
        ------
        ValueError
            If an output is missing, out of ``(0, 1)``, or no steady state reaches it.
        """
        missing = [nm for nm in self.output_names if nm not in y_bar]
        if missing:
            raise ValueError(f"Column.equilibrium: set points missing for outputs {missing}")
        xd, xb = float(y_bar["x_D"]), float(y_bar["x_B"])
        if not (0.0 < xb < xd < 1.0):
            raise ValueError(f"Column.equilibrium: need 0 < x_B < x_D < 1, got {xb}, {xd}")
        n = self.n
        u0 = self.nominal_input()
        z0 = np.concatenate((self.steady_state(u0), u0))

        def g(z: Array) -> Array:
            x, u = z[:n], z[n:]
            return np.concatenate((self.rhs(0.0, x, u), (x[-1] - xd, x[0] - xb)))

        def gj(z: Array) -> Array:
            jx, ju = self.jacobian(z[:n], z[n:])
            out = np.zeros((n + 2, n + 2))
            out[:n, :n], out[:n, n:] = jx, ju
            out[n, n - 1] = 1.0
            out[n + 1, 0] = 1.0
            return out

        z = fsolve(g, z0, fprime=gj, xtol=1e-13)
        x, u = z[:n], z[n:]
        p = self.params
        ok = (
            np.max(np.abs(g(z))) < 1e-9
            and np.all((x >= 0) & (x <= 1))
            and u[1] + p.V_F - u[0] > 0
            and u[0] + p.L_F - u[1] > 0
        )
        if not ok:
            raise ValueError(f"Column.equilibrium: no steady state reaches {dict(y_bar)}")
        return x, u


# -- appendix E and the reduced model of section 4.3 --------------------------------------------
def _tridiag(rows: Sequence[tuple[float | None, float, float | None]]) -> Array:
    n = len(rows)
    a = np.zeros((n, n))
    for i, (sub, diag, sup) in enumerate(rows):
        a[i, i] = diag
        if sub is not None:
            a[i, i - 1] = sub
        if sup is not None:
            a[i, i + 1] = sup
    return a


APPENDIX_E_A: Array = _tridiag(
    [
        (None, -23.0, 7.3), (61.4, -83.2, 31.0), (52.1, -70.5, 31.0), (39.5, -59.0, 31.0),
        (27.9, -51.4, 31.0), (20.4, -47.5, 31.0), (16.5, -45.7, 31.0), (14.7, -44.9, 13.0),
        (13.9, -44.9, 13.0), (31.9, -41.6, 13.0), (28.5, -35.6, 13.0), (22.5, -28.3, 13.0),
        (15.2, -22.7, 13.0), (9.7, -19.9, 13.0), (6.9, -18.7, 13.0), (2.4, -12.0, None),
    ]
)  # fmt: skip
"""Appendix E.1: the thesis's 16 x 16 state matrix as printed (1/h)."""
APPENDIX_E_B: Array = np.array(
    [
        [0.0012, 0.0063, 0.0091, 0.0098, 0.0076, 0.0044, 0.0022, 0.0021,
         0.0048, 0.0111, 0.0216, 0.0306, 0.0285, 0.0178, 0.0086, -0.0702],
        [-0.0024, -0.0157, -0.0237, -0.0254, -0.0196, -0.0116, -0.0058, -0.0027,
         -0.0024, -0.0050, -0.0097, -0.0138, -0.0128, -0.0080, -0.0039, 0.0704],
    ]
).T  # fmt: skip
"""Appendix E.1: input matrix as printed (columns ``dL, dV``)."""
APPENDIX_E_C: Array = np.zeros((2, 16))
APPENDIX_E_C[0, 0] = 1.0
APPENDIX_E_C[1, 15] = 1.0
"""Appendix E.1: outputs ``(dx_B, dx_D) = (dx_1, dx_16)`` (note the order)."""

THESIS_A_M: Array = np.array([[-6.7941, -0.9095], [1.4686, -0.2497]])
"""Eq. (4.3): reduced state matrix (eigenvalues -6.5832, -0.4606, section 4.3.1)."""
THESIS_B_M: Array = np.array([[-0.1461, 0.2073], [-0.0021, -0.0281]])
"""Eq. (4.3): reduced input matrix."""
THESIS_C_M: Array = np.array([[-0.0624, -0.0281], [0.2458, 0.0009]])
"""Eq. (4.4): reduced output matrix (outputs in appendix E's order ``(x_B, x_D)``)."""


@dataclass(frozen=True)
class ReducedModel:
    """A balanced reduced model ``dx_r/dt = A x_r + B u``, ``y = C x_r + D u``.

    ``W`` (``r x n``) maps the full state to the reduced one (``x_r = W x``, the first ``r``
    balanced coordinates); ``V`` (``n x r``) lifts it back (``x ~ V x_r``; ``W V = I``).
    """

    A: Array
    B: Array
    C: Array
    D: Array
    hsv: Array
    W: Array
    V: Array
    method: str

    def eigenvalues(self) -> Array:
        """Eigenvalues of ``A``, sorted by decreasing real part."""
        ev = np.linalg.eigvals(self.A)
        return ev[np.argsort(-ev.real)]

    def dc_gain(self) -> Array:
        """Steady-state gain ``D - C A^-1 B``."""
        return self.D - self.C @ np.linalg.solve(self.A, self.B)

    def to_statespace(self) -> control.StateSpace:
        """As a python-control state-space object."""
        import control

        return control.ss(self.A, self.B, self.C, self.D)


def _psd_factor(w: Array) -> Array:
    """A factor ``F`` with ``w = F F^T`` for a symmetric positive semi-definite ``w``."""
    lam, vec = np.linalg.eigh(0.5 * (w + w.T))
    return vec * np.sqrt(np.clip(lam, 0.0, None))


def balanced_reduction(
    A: Array,
    B: Array,
    C: Array,
    order: int,
    method: Literal["truncate", "matchdc"] = "truncate",
    D: Array | None = None,
) -> ReducedModel:
    """Balanced truncation or residualization to ``order`` states (section 4.3).

    Square-root method: the Gramians ``Wc``, ``Wo`` solve the Lyapunov equations, ``Lo^T Lc =
    U S V^T``, and ``W = S^-1/2 U^T Lo^T``, ``V = Lc V S^-1/2`` keep the ``order`` largest Hankel
    singular values. ``"truncate"`` is MATLAB ``modred(..., 'del')`` after ``balreal``;
    ``"matchdc"`` (``modred``'s default) residualizes the rest (singular perturbation), keeping the
    steady-state gain. The residualized states are any complement of the kept ones with ``W V2 =
    0``; the result does not depend on which.

    Raises
    ------
    ValueError
        If ``A`` is not stable (Hurwitz), shapes disagree, or ``order`` is out of range.
    """
    a, b, c = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C))
    n = a.shape[0]
    if a.shape != (n, n) or b.shape[0] != n or c.shape[1] != n:
        raise ValueError(f"balanced_reduction: shapes A {a.shape}, B {b.shape}, C {c.shape}")
    if not 0 < order < n:
        raise ValueError(f"balanced_reduction: order must be in 1..{n - 1}, got {order}")
    if np.max(np.linalg.eigvals(a).real) >= 0.0:
        raise ValueError("balanced_reduction: A must be stable (all eigenvalues in Re < 0)")
    d = np.zeros((c.shape[0], b.shape[1])) if D is None else np.asarray(D, dtype=float)
    wc = solve_continuous_lyapunov(a, -b @ b.T)
    wo = solve_continuous_lyapunov(a.T, -c.T @ c)
    lc, lo = _psd_factor(wc), _psd_factor(wo)
    u_, s, vt = np.linalg.svd(lo.T @ lc)
    if s[order - 1] <= 1e-14 * s[0]:
        raise ValueError("balanced_reduction: the kept Hankel singular values are zero")
    scale = s[:order] ** -0.5
    w1 = scale[:, None] * (u_[:, :order].T @ lo.T)
    v1 = (lc @ vt[:order].T) * scale[None, :]
    a11, b1, c1 = w1 @ a @ v1, w1 @ b, c @ v1
    if method == "truncate":
        ar, br, cr, dr = a11, b1, c1, d
    elif method == "matchdc":
        v2 = null_space(w1)
        t_full = np.hstack((v1, v2))
        w2 = np.linalg.inv(t_full)[order:]
        a12, a21, a22 = w1 @ a @ v2, w2 @ a @ v1, w2 @ a @ v2
        b2, c2 = w2 @ b, c @ v2
        a22_inv_a21 = np.linalg.solve(a22, a21)
        a22_inv_b2 = np.linalg.solve(a22, b2)
        ar = a11 - a12 @ a22_inv_a21
        br = b1 - a12 @ a22_inv_b2
        cr = c1 - c2 @ a22_inv_a21
        dr = d - c2 @ a22_inv_b2
    else:
        raise ValueError(f"balanced_reduction: method must be 'truncate' or 'matchdc': {method}")
    return ReducedModel(ar, br, cr, dr, s, w1, v1, method)


# -- the test plant of section 6.3.1 -------------------------------------------------------------
SECTION_631_SPREAD: dict[str, Array] = {
    "A": np.array([[0.67, 0.09], [0.15, 0.02]]),
    "B": np.array([[0.014, 0.02], [0.0002, 0.003]]),
    "C": np.array([[0.006, 0.003], [0.025, 0.00009]]),
}
"""Section 6.3.1 / appendix F.2: each element moves by ``spread * (rand() % 2 - 0.5)``."""

APPENDIX_G_SIGNS = (
    "028b991c48b7b09f9b224aece904c934c6c6948940b612e4355ad962b3dceff7b56013c452ebf2ee9bd0460719"
    "5dd679d93af679a0f3385cdcf3fc5944d914161f9d114d3af95a153cb2f2fd3a80cc3a5341c1d6de08095f6c84"
    "51829bf71702973dded4"
)
"""The signs of ``(a11, a12, a21, a22, b11, b12, b21, b22)`` (bit 7 to bit 0, set = ``+``) at
steps ``k = 0 ... 99`` that reproduce Table G.1 (inferred; see the module notes)."""


def appendix_g_signs() -> Array:
    """:data:`APPENDIX_G_SIGNS` as a ``(100, 8)`` array of ``+-0.5``."""
    raw = np.frombuffer(bytes.fromhex(APPENDIX_G_SIGNS), dtype=np.uint8)
    bits = np.unpackbits(raw[:, None], axis=1)
    return bits.astype(float) - 0.5


class PerturbedReducedPlant:
    """The thesis's test plant (section 6.3.1, appendix F.2): ``(A_m, B_m, C_m)`` with each element
    moved by ``+- spread / 2``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the signs (``rng.integers(0, 2) - 0.5``, the C++ ``rand() % 2 - 0.5``).
    redraw : {"once", "every_step"}
        ``"once"``: one plant for the whole run; ``"every_step"``: a new plant at every
        :meth:`euler_step` (what the thesis's C++ program does, appendix G).
    A, B, C : array_like
        Nominal matrices (default: eq. (4.3)-(4.4)).
    """

    state_names: tuple[str, ...] = ("x1", "x2")
    input_names: tuple[str, ...] = ("u1", "u2")
    output_names: tuple[str, ...] = ("y1", "y2")

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        redraw: Literal["once", "every_step"] = "once",
        A: Array = THESIS_A_M,
        B: Array = THESIS_B_M,
        C: Array = THESIS_C_M,
    ) -> None:
        if redraw not in ("once", "every_step"):
            raise ValueError(f"redraw must be 'once' or 'every_step', got {redraw!r}")
        self.rng = rng
        self.redraw = redraw
        self.A_nom, self.B_nom, self.C_nom = (np.array(m, dtype=float) for m in (A, B, C))
        self.draw()

    def draw(self) -> None:
        """New signs for all twelve elements (C++ order ``a11 ... b22, c11 ... c22``)."""
        signs = self.rng.integers(0, 2, size=12) - 0.5
        self.set_signs(signs)

    def set_signs(self, signs: Sequence[float] | Array) -> None:
        """Set the perturbations: 8 (``A, B``) or 12 (``A, B, C``) values of ``+-0.5``."""
        s = np.asarray(signs, dtype=float)
        if s.shape not in ((8,), (12,)):
            raise ValueError(f"signs must have 8 or 12 elements, got shape {s.shape}")
        sp = SECTION_631_SPREAD
        self.A = self.A_nom + sp["A"] * s[0:4].reshape(2, 2)
        self.B = self.B_nom + sp["B"] * s[4:8].reshape(2, 2)
        self.C = self.C_nom + (sp["C"] * s[8:12].reshape(2, 2) if s.size == 12 else 0.0)

    def rhs(self, t: float, x: Array, u: Array) -> Array:
        """Continuous plant ``dx/dt = A x + B u`` (eq. (4.7))."""
        return self.A @ x + self.B @ u

    def euler_step(self, x: Array, u: Array, T: float) -> Array:
        """Eq. (5.1): ``x(k+1) = (I + T A) x(k) + T B u(k)``, then a new plant if ``every_step``."""
        x_next = x + T * (self.A @ x + self.B @ u)
        if self.redraw == "every_step":
            self.draw()
        return x_next

    def outputs(self, x: Array) -> Array:
        """Eq. (4.8): ``y = C x``."""
        return self.C @ x
