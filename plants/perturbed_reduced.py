"""The MRAC test plant of seed 003 (section 6.3.1) as a plant node runs it.

The reduced column model of section 4.3 with the thesis's randomized parameter perturbations,
in continuous time, with the states measured (the MRAC of chapter 4 is a state feedback)::

    dx/dt = A(t) x + B(t) u + w(t),        x = (x1, x2),  u = (u1, u2)

Parameter perturbations (the thesis's "random disturbance")
----------------------------------------------------------
The thesis's C++ program draws a new plant at every step, each element of ``A_m, B_m, C_m``
moved by ``spread * (rand() % 2 - 0.5)`` (:data:`plants.column.SECTION_631_SPREAD`), and steps it
by forward Euler (5.1). Here draw ``k`` is the ``k``-th call of
:meth:`plants.column.PerturbedReducedPlant.draw` on ``np.random.default_rng(seed)`` (twelve signs
``a11 ... b22, c11 ... c22``; the four of ``C`` perturb only the thesis's outputs ``y = C x``,
which no loop measures, and are discarded), so ``A_k, B_k`` are exactly the matrices of
``PerturbedReducedPlant(np.random.default_rng(seed))`` after ``k`` draws, the plants that
``bench/mrac_study.py`` ``discrete_run(..., seed)`` steps through.

* ``redraw_period: null``: draw 0 for the whole run (``redraw="once"``: a fixed perturbed plant).
* ``redraw_period: P``: the plant passes through draw ``k`` at ``t = k P`` and moves linearly
  between draws. The thesis's matrices jump at every step; a jump cannot be integrated by the
  platform's fixed-step RK4 between events (a step ending at the jump would see the next plant),
  so the continuous-time plant ramps instead: at the sampling instants (with ``P`` the sampling
  period) it is the thesis's plant of that step, in between it varies continuously.

Additive disturbances
---------------------
``w_i(t) = d_std[i] * v_i(t)``, ``v_i`` unit Gaussian knots every ``d_period``, linearly
interpolated, drawn from ``np.random.default_rng([seed, 1 + i, chunk])`` in chunks of
:data:`CHUNK`. Like the parameter draws, a pure function of ``t``: every engine integrating the
same segments computes the same trajectory bit for bit, whatever order it evaluates ``rhs`` in.
Default off (``d_std = (0, 0)``).

Time in hours (the thesis's ``T = 0.1 h``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, field_validator

from plants.column import SECTION_631_SPREAD, THESIS_A_M, THESIS_B_M
from plants.knots import CHUNK, Knots

__all__ = ["CHUNK", "PerturbedReducedParams", "PerturbedReduced"]


Matrix2 = tuple[tuple[float, float], tuple[float, float]]


def _matrix(m: NDArray[np.float64]) -> Matrix2:
    return ((float(m[0, 0]), float(m[0, 1])), (float(m[1, 0]), float(m[1, 1])))


class PerturbedReducedParams(BaseModel):
    """Nominal matrices, perturbation seed and timing, disturbances (time in hours)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    A: Matrix2 = Field(default=_matrix(THESIS_A_M), description="nominal A, eq. (4.3)")
    B: Matrix2 = Field(default=_matrix(THESIS_B_M), description="nominal B, eq. (4.3)")
    seed: int = Field(default=0, ge=0, description="seed of the perturbations and disturbances")
    redraw_period: float | None = Field(
        default=None,
        gt=0,
        description="a new perturbation every redraw_period, ramped to (null: one for the run)",
    )
    d_std: tuple[float, float] = Field(
        default=(0.0, 0.0), description="standard deviation of the additive disturbance, per state"
    )
    d_period: float = Field(default=0.1, gt=0, description="spacing of the disturbance knots")

    @field_validator("A", "B")
    @classmethod
    def _finite(cls, v: Matrix2) -> Matrix2:
        if not all(math.isfinite(e) for row in v for e in row):
            raise ValueError(f"must be finite, got {v}")
        return v

    @field_validator("d_std")
    @classmethod
    def _non_negative(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(e) and e >= 0.0 for e in v):
            raise ValueError(f"standard deviations must be finite and >= 0, got {v}")
        return v


