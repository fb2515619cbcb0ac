"""Step-response figures of a loop: overshoot %, 2 % settling time, IAE.

Computed from the plant's true output on its monitoring grid (the paper reads its overshoots off
the continuous responses of Fig. 3-8), per set-point step, over the window from the step to the
loop's next step or the end of the run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["StepMetrics", "step_metrics", "iae"]

SETTLING_BAND = 0.02
"""Settling band as a fraction of the step size."""


@dataclass(frozen=True)
class StepMetrics:
    """Figures of one set-point step (times in scenario units)."""

    t: float
    r_from: float
    r_to: float
    overshoot_pct: float
    settling_time: float | None
    iae: float


def _trapz(y: np.ndarray, t: np.ndarray) -> float:
    if len(t) < 2:
        return 0.0
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


def step_metrics(
    t: np.ndarray,
    y: np.ndarray,
    *,
    t_step: float,
    t_end: float,
    r_from: float,
    r_to: float,
    band: float = SETTLING_BAND,
) -> StepMetrics:
    """Overshoot, settling time and IAE of the response ``y(t)`` to a step at ``t_step``.

    Parameters
    ----------
    t, y : ndarray
        The output on a time grid (scenario units).
    t_step, t_end : float
        The window: from the step to the next step of the same loop, or the end of the run.
    r_from, r_to : float
        Set point before and after the step.
    band : float
        Settling band as a fraction of the step size (2 % by default).

    Returns
    -------
    StepMetrics
        ``overshoot_pct = 100 max(0, max sign (y - r_to)) / |r_to - r_from|``;
        ``settling_time`` from the step until ``y`` stays within ``band`` of the step size of
        ``r_to`` to the end of the window (``None`` if it never does);
        ``iae`` the integral of ``|r_to - y|`` over the window.
    """
    size = r_to - r_from
    if size == 0.0:
        raise ValueError("step_metrics: a step of size zero has no overshoot")
    mask = (t >= t_step) & (t <= t_end)
    tw, yw = t[mask], y[mask]
    if len(tw) == 0:
        return StepMetrics(t_step, r_from, r_to, 0.0, None, 0.0)
    sign = 1.0 if size > 0 else -1.0
    overshoot = max(0.0, float(np.max(sign * (yw - r_to)))) / abs(size) * 100.0
    outside = np.nonzero(np.abs(yw - r_to) > band * abs(size))[0]
    if len(outside) == 0:
        settling: float | None = 0.0
    elif outside[-1] == len(tw) - 1:
        settling = None
    else:
        settling = float(tw[outside[-1] + 1] - t_step)
    return StepMetrics(t_step, r_from, r_to, overshoot, settling, _trapz(np.abs(r_to - yw), tw))


def iae(t: np.ndarray, y: np.ndarray, r: Sequence[float] | np.ndarray) -> float:
    """Integral of ``|r - y|`` over the grid ``t`` (trapezoid rule)."""
    return _trapz(np.abs(np.asarray(r, dtype=float) - y), t)
