"""Operating points and small-signal models of any plant (``rhs``, ``outputs``), by numerics.

A plant that knows its own equilibrium (``equilibrium(y_bar)``, e.g. seed 000 eq. (5)-(7) for the
JCSTR) or its own Jacobians (``linearize(x, u)``) is asked first; otherwise the equilibrium is a
root solve of ``f(x, u) = 0, y(x) = y_bar`` over the state and the loops' inputs, and the
Jacobians are central differences. The coordination agent's fast method
(:mod:`agents.wncsca.fast`) and the notebook API's :func:`wncs.linearized_loop` both use these.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

if TYPE_CHECKING:
    import control

__all__ = ["equilibrium", "jacobians", "linearize"]


def equilibrium(
    model: Any,
    y_bar: Mapping[str, float],
    x0: NDArray[np.float64],
    u0: NDArray[np.float64],
    free: Sequence[int],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """State and input ``(x_bar, u_bar)`` that hold the outputs named in ``y_bar``.

    The plant's own ``equilibrium(y_bar)`` when it has one and it succeeds; otherwise a root solve
    of ``rhs(0, x, u) = 0`` and ``outputs(x)[y] = y_bar[y]``, with the inputs at indices ``free``
    (one per held output: the loops' actuators) unknown, the others at ``u0``, started from
    ``(x0, u0)``.
    """
    if hasattr(model, "equilibrium"):
        try:
            x, u = model.equilibrium(y_bar)
            return np.asarray(x, dtype=float), np.asarray(u, dtype=float)
        except ValueError:
            pass
    free = list(free)
    nx = len(x0)
    ys = [model.output_names.index(name) for name in y_bar]
    target = np.array(list(y_bar.values()))

    def residual(z: NDArray[np.float64]) -> NDArray[np.float64]:
        x, u = z[:nx], u0.copy()
        u[free] = z[nx:]
        y = np.asarray(model.outputs(x), dtype=float)[ys]
        return np.concatenate([model.rhs(0.0, x, u), y - target])

    sol = scipy.optimize.root(residual, np.concatenate([x0, u0[free]]))
    x, u = sol.x[:nx], u0.copy()
    u[free] = sol.x[nx:]
    return x, u


def jacobians(
    model: Any, x: NDArray[np.float64], u: NDArray[np.float64]
) -> tuple[NDArray[np.float64], ...]:
    """``df/dx``, ``df/du`` and ``dy/dx`` at ``(x, u)`` by central differences."""

    def f(xx: NDArray[np.float64], uu: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(model.rhs(0.0, xx, uu), dtype=float)

    def g(xx: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(model.outputs(xx), dtype=float)

    nx, nu = len(x), len(u)
    A = np.zeros((nx, nx))
    Cy = np.zeros((len(g(x)), nx))
    for k in range(nx):
        d = 1e-6 * max(1.0, abs(x[k]))
        e = np.zeros(nx)
        e[k] = d
        A[:, k] = (f(x + e, u) - f(x - e, u)) / (2 * d)
        Cy[:, k] = (g(x + e) - g(x - e)) / (2 * d)
    B = np.zeros((nx, nu))
    for k in range(nu):
        d = 1e-6 * max(1.0, abs(u[k]))
        e = np.zeros(nu)
        e[k] = d
        B[:, k] = (f(x, u + e) - f(x, u - e)) / (2 * d)
    return A, B, Cy


def linearize(model: Any, x: NDArray[np.float64], u: NDArray[np.float64]) -> control.StateSpace:
    """The small-signal model at ``(x, u)`` as a continuous ``control.StateSpace`` in deviation
    variables, with the plant's state, input and output names: the plant's own (analytic)
    ``linearize`` when it has one, else :func:`jacobians`."""
    import control

    if hasattr(model, "linearize"):
        sys = model.linearize(x, u)
        if isinstance(sys, control.StateSpace):
            return sys
    A, B, Cy = jacobians(model, np.asarray(x, dtype=float), np.asarray(u, dtype=float))
    return control.ss(
        A,
        B,
        Cy,
        np.zeros((Cy.shape[0], B.shape[1])),
        states=list(model.state_names),
        inputs=list(model.input_names),
        outputs=list(model.output_names),
    )
