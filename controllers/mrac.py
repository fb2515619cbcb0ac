"""Model-reference adaptive controller (MRAC) of seed 003 (Lyapunov design), chapters 4-5.

Plant ``dx/dt = A x + B u`` (4.7) with unknown ``A, B`` (``n x n``; the thesis has ``n = 2``),
reference model ``dx_m/dt = A_m x_m + B_m u_c``, ``y_m = C_m x_m`` (4.9)-(4.10), control law
(4.11)::

    u = u_bar + M u_c - L x,      L = [[th1, th2], [th3, th4]],  M = [[th5, th6], [th7, th8]]

(``u_bar``: the operating point's input when ``x`` is a deviation; zero in the thesis).
``theta = (vec L, vec M)`` row by row.

Compatibility condition (4.13)-(4.14) / (5.7): ``A - B L0 = A_m`` and ``B M0 = B_m``, i.e.
``L0 = B^-1 (A - A_m)`` and ``M0 = B^-1 B_m`` (:func:`compatibility_theta`), computed from the
nominal plant ``(A0, B0)`` for the initial ``theta``. It needs ``B`` invertible.

Error equation (4.15)-(4.17), with ``e = x - x_m``::

    de/dt = A_m e + psi (theta - theta0),   psi theta = -B L x + B M u_c       (:func:`psi`)

Continuous adaptation law (4.22)-(4.23), from ``V = (gamma e^T P e + |theta - theta0|^2) / 2``
(4.18) and ``A_m^T P + P A_m = -Q`` (4.21) (:func:`theta_dot`)::

    dtheta/dt = -gamma psi^T P e,   i.e.  dL/dt = gamma s x^T,  dM/dt = -gamma s u_c^T,  s = B^T P e

Discrete adaptation law (5.8), forward Euler over the *actual* time ``dt_k = t_k - t_(k-1)``
between executions (the thesis's ``T``) (:class:`MRAC`)::

    theta(k) = theta(k-1) - dt_k gamma psi^T(k-1) P e(k-1)                      (5.8)

In the adaptation law ``psi`` is built with the *nominal* ``B0`` (the plant's ``B`` is unknown);
the C++ code of appendix F.1 uses fixed ``b11 ... b22`` the same way.

Misprints of the thesis (checked in ``tests/unit/test_mrac.py``)
----------------------------------------------------------------
* (4.17), (4.22) and section 5.2.5 print ``psi[2, 2] = -b22 x2``; (4.16) gives ``-b21 x2``.
* (4.14) and (5.7) print ``th8 = (0.0281 b11 + 0.2073 b21) / det``; the condition ``b21 th6 +
  b22 th8 = -0.0281`` gives ``-(0.0281 b11 + 0.2073 b21) / det`` (with the thesis's nominal plant
  the printed formula gives -1.007 instead of the +1.007 of Table G.4).
* (5.9), the expansion of (5.8): ``th6`` is printed with ``(b12 e1 + b22 e2)``; (5.8) gives
  ``(b11 e1 + b21 e2) u_c2`` (as (4.23) and the C++ code of appendix F.1 have it).
* (4.24): ``e^T Q e`` is not ``(0.5591 e1 - 0.7066 e2)^2 + 13.2756 e1^2`` (its cross term is
  -0.790 e1 e2, that of ``Q`` is -1.118 e1 e2); it is ``(0.7067 e2 - 0.7912 e1)^2 + 12.9622
  e1^2``. ``Q`` itself, ``[[13.5882, -0.5591], [-0.5591, 0.4994]]``, is right, and the conclusion
  (``dV/dt <= 0``) stands.
* (5.1), (5.3) are called zero-order-hold equivalents but are forward Euler (``I + T A``, not
  ``exp(A T)``); (5.3) prints ``T B u_c`` for ``T B_m u_c`` and (5.4) ``C x_m`` for ``C_m x_m``.
  ``reference_discretization="euler"`` follows (5.3); ``"zoh"`` is the exact discretization.

Initial ``theta`` of the thesis's runs: Table G.4 starts from ``(0.372, -0.511, 0.281, -0.310,
1.044, -0.043, 0.000, 1.007)``. That is :func:`compatibility_theta` with ``A_m, B_m`` as nominal
plant after rounding to two significant digits, ``A0 = [[-6.79, -0.90], [1.46, -0.24]]``, ``B0 =
[[-0.14, 0.20], [-0.0020, -0.028]]`` (:data:`THESIS_A0`, :data:`THESIS_B0`): ``(0.3716,
-0.5106, 0.2806, -0.3100, 1.0442, -0.0427, 0.0004, 1.0066)``, also the values of Fig. 7.28.

Divergence
----------
The discrete law is a gradient step of size ``dt gamma``: too large a step makes ``theta`` grow
without bound. On the thesis's test (``u_c = (0.5, 0.1)``) that happens beyond ``gamma`` of about
4900 at ``T = 0.1 h``, and ``gamma* T`` stays near 490 for ``T = 0.05 ... 0.2 h``
(``bench/mrac_study.py``). After every update, a non-finite ``theta`` or ``max |theta - theta0| >
theta_bound`` is a divergence: ``on_divergence="raise"`` raises :class:`MRACDivergenceError`;
``"freeze"`` keeps the last bounded ``theta``, stops adapting and records it in
:attr:`MRAC.diverged`, :attr:`MRAC.divergence_time` and :attr:`MRAC.divergence_message`.

Around an operating point
-------------------------
For a non-linear plant (the column of :mod:`plants.column`) ``x`` is a deviation and ``u_bar`` the
operating point's input. With ``measurement="output"`` the law takes the measured outputs and
uses ``x = C_m^-1 (y - y_bar)`` (a two-state reference model with two outputs); with ``"state"``
the caller passes the reduced state itself (e.g. ``W (x - x*)`` of a balanced reduction).

On the platform
---------------
:class:`MultiLoopMRAC` is the law a controller node with ``loops: [...]`` runs (``type: mrac``):
loop ``i`` measures ``x_i``, moves ``u_i`` and its set point is ``u_c,i``. :func:`replay` re-runs
it over a run's executions (:func:`runtime.executions.multi_loop_executions`) to recover ``x_m``,
``e`` and ``theta``, which are not on the bus.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from scipy.linalg import expm

from plants.column import THESIS_A_M, THESIS_B_M, THESIS_C_M

__all__ = [
    "MRACConfig",
    "MRAC",
    "MRACDivergenceError",
    "compatibility_theta",
    "psi",
    "theta_dot",
    "lyapunov_Q",
    "continuous_loop_rhs",
    "THESIS_A0",
    "THESIS_B0",
    "THESIS_Q",
    "MultiLoopMRAC",
    "replay",
]

Array = NDArray[np.float64]
Matrix = tuple[tuple[float, ...], ...]

log = logging.getLogger(__name__)

THESIS_A0: Array = np.array([[-6.79, -0.90], [1.46, -0.24]])
"""Nominal ``A`` that gives the thesis's initial ``theta`` (``A_m`` to two significant digits)."""
THESIS_B0: Array = np.array([[-0.14, 0.20], [-0.0020, -0.028]])
"""Nominal ``B`` that gives the thesis's initial ``theta`` (``B_m`` to two significant digits)."""
THESIS_Q: Array = np.array([[13.5882, -0.5591], [-0.5591, 0.4994]])
"""Section 4.4.6: ``Q = -(A_m^T P + P A_m)`` with ``P = I``."""

