"""Fixed-step Runge-Kutta integration between events.

Plants are integrated from one event to the next (a sample, a monitoring instant, an input
change) with the classical fourth-order Runge-Kutta method on ``n = ceil(span / max_step)`` equal
steps. The result depends only on the segment's end points, the state and the held input, so every
engine that stops at the same instants computes the same trajectory bit for bit, and it is much
cheaper per call than an adaptive solver. Accuracy is checked against ``scipy.integrate.solve_ivp``
at tight tolerances in ``tests/unit/test_integrate.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["rk4", "rk4_tuple", "integrator_of"]

Rhs = Callable[[float, NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


def rk4(
    f: Rhs,
    t0: float,
    x0: NDArray[np.float64],
    t1: float,
    u: NDArray[np.float64],
    *,
    max_step: float,
) -> NDArray[np.float64]:
    """Integrate ``dx/dt = f(t, x, u)`` from ``t0`` to ``t1`` with ``u`` held constant.

    Parameters
    ----------
    f : callable
        Right-hand side ``f(t, x, u)``.
    t0, t1 : float
        Segment ends; ``t1 <= t0`` returns a copy of ``x0`` unchanged.
    x0 : ndarray
        State at ``t0``.
    u : ndarray
        Input held over the segment (zero-order hold).
    max_step : float
        Largest step; the segment is cut into equal steps no longer than this.

    Returns
    -------
    ndarray
        State at ``t1``.
    """
    span = t1 - t0
    x = np.array(x0, dtype=float)
    if span <= 0.0:
        return x
    n = max(1, math.ceil(span / max_step - 1e-9))
    h = span / n
    half = 0.5 * h
    for i in range(n):
        t = t0 + i * h
        k1 = f(t, x, u)
        k2 = f(t + half, x + half * k1, u)
        k3 = f(t + half, x + half * k2, u)
        k4 = f(t + h, x + h * k3, u)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


TupleRhs = Callable[[float, tuple[float, ...], tuple[float, ...]], tuple[float, ...]]


def rk4_tuple(
    f: TupleRhs,
    t0: float,
    x0: tuple[float, ...],
    t1: float,
    u: tuple[float, ...],
    *,
    max_step: float,
) -> tuple[float, ...]:
    """:func:`rk4` on tuples of Python floats, for plants with a few states.

    The same steps and the same arithmetic, element by element, as :func:`rk4` (IEEE float64
    either way), so the result is bit-identical; without numpy's per-call overhead it is several
    times faster for small systems.
    """
    span = t1 - t0
    x = tuple(x0)
    if span <= 0.0:
        return x
    n = max(1, math.ceil(span / max_step - 1e-9))
    h = span / n
    half = 0.5 * h
    sixth = h / 6.0
    for i in range(n):
        t = t0 + i * h
        k1 = f(t, x, u)
        k2 = f(t + half, tuple(a + half * b for a, b in zip(x, k1, strict=True)), u)
        k3 = f(t + half, tuple(a + half * b for a, b in zip(x, k2, strict=True)), u)
        k4 = f(t + h, tuple(a + h * b for a, b in zip(x, k3, strict=True)), u)
        x = tuple(
            a + sixth * (b + 2.0 * c + 2.0 * d + e)
            for a, b, c, d, e in zip(x, k1, k2, k3, k4, strict=True)
        )
    return x


def integrator_of(model: object) -> Callable[..., NDArray[np.float64]]:
    """``step(t0, x0, t1, u, max_step=...) -> x1`` for a plant model.

    Uses the model's ``rhs_tuple`` (plain floats) when it has one, else its ``rhs`` (numpy).
    Both give the same numbers; every engine integrates through this function.
    """
    rhs_tuple = getattr(model, "rhs_tuple", None)
    if rhs_tuple is None:
        rhs = model.rhs  # type: ignore[attr-defined]

        def step(
            t0: float,
            x0: NDArray[np.float64],
            t1: float,
            u: NDArray[np.float64],
            *,
            max_step: float,
        ) -> NDArray[np.float64]:
            return rk4(rhs, t0, x0, t1, u, max_step=max_step)

        return step

    def step_tuple(
        t0: float, x0: NDArray[np.float64], t1: float, u: NDArray[np.float64], *, max_step: float
    ) -> NDArray[np.float64]:
        x = rk4_tuple(rhs_tuple, t0, tuple(x0.tolist()), t1, tuple(u.tolist()), max_step=max_step)
        return np.array(x)

    return step_tuple
