"""Harris (minimum-variance) performance index from routine data and the loop delay.

Harris (1989), as used in seed 004 ("Theory", eq. (3) and (7); its "CLPI"): under feedback
with ``d`` samples of dead time from ``u`` to ``y``, the first ``d`` impulse-response coefficients
of the closed-loop output ``y_t = sum_i psi_i e_(t-i)`` (``psi_0 = 1``, ``e`` the innovations)
do not depend on the controller. Hence the minimum variance and the index::

    sigma2_mv = sigma2_e (psi_0^2 + ... + psi_(d-1)^2)
    eta       = sigma2_mv / sigma2_y                   (1: minimum-variance control; -> 0: poor)

``psi`` and ``sigma2_e`` come from an AR model of the routine output (least squares, order by
AIC/BIC, :func:`agents.monitor.timeseries.fit_var`), ``sigma2_y`` is the sample variance.

Uncertainty (the index is fragile: it depends on the tail of a fitted model and on ``d``):

* ``"delta"`` (default): the delta method on ``eta(theta) = sum_(i<d) psi_i^2 / sum_i psi_i^2``
  (the model's own ratio) with the least-squares covariance ``sigma2_e (X'X)^-1`` of the AR
  coefficients ``theta``; gradient by central differences. Cheap, symmetric, local.
* ``"bootstrap"``: parametric (sieve) bootstrap: ``n_boot`` series of the fitted AR driven by
  residuals resampled with a seeded ``np.random.Generator``, each refitted at the same order; the
  standard deviation and percentile interval of the re-estimated index.

The interval is that of the estimator: its lower end clipped at 0, its upper end never clipped,
so it is never inverted and always holds the index (delta method). The index itself may exceed
1 -- estimation noise around a loop at minimum variance (``above_one``), or, when the whole
interval lies above 1, a delay ``d`` larger than the loop's.

Sustained oscillations (limit cycles). The AR model is fitted with ``oscillation_ok``
(:mod:`agents.monitor.timeseries`): a record whose model has roots on the unit circle at a period
shorter than N/10 samples is assessed, not refused; only slow roots (drift, integrating, manual,
named by :func:`agents.monitor.stationarity.classify`) are refused. For such a model
(``oscillating_model``) ``psi_0 ... psi_(d-1)`` and ``sigma2_e`` are still well defined and the
index is that of the data, ``sigma2_mv / var(y)`` with the sample variance, which ten or more
cycles estimate well. Caveat: the limit cycle counts entirely as variance a minimum-variance
controller would remove (it is predictable d samples ahead), so the index measures how far the
oscillating loop is from minimum variance, not what retuning alone can gain if the cycle comes
from the valve (stiction). The model's own ratio and the delta method on it are undefined for a
root on the circle; the standard error is then the delta method on the numerator
``sigma2_e sum_(i<d) psi_i^2`` alone (coefficients and ``sigma2_e``, whose variance is
``2 sigma2_e^2 / (N - p)``), the sample variance held fixed (``uncertainty =
"delta_numerator"``, also when a bootstrap was asked for: an explosive model cannot be resampled).

:func:`harris_index` reports the index, its standard error, an interval, the AR order and the
minimum variance.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from agents.monitor.errors import IdentificationError, check_not_diverging
from agents.monitor.stationarity import classify
from agents.monitor.timeseries import Criterion, VARModel, fit_var, lagged, near_unit_roots

__all__ = ["HarrisResult", "harris_index", "model_index"]


@dataclass(frozen=True)
class HarrisResult:
    """Harris index of one loop.

    Attributes
    ----------
    index : float
        ``sigma2_mv / sigma2_y`` (sample variance).
    std : float
        Standard error of the index (delta method or bootstrap).
    ci : tuple of float
        Interval at ``confidence`` (lower end clipped at 0; never inverted).
    confidence : float
        Confidence level of ``ci``.
    sigma2_mv : float
        Minimum variance (feedback-invariant part).
    variance : float
        Sample variance of the output.
    model_index : float
        The fitted model's own ratio ``sum_(i<d) psi_i^2 / sum_i psi_i^2``.
    delay : int
        ``d`` used, samples.
    order : int
        AR order used.
    n : int
        Samples.
    uncertainty : str
        ``"delta"``, ``"bootstrap"`` or ``"delta_numerator"`` (oscillating model).
    psi : tuple of float
        ``psi_0 ... psi_(d-1)``.
    oscillating_model : bool
        The AR model has roots near the unit circle at ``model_period`` (a sustained
        oscillation); the index is that of the data (module docstring).
    model_period : float or None
        Period of the model's dominant near-unit root, samples.
    above_one : bool
        The index exceeds 1 (estimation noise, or a delay larger than the loop's).
    """

    index: float
    std: float
    ci: tuple[float, float]
    confidence: float
    sigma2_mv: float
    variance: float
    model_index: float
    delay: int
    order: int
    n: int
    uncertainty: str
    psi: tuple[float, ...]
    oscillating_model: bool = False
    model_period: float | None = None
    above_one: bool = False

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        d = asdict(self)
        d["ci"] = list(self.ci)
        d["psi"] = list(self.psi)
        return d


def model_index(coefs: NDArray[np.float64], delay: int) -> float:
    """``sum_(i<d) psi_i^2 / sum_(i>=0) psi_i^2`` of the AR(p) ``a_1 ... a_p`` (nan if unstable)."""
    p = coefs.size
    m = VARModel(
        coefs=np.asarray(coefs, dtype=float).reshape(p, 1, 1),
        sigma=np.eye(1),
        order=p,
        n_obs=0,
        method="ls",
    )
    if m.spectral_radius() >= 1.0 - 1e-9:
        return math.nan
    head = float(np.sum(m.impulse(delay)[:, 0, 0] ** 2))
    return head / m.response_energy(np.ones(1))


def harris_index(
    y: NDArray[np.float64],
    delay: int,
    *,
    order: int | None = None,
    max_order: int = 30,
    criterion: Criterion = "aic",
    uncertainty: Literal["delta", "bootstrap"] = "delta",
    n_boot: int = 200,
    rng: np.random.Generator | None = None,
    confidence: float = 0.95,
    name: str = "y",
    op: NDArray[np.float64] | None = None,
) -> HarrisResult:
    """Harris index of a routine output (or control error) and its uncertainty.

    Parameters
    ----------
    y : ndarray
        Routine closed-loop output, or the control error ``r - y`` if the set point moved.
    delay : int
        Dead time ``d >= 1`` from the manipulated variable to ``y``, samples (for a cascade
        process, ``d1 + d2``).
    order, max_order, criterion
        AR order (fixed) or its selection (see :func:`agents.monitor.timeseries.fit_var`).
    uncertainty : {"delta", "bootstrap"}
        How the standard error is computed (module docstring).
    n_boot : int
        Bootstrap replicates.
    rng : numpy.random.Generator
        Required for the bootstrap (``np.random.default_rng(seed)``); never the global RNG.
    confidence : float
        Level of the reported interval.
    name : str
        Series name for error messages.
    op : ndarray, optional
        The controller output over the same samples: names a non-stationary record ``manual``
        when it does not move.

    Raises
    ------
    IdentificationError
        ``constant``, ``not_finite``, ``too_short``, ``bad_delay``, ``unstable_model`` (with
        its :attr:`~agents.monitor.errors.IdentificationError.kind`: ``drift``,
        ``integrating``, ``manual`` or ``diverging``).
    """
    from scipy.stats import norm

    y = np.asarray(y, dtype=float).ravel()
    if not np.all(np.isfinite(y)):
        raise IdentificationError("not_finite", f"{name!r} has NaN or infinite values")
    if int(delay) != delay or delay < 1:
        raise IdentificationError("bad_delay", f"delay must be an integer >= 1, got {delay}")
    delay = int(delay)
    var = float(np.var(y))
    if var <= 1e-300 or var <= (1e-12 * max(1.0, float(np.mean(y)) ** 2)):
        raise IdentificationError("constant", f"{name!r} is constant (variance {var:.3g})")
    check_not_diverging(y, name)
    if delay >= y.size // 10:
        raise IdentificationError(
            "bad_delay", f"delay {delay} is not small compared with the {y.size} samples"
        )
    settings = {"order": order, "max_order": max_order, "criterion": criterion}
    try:
        model = fit_var(y, **settings, names=(name,), oscillation_ok=True)
    except IdentificationError as exc:
        if exc.kind != "slow":
            raise
        kind, why = classify(y, op=op, **settings, name=name)
        raise IdentificationError(
            "unstable_model",
            f"not stationary over the record ({kind}): {why}; {exc.detail}",
            kind=kind,
        ) from None
    _, near = near_unit_roots(model, y.size)
    oscillating = bool(near)
    a = model.coefs[:, 0, 0].copy()
    psi = model.impulse(delay)[:, 0, 0]
    s2e = float(model.sigma[0, 0])
    sigma2_mv = s2e * float(np.sum(psi**2))
    index = sigma2_mv / var
    eta_model = model_index(a, delay)
    z = float(norm.ppf(0.5 + confidence / 2.0))
    method = uncertainty
    if oscillating:
        method = "delta_numerator"
        std = _numerator_std(a, delay, s2e, model.cov_params, y.size - model.order) / var
        lo, hi = index - z * std, index + z * std
    elif uncertainty == "delta":
        std = _delta_std(a, delay, model.cov_params)
        lo, hi = index - z * std, index + z * std
    elif uncertainty == "bootstrap":
        if rng is None:
            raise ValueError("harris_index: the bootstrap needs rng=np.random.default_rng(seed)")
        reps = _bootstrap(y - y.mean(), a, delay, n_boot, rng)
        std = float(np.std(reps, ddof=1))
        lo, hi = (float(q) for q in np.quantile(reps, [0.5 - confidence / 2, 0.5 + confidence / 2]))
    else:
        raise ValueError(f"harris_index: unknown uncertainty {uncertainty!r}")
    return HarrisResult(
        index=index,
        std=std,
        ci=_interval(lo, hi),
        confidence=confidence,
        sigma2_mv=sigma2_mv,
        variance=var,
        model_index=eta_model,
        delay=delay,
        order=model.order,
        n=int(y.size),
        uncertainty=method,
        psi=tuple(float(v) for v in psi),
        oscillating_model=oscillating,
        model_period=2 * math.pi / abs(math.atan2(near[0].imag, near[0].real)) if near else None,
        above_one=index > 1.0,
    )


def _interval(lo: float, hi: float) -> tuple[float, float]:
    """The estimator's interval, lower end clipped at 0, never inverted (nan stays nan)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return (lo, hi)
    lo_c = max(0.0, lo)
    return (lo_c, max(hi, lo_c))


def _numerator_std(
    a: NDArray[np.float64],
    delay: int,
    s2e: float,
    cov: NDArray[np.float64] | None,
    dof: int,
) -> float:
    """Delta-method standard error of ``sigma2_e sum_(i<d) psi_i^2`` (module docstring)."""
    p = a.size

    def head(coefs: NDArray[np.float64]) -> float:
        m = VARModel(coefs=coefs.reshape(p, 1, 1), sigma=np.eye(1), order=p, n_obs=0, method="ls")
        return float(np.sum(m.impulse(delay)[:, 0, 0] ** 2))

    h0 = head(a)
    var_s2e = 2.0 * s2e**2 / max(dof, 1)
    if cov is None:
        return float(math.sqrt(var_s2e) * h0)
    grad = np.zeros(p)
    for i in range(p):
        step = 1e-6 * max(1.0, abs(a[i]))
        up, dn = a.copy(), a.copy()
        up[i] += step
        dn[i] -= step
        grad[i] = (head(up) - head(dn)) / (2 * step)
    return float(math.sqrt(s2e**2 * max(grad @ cov @ grad, 0.0) + var_s2e * h0**2))


def _delta_std(a: NDArray[np.float64], delay: int, cov: NDArray[np.float64] | None) -> float:
    if cov is None:
        return math.nan
    p = a.size
    grad = np.zeros(p)
    for i in range(p):
        h = 1e-6 * max(1.0, abs(a[i]))
        up, dn = a.copy(), a.copy()
        up[i] += h
        dn[i] -= h
        fu, fd = model_index(up, delay), model_index(dn, delay)
        if not (math.isfinite(fu) and math.isfinite(fd)):
            return math.nan
        grad[i] = (fu - fd) / (2 * h)
    return float(math.sqrt(max(grad @ cov @ grad, 0.0)))


def _bootstrap(
    y: NDArray[np.float64],
    a: NDArray[np.float64],
    delay: int,
    n_boot: int,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    from scipy.signal import lfilter

    p = a.size
    target, x = lagged(y[:, None], p)
    resid = (target - x @ a[:, None]).ravel()
    resid = resid - resid.mean()
    den = np.r_[1.0, -a]
    burn = 500
    out = np.empty(n_boot)
    for b in range(n_boot):
        e = rng.choice(resid, size=y.size + burn, replace=True)
        ys = lfilter([1.0], den, e)[burn:]
        ys = ys - ys.mean()
        t, xs = lagged(ys[:, None], p)
        ab, *_ = np.linalg.lstsq(xs, t, rcond=None)
        r = t - xs @ ab
        s2 = float(np.sum(r**2)) / (t.shape[0] - p)
        m = VARModel(coefs=ab.reshape(p, 1, 1), sigma=np.eye(1), order=p, n_obs=0, method="ls")
        psi = m.impulse(delay)[:, 0, 0]
        out[b] = s2 * float(np.sum(psi**2)) / float(np.var(ys))
    return out