_SINGULAR_COND = 1e12


class MRACDivergenceError(RuntimeError):
    """The adaptation diverged (``theta`` not finite or beyond ``theta_bound``)."""


def _as_matrix(name: str, value: Sequence[Sequence[float]] | Array) -> Array:
    m = np.array(value, dtype=float)
    if m.ndim != 2 or not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be a finite 2-D matrix, got {value!r}")
    return m


def compatibility_theta(A: Array, B: Array, A_m: Array, B_m: Array) -> Array:
    """Eq. (4.13)-(4.14) / (5.7): ``theta0`` with ``A - B L0 = A_m`` and ``B M0 = B_m``.

    Parameters
    ----------
    A, B : array_like
        Plant (or nominal plant) matrices, ``n x n``.
    A_m, B_m : array_like
        Reference model matrices, ``n x n``.

    Returns
    -------
    ndarray
        ``theta0 = (vec L0, vec M0)`` (row by row), length ``2 n^2``.

    Raises
    ------
    ValueError
        If ``B`` is singular (no ``theta0`` exists) or shapes disagree.
    """
    a, b = _as_matrix("A", A), _as_matrix("B", B)
    am, bm = _as_matrix("A_m", A_m), _as_matrix("B_m", B_m)
    n = a.shape[0]
    if a.shape != (n, n) or b.shape != (n, n) or am.shape != (n, n) or bm.shape != (n, n):
        raise ValueError(
            f"compatibility condition: A, B, A_m, B_m must be {n}x{n}; got {a.shape}, "
            f"{b.shape}, {am.shape}, {bm.shape}"
        )
    cond = np.linalg.cond(b)
    if not np.isfinite(cond) or cond > _SINGULAR_COND:
        raise ValueError(
            "compatibility condition (4.13)-(4.14): B is singular "
            f"(det B = {np.linalg.det(b):.3g}, condition number {cond:.3g}); "
            "no theta0 gives A - B L = A_m and B M = B_m"
        )
    l0 = np.linalg.solve(b, a - am)
    m0 = np.linalg.solve(b, bm)
    return np.concatenate((l0.ravel(), m0.ravel()))


