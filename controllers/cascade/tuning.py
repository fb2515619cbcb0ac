"""Variance-optimal tuning of seed 004's laws on the analytic model, and the examples' settings.

:func:`tune_sfb_pi` and :func:`tune_pi_p` minimize the analytic variance of the measured primary
(:func:`plants.cascade.variance.output_variance`) over ``(Kc, Ti)`` and ``(Kc1, Ti1, Kc2)`` by
Nelder-Mead: the paper's "PI achievable performance" for the SFB loop and "best CLPI achieved"
with the PI-P cascade (its Examples 1-2). The settings shipped for the examples
(:data:`EXAMPLE_SFB`, :data:`EXAMPLE_CASCADE`) are those optima, rounded
(``bench/monitor_examples.py --retune`` recomputes them). A variance-optimal PI-P is as tight as
a PI-P gets, so the cascade approaches its invariant bound (component 1a) as closely as the
restricted structure allows; it ignores the variance of ``u`` and robustness, like the paper.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize

from controllers.cascade.model import PIPCascadeConfig, SFBPIConfig, pi_tf
from plants.cascade.model import CascadeProcessConfig
from plants.cascade.transfer import TF
from plants.cascade.variance import output_variance

__all__ = ["tune_sfb_pi", "tune_pi_p", "EXAMPLE_SFB", "EXAMPLE_CASCADE"]

_PENALTY = 1e300


def _optimize(fun, grid: Sequence[Sequence[float]], n_starts: int = 3) -> tuple[np.ndarray, float]:
    """Nelder-Mead in log-parameters from the best ``n_starts`` points of a coarse grid (the
    variance surface of restricted-structure controllers has several local minima)."""
    pts = np.array(np.meshgrid(*[np.log(np.asarray(g, dtype=float)) for g in grid])).reshape(
        len(grid), -1
    )
    vals = np.array([fun(pts[:, i]) for i in range(pts.shape[1])])
    best_x, best_f = None, math.inf
    for i in np.argsort(vals)[:n_starts]:
        res = minimize(
            fun,
            pts[:, i],
            method="Nelder-Mead",
            options={"xatol": 1e-4, "fatol": 1e-10, "maxiter": 4000, "maxfev": 8000},
        )
        if res.fun < best_f:
            best_x, best_f = res.x, float(res.fun)
    return np.exp(best_x), best_f


def tune_sfb_pi(process: CascadeProcessConfig) -> tuple[SFBPIConfig, float]:
    """PI on the primary minimizing the analytic variance of the measured primary.

    Returns the configuration and the variance it achieves. ``Kc`` is searched positive (the
    examples have positive process gains); multi-start Nelder-Mead in ``log(Kc), log(Ti)``.
    """
    primary, dt = process.primary, process.dt

    def fun(x: np.ndarray) -> float:
        kc, ti = np.exp(x)
        v = output_variance(process, {primary: pi_tf(kc, ti, dt)})
        return v if math.isfinite(v) else _PENALTY

    grid = ([0.1, 0.3, 1.0, 3.0], [dt * t for t in (3.0, 10.0, 30.0, 100.0)])
    (kc, ti), var = _optimize(fun, grid)
    return SFBPIConfig(measurement=primary, Kc=float(kc), Ti=float(ti), dt=dt), var


def tune_pi_p(process: CascadeProcessConfig, secondary: str) -> tuple[PIPCascadeConfig, float]:
    """PI-P cascade minimizing the analytic variance of the measured primary (best CLPI);
    multi-start Nelder-Mead in ``log(Kc1), log(Ti1), log(Kc2)``."""
    primary, dt = process.primary, process.dt

    def fun(x: np.ndarray) -> float:
        kc1, ti1, kc2 = np.exp(x)
        cfg = {secondary: TF([kc2]), primary: pi_tf(kc1, ti1, dt) * kc2}
        v = output_variance(process, cfg)
        return v if math.isfinite(v) else _PENALTY

    grid = ([0.1, 0.3, 1.0, 3.0], [dt * t for t in (3.0, 10.0, 30.0, 100.0)], [0.3, 1, 3, 10])
    (kc1, ti1, kc2), var = _optimize(fun, grid)
    cfg = PIPCascadeConfig(
        primary=primary,
        secondary=secondary,
        Kc1=float(kc1),
        Ti1=float(ti1),
        Kc2=float(kc2),
        dt=dt,
    )
    return cfg, var


# Settings for plants.cascade.examples.EXAMPLE_1..3 (variance-optimal, rounded; see module doc).
EXAMPLE_SFB: dict[str, SFBPIConfig] = {
    "example_1": SFBPIConfig(measurement="y1", Kc=1.75, Ti=36.1),
    "example_2": SFBPIConfig(measurement="y1", Kc=0.886, Ti=25.0),
    "example_3": SFBPIConfig(measurement="y1", Kc=1.41, Ti=83.8),
}
"""Variance-optimal PI of each example's simple-feedback loop (the loop the monitor analyses)."""

EXAMPLE_CASCADE: dict[str, dict[str, PIPCascadeConfig]] = {
    "example_1": {
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.87, Ti1=27.6, Kc2=4.05),
    },
    "example_2": {
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.13, Ti1=18.6, Kc2=3.82),
    },
    "example_3": {
        "y3": PIPCascadeConfig(primary="y1", secondary="y3", Kc1=1.88, Ti1=44.3, Kc2=3.92),
        "y2": PIPCascadeConfig(primary="y1", secondary="y2", Kc1=1.51, Ti1=27.5, Kc2=3.29),
    },
}
"""Variance-optimal PI-P cascade of each example for each candidate secondary."""