class _Draws:
    """``(A_k, B_k)`` as flat tuples, drawn in order from one generator and cached."""

    __slots__ = ("_rng", "_a", "_b", "_list")

    def __init__(self, params: PerturbedReducedParams) -> None:
        self._rng = np.random.default_rng(params.seed)
        self._a = np.array(params.A, dtype=float)
        self._b = np.array(params.B, dtype=float)
        self._list: list[tuple[tuple[float, ...], tuple[float, ...]]] = []

    def __getitem__(self, k: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
        while len(self._list) <= k:
            # the arithmetic of PerturbedReducedPlant.draw / set_signs
            s = self._rng.integers(0, 2, size=12) - 0.5
            a = self._a + SECTION_631_SPREAD["A"] * s[0:4].reshape(2, 2)
            b = self._b + SECTION_631_SPREAD["B"] * s[4:8].reshape(2, 2)
            self._list.append((tuple(a.ravel().tolist()), tuple(b.ravel().tolist())))
        return self._list[k]


class PerturbedReduced:
    """The plant object: ``rhs``, ``rhs_tuple``, ``outputs``, ``matrices``, ``disturbance``.

    Parameters
    ----------
    params : PerturbedReducedParams
        Nominal matrices, seed, redraw period, disturbances.
    """

    state_names: tuple[str, ...] = ("x1", "x2")
    input_names: tuple[str, ...] = ("u1", "u2")
    output_names: tuple[str, ...] = ("x1", "x2")

    def __init__(self, params: PerturbedReducedParams) -> None:
        self.params = p = params
        self._draws = _Draws(p)
        self._period = p.redraw_period
        self._d_std = p.d_std
        self._noisy = any(s > 0.0 for s in p.d_std)
        self._knots = (Knots(p.seed, 1), Knots(p.seed, 2))

    # -- time-varying parameters and disturbances ---------------------------------------------
    def _ab(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        if self._period is None:
            return self._draws[0]
        s = t / self._period
        k = max(math.floor(s), 0)
        f = s - k
        (a0, b0), (a1, b1) = self._draws[k], self._draws[k + 1]
        return (
            tuple(x + f * (y - x) for x, y in zip(a0, a1, strict=True)),
            tuple(x + f * (y - x) for x, y in zip(b0, b1, strict=True)),
        )

    def matrices(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(A(t), B(t))``: the perturbed plant at time ``t`` (hours)."""
        a, b = self._ab(t)
        return np.array(a).reshape(2, 2), np.array(b).reshape(2, 2)

    def disturbance(self, t: float) -> tuple[float, float]:
        """``w(t)``: the additive disturbance at time ``t``."""
        if not self._noisy:
            return (0.0, 0.0)
        s = t / self.params.d_period
        k = max(math.floor(s), 0)
        f = s - k
        out = []
        for std, knots in zip(self._d_std, self._knots, strict=True):
            v0, v1 = knots[k], knots[k + 1]
            out.append(std * (v0 + f * (v1 - v0)))
        return (out[0], out[1])

    # -- dynamics -------------------------------------------------------------------------------
    def rhs_tuple(self, t: float, x: Sequence[float], u: Sequence[float]) -> tuple[float, ...]:
        """``A(t) x + B(t) u + w(t)`` on plain floats (what the fixed-step integrator calls)."""
        a, b = self._ab(t)
        w1, w2 = self.disturbance(t)
        x1, x2 = x
        u1, u2 = u
        return (
            a[0] * x1 + a[1] * x2 + b[0] * u1 + b[1] * u2 + w1,
            a[2] * x1 + a[3] * x2 + b[2] * u1 + b[3] * u2 + w2,
        )

    def rhs(self, t: float, x: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`rhs_tuple` on arrays."""
        return np.array(self.rhs_tuple(t, tuple(x.tolist()), tuple(u.tolist())))

    def outputs(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The measured states ``(x1, x2)``."""
        return np.array(x, dtype=float)