def psi(x: Array, u_c: Array, B: Array) -> Array:
    """Regressor of the error equation (4.17), corrected: ``psi theta = -B L x + B M u_c``.

    For ``n = 2``::

        [[-b11 x1, -b11 x2, -b12 x1, -b12 x2, b11 uc1, b11 uc2, b12 uc1, b12 uc2],
         [-b21 x1, -b21 x2, -b22 x1, -b22 x2, b21 uc1, b21 uc2, b22 uc1, b22 uc2]]

    (the thesis prints ``-b22 x2`` in row 2, column 2).
    """
    b = np.asarray(B, dtype=float)
    x = np.asarray(x, dtype=float)
    uc = np.asarray(u_c, dtype=float)
    n = b.shape[0]
    return np.hstack((-np.kron(b, x[None, :]), np.kron(b, uc[None, :]))).reshape(n, -1)


def theta_dot(
    x: Array, e: Array, u_c: Array, *, gamma: float, B: Array, P: Array | None = None
) -> Array:
    """Continuous adaptation law (4.22)-(4.23): ``dtheta/dt = -gamma psi^T P e``."""
    b = np.asarray(B, dtype=float)
    pe = np.asarray(e, dtype=float) if P is None else np.asarray(P, dtype=float) @ e
    s = b.T @ pe
    return gamma * np.concatenate((np.outer(s, x).ravel(), -np.outer(s, u_c).ravel()))


def lyapunov_Q(A_m: Array, P: Array | None = None) -> Array:
    """Eq. (4.21): ``Q = -(A_m^T P + P A_m)``."""
    am = np.asarray(A_m, dtype=float)
    p = np.eye(am.shape[0]) if P is None else np.asarray(P, dtype=float)
    return -(am.T @ p + p @ am)


def _check_square(name: str, m: Array, n: int | None = None) -> Array:
    if m.shape[0] != m.shape[1] or (n is not None and m.shape[0] != n):
        size = "square" if n is None else f"{n}x{n}"
        raise ValueError(f"{name} must be {size}, got shape {m.shape}")
    return m


