"""Which kind of non-stationary record the Harris index refuses: drift, integrating or manual.

The index needs the variance of a stationary record. :func:`agents.monitor.timeseries.fit_var`
(with ``oscillation_ok``) refuses a record whose AR model has a *slow* root near the unit circle
(period longer than N/10 samples); sustained oscillations are kept. :func:`classify` then names
the cause, so that the engineer knows what to do:

* ``drift`` -- the record minus its least-squares straight line is clearly stationary (its AR
  fit's slowest root ``rho`` has ``N (1 - rho) > 40``): a deterministic trend (a fouling
  exchanger, a slowly moving operating point). A detrended random walk often passes the fit's
  own limit ``N (1 - rho) > 10`` but not this one (measured over 40 seeds at N = 751 and 5000:
  ``N (1 - rho) <= 28``; a line plus AR(1) noise of pole 0.9: 75-540);
* ``integrating`` -- detrending does not help: a unit root (a random-walk disturbance, an
  integrating process without feedback, set-point moves analysed on the PV alone);
* ``manual`` -- integrating while the controller output (``op``) does not move (constant, or
  frozen over ``manual_share`` of the record): the loop is in manual.

``diverging`` (the spread grows a hundredfold, :func:`agents.monitor.errors.check_not_diverging`)
is classified before any model is fitted.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.monitor.errors import IdentificationError
from agents.monitor.timeseries import Criterion, fit_var

__all__ = ["detrend", "classify", "op_is_still"]

_DRIFT_SAMPLES = 40.0


def detrend(y: NDArray[np.float64]) -> tuple[NDArray[np.float64], float, float]:
    """``y`` minus its least-squares line; the slope per sample and the share of the variance
    the line explains."""
    y = np.asarray(y, dtype=float).ravel()
    t = np.arange(y.size, dtype=float)
    slope, icpt = np.polyfit(t, y, 1)
    resid = y - (slope * t + icpt)
    var = float(np.var(y))
    share = 1.0 - float(np.var(resid)) / var if var > 0 else 0.0
    return resid, float(slope), share


def op_is_still(op: NDArray[np.float64] | None, *, share: float = 0.9) -> bool:
    """Whether the controller output does not move: constant, or its increments zero over
    ``share`` of the record."""
    if op is None or np.asarray(op).size < 2:
        return False
    op = np.asarray(op, dtype=float)
    if np.ptp(op) == 0.0:
        return True
    return float(np.mean(np.diff(op) == 0.0)) >= share


def classify(
    y: NDArray[np.float64],
    *,
    op: NDArray[np.float64] | None = None,
    order: int | None = None,
    max_order: int = 30,
    criterion: Criterion = "aic",
    name: str = "y",
) -> tuple[str, str]:
    """Kind (``drift``, ``integrating``, ``manual``) and explanation of a record whose AR model
    has a slow root near 1 (module docstring).

    Parameters
    ----------
    y : ndarray
        The refused record.
    op : ndarray, optional
        The controller output over the same rows (tells ``manual`` from ``integrating``).
    order, max_order, criterion
        The model settings the refusal used.
    name : str
        Series name for the explanation.
    """
    y = np.asarray(y, dtype=float).ravel()
    resid, slope, share = detrend(y)
    try:
        model = fit_var(
            resid,
            order=order,
            max_order=max_order,
            criterion=criterion,
            names=(name,),
            oscillation_ok=True,
        )
    except IdentificationError:
        model = None
    if model is not None and y.size * (1.0 - model.spectral_radius()) > _DRIFT_SAMPLES:
        return "drift", (
            f"{name!r} drifts by {slope:.3g} per sample ({100 * share:.0f} % of its variance "
            "is the straight line); detrended it is stationary"
        )
    if op_is_still(op):
        return "manual", (
            f"{name!r} wanders like an integrating series while the controller output does not "
            "move: the loop is in manual (or the output is clamped)"
        )
    return "integrating", (
        f"{name!r} has a unit root near z = 1 that detrending does not remove (integrating "
        "disturbance or process, set-point moves, or a loop in manual)"
    )
