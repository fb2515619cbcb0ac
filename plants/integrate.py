"""Fixed-step Runge-Kutta integration between events.

Plants are integrated from one event to the next (a sample, a monitoring instant, an input
change) with the classical fourth-order Runge-Kutta method on ``n = ceil(span / max_step)`` equal
steps. The result depends only on the segment's end points, the state and the held input, so every
engine that stops at the same instants computes the same trajectory bit for bit, and it is much
cheaper per call than an adaptive solver. Accuracy is checked against ``scipy.integrate.solve_ivp``
at tight tolerances in ``tests/unit/test_integrate.py``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

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


TupleRhs = Callable[[float, Sequence[float], Sequence[float]], Sequence[float]]


def rk4_tuple(
    f: TupleRhs,
    t0: float,
    x0: Sequence[float],
    t1: float,
    u: tuple[float, ...],
    *,
    max_step: float,
) -> tuple[float, ...]:
    """:func:`rk4` on tuples of Python floats, for plants with a few states.

    The same steps and the same arithmetic, element by element, as :func:`rk4` (IEEE float64
    either way), so the result is bit-identical; without numpy's per-call overhead it is several
    times faster for small systems. The steps run in a loop written out for the state's
    dimension (:func:`_unrolled`).
    """
    span = t1 - t0
    x = tuple(x0)
    if span <= 0.0 or not x:
        return x
    n = max(1, math.ceil(span / max_step - 1e-9))
    h = span / n
    return _unrolled(len(x))(f, t0, x, u, n, h, 0.5 * h, h / 6.0)


_Steps = Callable[
    [TupleRhs, float, tuple[float, ...], tuple[float, ...], int, float, float, float],
    tuple[float, ...],
]


@functools.cache
def _unrolled(dim: int) -> _Steps:
    """``steps(f, t0, x, u, n, h, half, sixth)``: ``n`` RK4 steps of a ``dim``-state system, each
    state a local variable.

    Element-wise loops over a few floats (``[a + half * b for a, b in zip(x, k)]``) cost about
    four times the arithmetic they do in CPython; the written-out loop does the same operations
    in the same order (so the same bits) without them. The source is generated once per
    dimension, like :mod:`dataclasses` generates ``__init__``.
    """
    xs = [f"x{i}" for i in range(dim)]
    tup = "(" + "".join(f"{v}, " for v in xs) + ")"

    def stage(c: str, k: str) -> str:
        return "(" + "".join(f"x{i} + {c} * {k}{i}, " for i in range(dim)) + ")"

    def names(k: str) -> str:
        return "".join(f"{k}{i}, " for i in range(dim))

    new_x = "".join(
        f"        x{i} = x{i} + sixth * (a{i} + 2.0 * b{i} + 2.0 * c{i} + d{i})\n"
        for i in range(dim)
    )
    source = (
        "def steps(f, t0, x, u, n, h, half, sixth):\n"
        f"    {names('x')}= x\n"
        "    for i in range(n):\n"
        "        t = t0 + i * h\n"
        f"        {names('a')}= f(t, {tup}, u)\n"
        f"        {names('b')}= f(t + half, {stage('half', 'a')}, u)\n"
        f"        {names('c')}= f(t + half, {stage('half', 'b')}, u)\n"
        f"        {names('d')}= f(t + h, {stage('h', 'c')}, u)\n"
        f"{new_x}"
        f"    return {tup}\n"
    )
    scope: dict[str, _Steps] = {}
    exec(compile(source, f"<rk4 steps, {dim} states>", "exec"), scope)  # noqa: S102
    return scope["steps"]


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