class MRACConfig(BaseModel):
    """Configuration of the MRAC (seed 003's symbols; time in the plant's unit, hours)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type: Literal["mrac"] = "mrac"
    gamma: float = Field(ge=0, description="adaptation rate gamma, eq. (4.18), (4.22), (5.8)")
    T: float = Field(
        gt=0,
        description="nominal sampling period; the law uses the actual time between executions, "
        "the Euler reference model steps of at most T",
    )
    A_m: Matrix = Field(default=tuple(map(tuple, THESIS_A_M)), description="eq. (4.9)")
    B_m: Matrix = Field(default=tuple(map(tuple, THESIS_B_M)), description="eq. (4.9)")
    C_m: Matrix = Field(default=tuple(map(tuple, THESIS_C_M)), description="eq. (4.10)")
    A0: Matrix | None = Field(
        default=None, description="nominal plant A for the compatibility condition (None: A_m)"
    )
    B0: Matrix | None = Field(
        default=None,
        description="nominal plant B for the compatibility condition and the b_ij of psi in the "
        "adaptation law (None: B_m)",
    )
    P: Matrix | None = Field(default=None, description="Lyapunov weight, eq. (4.18) (None: I)")
    theta0: tuple[float, ...] | None = Field(
        default=None, description="initial theta (None: compatibility condition with A0, B0)"
    )
    x_m0: tuple[float, ...] | None = Field(default=None, description="initial x_m (None: 0)")
    u_bar: tuple[float, ...] | None = Field(
        default=None, description="operating-point input added to u (None: 0)"
    )
    y_bar: tuple[float, ...] | None = Field(
        default=None, description="operating-point output subtracted in measurement='output'"
    )
    measurement: Literal["state", "output"] = Field(
        default="state",
        description="state: step() gets x; output: step() gets y and uses x = C_m^-1 (y - y_bar)",
    )
    reference_discretization: Literal["euler", "zoh"] = Field(
        default="euler", description="euler: eq. (5.3); zoh: exact for a held u_c"
    )
    theta_bound: float = Field(
        default=10.0, gt=0, description="divergence when max |theta - theta0| exceeds this"
    )
    on_divergence: Literal["raise", "freeze"] = "raise"

    @field_validator("A_m", "B_m", "C_m", "A0", "B0", "P")
    @classmethod
    def _finite_matrix(cls, v: Matrix | None, info: object) -> Matrix | None:
        if v is None:
            return v
        name = getattr(info, "field_name", "matrix")
        m = _as_matrix(name, v)
        return tuple(map(tuple, m.tolist()))

    @model_validator(mode="after")
    def _consistent(self) -> MRACConfig:
        am = _check_square("A_m", np.array(self.A_m))
        n = am.shape[0]
        _check_square("B_m", np.array(self.B_m), n)
        cm = np.array(self.C_m)
        if cm.shape[1] != n:
            raise ValueError(f"C_m must have {n} columns, got shape {cm.shape}")
        if np.max(np.linalg.eigvals(am).real) >= 0:
            raise ValueError("A_m must be stable (eigenvalues with negative real parts)")
        a0 = am if self.A0 is None else _check_square("A0", np.array(self.A0), n)
        b0 = np.array(self.B_m) if self.B0 is None else _check_square("B0", np.array(self.B0), n)
        if self.P is not None:
            p = _check_square("P", np.array(self.P), n)
            if not np.allclose(p, p.T) or np.min(np.linalg.eigvalsh(0.5 * (p + p.T))) <= 0:
                raise ValueError("P must be symmetric positive definite")
        if self.theta0 is None:
            try:
                compatibility_theta(a0, b0, am, np.array(self.B_m))
            except ValueError as exc:
                field = "B0" if self.B0 is not None else "B_m (B0 not given: the nominal B is B_m)"
                raise ValueError(f"{field}: {exc}") from None
        elif len(self.theta0) != 2 * n * n or not all(map(math.isfinite, self.theta0)):
            raise ValueError(f"theta0 must be {2 * n * n} finite numbers, got {self.theta0}")
        for name in ("x_m0", "u_bar", "y_bar"):
            v = getattr(self, name)
            if v is not None and (len(v) != n or not all(map(math.isfinite, v))):
                raise ValueError(f"{name} must be {n} finite numbers, got {v}")
        if self.measurement == "output":
            if cm.shape != (n, n) or np.linalg.cond(cm) > _SINGULAR_COND:
                raise ValueError("C_m must be square and invertible for measurement='output'")
        if self.reference_discretization == "euler":
            rho = np.max(np.abs(1.0 + self.T * np.linalg.eigvals(am)))
            if rho >= 1.0:
                raise ValueError(
                    f"T = {self.T} makes the forward-Euler reference model (5.3) unstable "
                    f"(spectral radius of I + T A_m = {rho:.3f}); lower T or use "
                    "reference_discretization='zoh'"
                )
        return self


class MRAC:
    """Discrete MRAC: control law (4.11)/(5.5), reference model (5.3), adaptation law (5.8).

    Parameters
    ----------
    config : MRACConfig
        Adaptation rate, sampling period, reference model, nominal plant.
    u_bar : sequence of float, optional
        Operating-point input (overrides ``config.u_bar``); see :meth:`set_feedforward`.

    Notes
    -----
    One execution at ``t_k`` (:meth:`step`): advance ``x_m`` from ``t_(k-1)`` with ``u_c(k-1)``
    held; update ``theta`` by (5.8) with ``x, e, u_c`` of ``t_(k-1)`` and ``dt_k = t_k -
    t_(k-1)``; then ``e(k) = x(k) - x_m(k)`` and ``u(k) = u_bar + M(k) u_c(k) - L(k) x(k)``.
    This is the order of appendix F (sections F.1-F.4).
    """

    def __init__(self, config: MRACConfig, *, u_bar: Sequence[float] | None = None) -> None:
        self.config = c = config
        self.A_m = np.array(c.A_m)
        self.B_m = np.array(c.B_m)
        self.C_m = np.array(c.C_m)
        self.n = n = self.A_m.shape[0]
        self.A0 = self.A_m.copy() if c.A0 is None else np.array(c.A0)
        self.B0 = self.B_m.copy() if c.B0 is None else np.array(c.B0)
        self.P = np.eye(n) if c.P is None else np.array(c.P)
        self.theta0 = (
            compatibility_theta(self.A0, self.B0, self.A_m, self.B_m)
            if c.theta0 is None
            else np.array(c.theta0, dtype=float)
        )
        self._bp = self.B0.T @ self.P  # s = B0^T P e
        self._x_m0 = np.zeros(n) if c.x_m0 is None else np.array(c.x_m0, dtype=float)
        self.y_bar = np.zeros(n) if c.y_bar is None else np.array(c.y_bar, dtype=float)
        self.u_bar = np.zeros(n)
        self.set_feedforward(c.u_bar if u_bar is None else u_bar)
        self._zoh_cache: dict[float, tuple[Array, Array]] = {}
        self.reset()

    # -- state ------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to ``theta0`` and ``x_m0``; forget the previous execution and any divergence."""
        self.theta = self.theta0.copy()
        self.x_m = self._x_m0.copy()
        self.e = np.zeros(self.n)
        self.diverged = False
        self.divergence_time: float | None = None
        self.divergence_message: str | None = None
        self._t_prev: float | None = None
        self._x_prev = np.zeros(self.n)
        self._e_prev = np.zeros(self.n)
        self._uc_prev = np.zeros(self.n)

    def set_feedforward(self, u_bar: Sequence[float] | Array | None) -> None:
        """Set the operating-point input ``u_bar`` (zero for the thesis's deviation model)."""
        if u_bar is None:
            self.u_bar = np.zeros(self.n)
            return
        v = np.array(u_bar, dtype=float).ravel()
        if v.shape != (self.n,) or not np.all(np.isfinite(v)):
            raise ValueError(f"u_bar must be {self.n} finite numbers, got {u_bar}")
        self.u_bar = v

    @property
    def L(self) -> Array:
        """Feedback gain ``L = [[th1, th2], [th3, th4]]`` (a copy)."""
        n = self.n
        return self.theta[: n * n].reshape(n, n).copy()

    @property
    def M(self) -> Array:
        """Feedforward gain ``M = [[th5, th6], [th7, th8]]`` (a copy)."""
        n = self.n
        return self.theta[n * n :].reshape(n, n).copy()

    @property
    def y_m(self) -> Array:
        """Reference output ``C_m x_m`` (4.10)."""
        return self.C_m @ self.x_m

    @property
    def theta_drift(self) -> float:
        """``max |theta - theta0|``, the quantity the divergence test bounds."""
        return float(np.max(np.abs(self.theta - self.theta0)))

    # -- one execution ----------------------------------------------------------------------------
    def state_from(self, x_or_y: Sequence[float] | Array) -> Array:
        """The state the law uses: ``x`` itself, or ``C_m^-1 (y - y_bar)`` for outputs."""
        v = np.array(x_or_y, dtype=float).ravel()
        if v.shape != (self.n,) or not np.all(np.isfinite(v)):
            raise ValueError(f"MRAC.step: expected {self.n} finite measurements, got {x_or_y}")
        if self.config.measurement == "output":
            return np.linalg.solve(self.C_m, v - self.y_bar)
        return v

    def _advance_reference(self, dt: float, uc: Array) -> Array:
        c = self.config
        if c.reference_discretization == "zoh":
            if dt not in self._zoh_cache:
                n = self.n
                aug = np.zeros((2 * n, 2 * n))
                aug[:n, :n], aug[:n, n:] = self.A_m * dt, self.B_m * dt
                ex = expm(aug)
                if len(self._zoh_cache) > 64:
                    self._zoh_cache.clear()
                self._zoh_cache[dt] = (ex[:n, :n], ex[:n, n:])
            phi, gam = self._zoh_cache[dt]
            return phi @ self.x_m + gam @ uc
        # eq. (5.3), in Euler steps no longer than T (one step when dt = T)
        k = max(1, math.ceil(dt / c.T - 1e-9))
        h = dt / k
        xm = self.x_m
        bu = self.B_m @ uc
        for _ in range(k):
            xm = xm + h * (self.A_m @ xm + bu)
        return xm

    def _adapt(self, t: float, dt: float) -> None:
        if self.diverged:
            return  # frozen after a divergence
        s = self._bp @ self._e_prev
        g = dt * self.config.gamma
        n = self.n
        new = self.theta.copy()
        new[: n * n] += g * np.outer(s, self._x_prev).ravel()
        new[n * n :] -= g * np.outer(s, self._uc_prev).ravel()
        drift = np.max(np.abs(new - self.theta0)) if np.all(np.isfinite(new)) else math.inf
        if drift > self.config.theta_bound:
            msg = (
                f"MRAC adaptation diverged at t = {t:.6g}: max |theta - theta0| = {drift:.4g} > "
                f"theta_bound = {self.config.theta_bound:.4g} (gamma = {self.config.gamma:.6g}, "
                f"dt = {dt:.6g})"
            )
            self.diverged = True
            self.divergence_time = t
            self.divergence_message = msg
            if self.config.on_divergence == "raise":
                raise MRACDivergenceError(msg)
            return  # freeze: keep the last bounded theta
        self.theta = new

    def step(self, t: float, x_or_y: Sequence[float] | Array, u_c: Sequence[float]) -> Array:
        """One execution at time ``t``; returns the plant input ``u`` (4.11)/(5.5).

        Parameters
        ----------
        t : float
            Execution time (the adaptation uses ``t`` minus the previous execution's time).
        x_or_y : array_like
            Plant state (or outputs, with ``measurement="output"``).
        u_c : array_like
            Reference input ``u_c``.

        Raises
        ------
        ValueError
            If time goes backwards or an input is not finite.
        MRACDivergenceError
            If the adaptation diverges and ``on_divergence="raise"``.
        """
        x = self.state_from(x_or_y)
        uc = np.array(u_c, dtype=float).ravel()
        if uc.shape != (self.n,) or not np.all(np.isfinite(uc)):
            raise ValueError(f"MRAC.step: expected {self.n} finite reference inputs, got {u_c}")
        if self._t_prev is not None:
            dt = t - self._t_prev
            if dt < 0.0:
                raise ValueError(f"MRAC.step: time went backwards ({self._t_prev} -> {t})")
            if dt > 0.0:
                self.x_m = self._advance_reference(dt, self._uc_prev)
                self._adapt(t, dt)
        self.e = x - self.x_m
        n = self.n
        lmat = self.theta[: n * n].reshape(n, n)
        mmat = self.theta[n * n :].reshape(n, n)
        u = self.u_bar + mmat @ uc - lmat @ x
        self._t_prev = float(t)
        self._x_prev = x
        self._e_prev = self.e.copy()
        self._uc_prev = uc
        return u


