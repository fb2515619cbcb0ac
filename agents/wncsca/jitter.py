"""The jitter margin of each loop: the largest delay variation for which stability is guaranteed,
whatever the simulations say (issue 14, item 3).

Kao and Lincoln (2004), "Simple stability criteria for systems with time-varying delays",
Automatica 40(8), Theorem 1 (also Cervin et al. 2004, "The jitter margin and its application in
the design of real-time control systems"): a loop ``L(s) e^{-s L_0}`` that is stable with its
nominal delay ``L_0`` stays stable for every time-varying extra delay ``0 <= delta(t) <= J`` if::

    |T(jw)| < 1 / (J w)   for all w > 0,     T = L e^{-s L_0} / (1 + L e^{-s L_0})

so the **jitter margin** is ``J_m = 1 / sup_w w |T(jw)|`` (:func:`jitter_margin`). For a loop
``k / s`` the margin is exactly ``1 / k`` (the supremum is reached as ``w -> inf``).

For the agent's loops (:func:`loop_margins`) the plant is linearised at the equilibrium of the
test's final set points (:class:`agents.wncsca.fast.LinearPredictor`'s plant data), the laws
taken in continuous time by their feedback from the measurement (``k_y + k_i / s`` of
:class:`agents.wncsca.laws.LinearForm`: ``Kp + Ki / s`` for the PI), and each loop is broken at
its own input with the other loops of its plant closed (each with its nominal delay):
``L_i = C_i (G_ii - G_ij C_j G_ji / (1 + C_j G_jj e^{-s L_j}) e^{-s L_j})`` for two loops, in
general by the matrix identity below. The nominal delay of loop ``i`` is the shortest
control-path delay of its distribution; the variation it must tolerate (:func:`delay_variation`)
is its delay spread up to the 0.999 quantile, plus the sample-and-hold's (one period: a sample's
age at the controller's next execution varies over ``[0, h)``), plus one period per consecutive
loss with probability at least 1e-3.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.wncsca.chance import LoopLaw
from agents.wncsca.fast import LinearPredictor
from agents.wncsca.model import LoopModel

__all__ = ["FREQUENCIES", "jitter_margin", "delay_variation", "loop_margins"]

FREQUENCIES = np.logspace(-4, 4, 4000)
"""Frequencies (rad per time unit) at which the supremum is taken."""

_RARE = 1e-3  # a burst of losses less likely than this per sample is ignored


def jitter_margin(T: NDArray[np.complex128], w: NDArray[np.float64]) -> float:
    """``1 / sup_w w |T(jw)|`` from the complementary sensitivity ``T`` at frequencies ``w``."""
    peak = float(np.max(w * np.abs(T)))
    return math.inf if peak <= 0 else 1.0 / peak


def delay_variation(law: LoopLaw, mean: float, period: float) -> tuple[float, float]:
    """``(nominal, variation)`` of a loop's control-path delay with distribution shape ``law``
    located at ``mean`` and sampling ``period`` (module docstring)."""
    shift = mean - law.mean
    low = max(0.0, law.delays[0] + shift)
    high = max(0.0, float(np.interp(0.999, law.probabilities, law.delays)) + shift)
    bursts = 0
    if law.loss > 0:
        while law.loss ** (bursts + 1) >= _RARE:
            bursts += 1
    return low, (high - low) + period + bursts * period


def loop_margins(
    model: LoopModel,
    periods: Mapping[str, float],
    delays: Mapping[str, float],
    laws: Mapping[str, LoopLaw],
    w: NDArray[np.float64] = FREQUENCIES,
) -> dict[str, dict[str, Any]]:
    """Per loop: its jitter margin, the delay variation it must tolerate, and whether it does
    (``ok``); ``margin`` is 0 when the loop is not stable at its nominal delay (Nyquist: the
    closed loop's characteristic function winds, checked by the phase of ``1 + L``)."""
    lin = LinearPredictor(model, {})
    out: dict[str, dict[str, Any]] = {}
    final = dict(lin.initial)
    for _, loop, value in sorted(lin.steps):
        final[loop] = value
    for plant in lin.plants.values():
        names = plant.loops
        A, B, Cy, *_ = plant.linearization(tuple(final[n] for n in names))
        rows = [plant.y_index[n] for n in names]
        cols = [plant.u_index[n] for n in names]
        nominal: dict[str, float] = {}
        variation: dict[str, float] = {}
        for n in names:
            law = laws.get(n, LoopLaw())
            nominal[n], variation[n] = delay_variation(law, float(delays.get(n, 0.0)), periods[n])
        s = 1j * w
        eye = np.eye(A.shape[0])
        G = np.stack([Cy[rows] @ np.linalg.solve(si * eye - A, B[:, cols]) for si in s])
        y_start = np.asarray(plant.model.outputs(plant.x0), dtype=float)
        forms = [lin.laws[n].linear(final[n], float(y_start[plant.y_index[n]])) for n in names]
        C = np.stack([np.array([f.k_y + f.k_i / si for f in forms]) for si in s])
        D = np.stack([np.exp(-s * nominal[n]) for n in names], axis=1)  # (w, loops)
        for i, n in enumerate(names):
            # break loop i at its input: the others closed, u_i -> y -> u_i
            Li = np.empty(len(w), dtype=complex)
            for k in range(len(w)):
                others = [j for j in range(len(names)) if j != i]
                g = G[k]
                if others:
                    Ko = np.diag(C[k, others] * D[k, others])
                    Goo = g[np.ix_(others, others)]
                    closed = np.linalg.solve(np.eye(len(others)) + Ko @ Goo, Ko)
                    gii = g[i, i] - g[i, others] @ closed @ g[others, i]
                else:
                    gii = g[i, i]
                Li[k] = C[k, i] * gii
            Lw = Li * D[:, i]
            T = Lw / (1.0 + Lw)
            margin = jitter_margin(T, w)
            out[n] = {
                "margin": margin,
                "nominal_delay": nominal[n],
                "variation": variation[n],
                "ok": variation[n] < margin,
            }
    return out