def _constant(m: Array) -> Callable[[float], Array]:
    return lambda t: m


def continuous_loop_rhs(
    A: Array | Callable[[float], Array],
    B: Array | Callable[[float], Array],
    config: MRACConfig,
) -> Callable[[float, Array, Array], Array]:
    """The analog MRAC loop of section 4.4 as one ODE, for :func:`plants.integrate.rk4`.

    State ``z = (x, x_m, theta)``, held input ``w = (u_c, d)`` (``d``: disturbance added to
    ``dx/dt``)::

        dx/dt     = A x + B (M u_c - L x) + d
        dx_m/dt   = A_m x_m + B_m u_c
        dtheta/dt = -gamma psi^T(x, u_c; B0) P (x - x_m)                    (4.22)

    ``A`` and ``B`` may be functions of time (a plant whose parameters change).
    """
    am, bm = np.array(config.A_m), np.array(config.B_m)
    n = am.shape[0]
    b0 = np.array(config.B_m) if config.B0 is None else np.array(config.B0)
    p = np.eye(n) if config.P is None else np.array(config.P)
    gamma = config.gamma
    a_of = A if callable(A) else _constant(np.array(A, dtype=float))
    b_of = B if callable(B) else _constant(np.array(B, dtype=float))

    def f(t: float, z: Array, w: Array) -> Array:
        x, xm, th = z[:n], z[n : 2 * n], z[2 * n :]
        uc, d = w[:n], w[n : 2 * n]
        lmat = th[: n * n].reshape(n, n)
        mmat = th[n * n :].reshape(n, n)
        u = mmat @ uc - lmat @ x
        dx = a_of(t) @ x + b_of(t) @ u + d
        dxm = am @ xm + bm @ uc
        dth = theta_dot(x, x - xm, uc, gamma=gamma, B=b0, P=p)
        return np.concatenate((dx, dxm, dth))

    return f


class MultiLoopMRAC:
    """The MRAC as a multi-loop control law of the platform (a controller node with ``loops:``).

    Loop ``i`` of the node's ``loops: [...]`` (in that order) measures ``x_i`` (or ``y_i`` with
    ``measurement="output"``), moves ``u_i``, and its set point is the reference command
    ``u_c,i`` (4.9): the set points are what the thesis feeds the reference model, in the units
    of the plant's inputs, not desired values of the measured variables (the reference model's
    steady state is ``x_m = -A_m^-1 B_m u_c``). Each execution is one :meth:`MRAC.step` at the
    execution's time, so the adaptation (5.8) uses the actual time since the previous one.

    A divergence with ``on_divergence="raise"`` stops the node (and the run, naming the node);
    with ``"freeze"`` it is logged once as a warning and the law keeps its last bounded ``theta``.

    Parameters
    ----------
    config : MRACConfig
        The controller's configuration.
    loops : sequence of str
        The loops it controls, in the order of ``x`` and ``u``.
    """

    multi_loop = True

    def __init__(self, config: MRACConfig, loops: Sequence[str]) -> None:
        self.check_loops(config, loops)
        self.loops = tuple(loops)
        self.mrac = MRAC(config)
        self._warned = False

    @staticmethod
    def check_loops(config: MRACConfig, loops: Sequence[str]) -> None:
        """Refuse a loop list that does not match the reference model's order (``ValueError``)."""
        n = len(config.A_m)
        if len(loops) != n:
            raise ValueError(
                f"the MRAC's reference model has {n} states, so it controls exactly {n} loops "
                f"(x_i measured, u_i moved, u_c,i the set point of loop i); got {len(loops)}: "
                f"{list(loops)}"
            )

    @classmethod
    def from_config(
        cls,
        config: MRACConfig,
        *,
        loops: Sequence[str],
        plant: object,
        tau_s: float,
        context: object = None,
    ) -> MultiLoopMRAC:
        """Build from the scenario (the plant, sampling period and context are not used: the
        MRAC is designed from its reference model and nominal plant, and uses the actual time
        between executions)."""
        return cls(config, loops)

    def reset(self) -> None:
        """Back to ``theta0`` and ``x_m0``."""
        self.mrac.reset()
        self._warned = False

    def step(self, t: float, y: Mapping[str, float], r: Mapping[str, float]) -> dict[str, float]:
        """One execution: measurements ``y`` and reference commands ``r`` by loop; returns each
        loop's move."""
        u = self.mrac.step(t, [y[n] for n in self.loops], [r[n] for n in self.loops])
        if self.mrac.diverged and not self._warned:
            self._warned = True
            log.warning("%s; adaptation frozen", self.mrac.divergence_message)
        return {n: float(u[i]) for i, n in enumerate(self.loops)}


def replay(
    config: MRACConfig,
    loops: Sequence[str],
    executions: Iterable[tuple[float, Mapping[str, float], Mapping[str, float]]],
) -> dict[str, Array]:
    """Re-run the MRAC over a run's executions and return its signals (the thesis's Fig. 6.3-6.5).

    Parameters
    ----------
    config : MRACConfig
        The controller's configuration.
    loops : sequence of str
        Its loops, in order.
    executions : iterable of (t, y, r)
        Execution time (time units), held measurement and reference command per loop, e.g. from
        :func:`runtime.executions.multi_loop_executions` (a bus run's executions are not on the bus,
        the samples and set points they follow are).

    Returns
    -------
    dict
        ``t``; ``x`` the state the law used, ``x_m`` the reference state, ``e = x - x_m``, ``y_m =
        C_m x_m``, ``u_c``, ``u`` the moves, ``theta``; arrays with one row per execution.
    """
    law = MultiLoopMRAC(config, loops)
    m = law.mrac
    rec: dict[str, list] = {k: [] for k in ("t", "x", "x_m", "e", "y_m", "u_c", "u", "theta")}
    for t, y, r in executions:
        u = law.step(t, y, r)
        rec["t"].append(t)
        rec["x"].append(m.e + m.x_m)
        rec["x_m"].append(m.x_m.copy())
        rec["e"].append(m.e.copy())
        rec["y_m"].append(m.y_m)
        rec["u_c"].append([r[n] for n in loops])
        rec["u"].append([u[n] for n in loops])
        rec["theta"].append(m.theta.copy())
    return {k: np.array(v, dtype=float) for k, v in rec.items()}
