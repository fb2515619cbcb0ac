"""Variance decomposition of a simple-feedback loop for cascade control (seed 004).

Seed 004 (Lakshminarayanan et al. 2006), "Theory", eq. (11)-(15). Routine data of the primary
``y1`` and a candidate secondary ``y2`` of a simple-feedback (SFB) loop are described by a
bivariate AR model (least squares or Yule-Walker, :mod:`agents.monitor.timeseries`) and
transformed into::

    y1 = H1 a1 + H2 a2

with ``a1`` the primary and ``a2`` the secondary innovation. The innovations ``e = (e1, e2)`` of
the VAR are made orthogonal with the secondary first: ``a2 = e2`` and ``a1 = e1 - beta e2``,
``beta = s12/s22``, i.e. whatever part of the primary innovation the secondary innovation
predicts is attributed to the secondary channel (needed when ``d1 = 0``, where ``a2`` reaches
``y1`` within the sample; with ``d1 >= 1`` and independent disturbances ``beta ~ 0``). Then
``H1_i = Psi11_i``, ``H2_i = Psi12_i + beta Psi11_i``, ``sigma2_a1 = s11 - s12^2/s22``,
``sigma2_a2 = s22``, and the four components are (``d = d1 + d2``; sums of squares by recursion
for the heads and by the Lyapunov equation for the infinite tails, so they add up to the
model's variance of ``y1`` exactly)::

    1a  SFB and cascade invariant (12)   sum_(i<d) H1_i^2 s_a1 + sum_(i<d) H2_i^2 s_a2
    1b  additional SFB invariant (14)    sum_(d<=i<2d1+d2) H2_i^2 s_a2
    2a  remainder due to a1 (15)         sum_(i>=d) H1_i^2 s_a1
    2b  remainder due to a2 (15)         sum_(i>=2d1+d2) H2_i^2 s_a2

``1a + 1b`` is eq. (11)/(13) (the SFB feedback invariant, eq. (7) with estimated coefficients),
``1a`` is eq. (12)/(8), the minimum variance under cascade control (Remark 3).

Prediction under cascade control
--------------------------------
A cascade removes 1b and 2b (a "perfect" secondary controller) and an unknown part of 2a
(Remark 2: not determinable from routine data). :meth:`Decomposition.prediction` returns::

    minimum      = 1a                                   (no cascade can do better)
    band         = [1a + (1 - f_hi) 2a,  1a + (1 - f_lo) 2a]
    point        = 1a + 2a/2                            (the paper's working estimate)

with the removed fraction of 2a in ``[f_lo, f_hi]``, default ``[0, 0.5]``, i.e. the band
``[1a + 2a/2, 1a + 2a]`` (candidates are ranked by ``point``). NB: the paper writes that its
cascades removed "at least 50 %" of 2a (which would be the band ``[1a, 1a + 2a/2]``,
``removed_2a=(0.5, 1.0)``); in our examples, with a variance-optimal PI baseline and a
variance-optimal PI-P cascade, the implemented cascade removed 26-39 % of the estimated 2a net of
the residual 1b/2b a proportional slave leaves (N = 20000, 10 seeds; 17-57 % at N = 5000), hence
the default. A poorly tuned SFB loop inflates 2a and the cascade then removes more (57 % for
``EXAMPLE_2`` under a sluggish PI), i.e. it does better than the band; and a slow proportional
slave (large ``d2`` relative to ``d1``) leaves much of 1b/2b, i.e. worse than the band.

Failure to identify
-------------------
Reported as :class:`agents.monitor.errors.IdentificationError` (seed 004 after eq. (15)):
``collinear`` (``y2`` an exact copy of ``y1`` up to scale and offset, or rank-deficient lagged
regressors), ``silent_channel`` (a series exactly predictable from the past: no disturbance
enters that channel), ``correlated_innovations`` (``|corr(e1, e2)|`` above
``max_innovation_correlation``), ``unstable_model``, ``too_short``, ``constant``, ``not_finite``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from agents.monitor.errors import IdentificationError, check_not_diverging
from agents.monitor.timeseries import Criterion, Method, VARModel, fit_var, lagged

__all__ = [
    "Components",
    "CascadePrediction",
    "Decomposition",
    "decompose",
    "decomposition_from_model",
    "rank_secondaries",
    "check_pair",
]

_SILENT_TOL = 1e-9
_COPY_TOL = 1e-9


@dataclass(frozen=True)
class Components:
    """The four variance components of ``y1`` (seed 004 eq. (11)-(15))."""

    c1a: float
    c1b: float
    c2a: float
    c2b: float

    @property
    def total(self) -> float:
        return self.c1a + self.c1b + self.c2a + self.c2b

    def to_dict(self) -> dict[str, float]:
        return {"1a": self.c1a, "1b": self.c1b, "2a": self.c2a, "2b": self.c2b}


@dataclass(frozen=True)
class CascadePrediction:
    """Predicted variance of ``y1`` under cascade control with one secondary.

    Attributes
    ----------
    minimum : float
        Component 1a: the minimum variance under cascade control (a hard lower bound).
    low, high : float
        Band ``[1a + (1 - f_hi) 2a, 1a + (1 - f_lo) 2a]``.
    point : float
        ``1a + 2a/2``.
    removed_2a : tuple of float
        ``(f_lo, f_hi)``: fraction of 2a assumed removed.
    reduction : float
        Predicted relative reduction of the variance at ``point``: ``1 - point / var(y1)``.
    """

    minimum: float
    low: float
    high: float
    point: float
    removed_2a: tuple[float, float]
    reduction: float

    def contains(self, variance: float) -> bool:
        return self.low <= variance <= self.high

    def to_dict(self) -> dict:
        return {
            "minimum": self.minimum,
            "band": [self.low, self.high],
            "point": self.point,
            "removed_2a": list(self.removed_2a),
            "reduction": self.reduction,
        }


@dataclass(frozen=True)
class Decomposition:
    """Variance decomposition of ``y1`` for one candidate secondary ``y2``.

    Attributes
    ----------
    components : Components
        1a, 1b, 2a, 2b.
    variance : float
        Sample variance of ``y1``.
    model_variance : float
        Variance of ``y1`` implied by the fitted model (``= components.total``).
    d1, d2 : int
        Delays secondary -> primary and ``u`` -> secondary, samples.
    order : int
        VAR order.
    method : str
        ``"ls"`` or ``"yule_walker"``.
    innovation_correlation : float
        ``corr(e1, e2)`` of the VAR innovations.
    sigma_a : tuple of float
        ``(sigma2_a1, sigma2_a2)`` of the orthogonalized innovations.
    h1, h2 : tuple of float
        ``H1_0 ... H1_(2d1+d2-1)`` and ``H2_...`` (impulse responses for unit innovations).
    std : dict
        Bootstrap standard errors of the components and of the band (empty without bootstrap).
    """

    components: Components
    variance: float
    model_variance: float
    d1: int
    d2: int
    order: int
    method: str
    innovation_correlation: float
    sigma_a: tuple[float, float]
    h1: tuple[float, ...]
    h2: tuple[float, ...]
    std: dict[str, float] = field(default_factory=dict)

    @property
    def closure(self) -> float:
        """``(1a + 1b + 2a + 2b) / var(y1)`` (1 when the model reproduces the variance)."""
        return self.components.total / self.variance

    def prediction(self, removed_2a: tuple[float, float] = (0.0, 0.5)) -> CascadePrediction:
        """Predicted variance of ``y1`` under cascade control (module docstring)."""
        f_lo, f_hi = removed_2a
        if not 0.0 <= f_lo <= f_hi <= 1.0:
            raise ValueError(f"removed_2a must satisfy 0 <= lo <= hi <= 1, got {removed_2a}")
        c = self.components
        point = c.c1a + 0.5 * c.c2a
        return CascadePrediction(
            minimum=c.c1a,
            low=c.c1a + (1.0 - f_hi) * c.c2a,
            high=c.c1a + (1.0 - f_lo) * c.c2a,
            point=point,
            removed_2a=(f_lo, f_hi),
            reduction=1.0 - point / self.variance,
        )

    def to_dict(self, removed_2a: tuple[float, float] = (0.0, 0.5)) -> dict:
        return {
            "components": self.components.to_dict(),
            "variance": self.variance,
            "model_variance": self.model_variance,
            "closure": self.closure,
            "d1": self.d1,
            "d2": self.d2,
            "order": self.order,
            "method": self.method,
            "innovation_correlation": self.innovation_correlation,
            "sigma_a": list(self.sigma_a),
            "prediction": self.prediction(removed_2a).to_dict(),
            "std": dict(self.std),
        }


def check_pair(
    y1: NDArray[np.float64], y2: NDArray[np.float64], names: tuple[str, str] = ("y1", "y2")
) -> None:
    """Refuse data from which no bivariate model can be identified (reasons in the module doc).

    Raises
    ------
    IdentificationError
    """
    for y, nm in ((y1, names[0]), (y2, names[1])):
        if not np.all(np.isfinite(y)):
            raise IdentificationError("not_finite", f"{nm!r} has NaN or infinite values")
        v = float(np.var(y))
        if v <= 1e-300 or v <= 1e-12 * max(1.0, float(np.mean(y)) ** 2):
            raise IdentificationError("constant", f"{nm!r} is constant (variance {v:.3g})")
        check_not_diverging(y, nm)
    r = float(np.corrcoef(y1, y2)[0, 1])
    if abs(r) >= 1.0 - _COPY_TOL:
        raise IdentificationError(
            "collinear",
            f"{names[1]!r} is an exact copy of {names[0]!r} up to scaling and offset "
            f"(correlation {r:+.9f}): the two channels cannot be told apart",
        )


def _silent_channels(y: NDArray[np.float64], p: int, names: tuple[str, str]) -> None:
    """A series exactly predictable from the past of both: its channel carries no disturbance."""
    target, x = lagged(y, p)
    beta, *_ = np.linalg.lstsq(x, target, rcond=None)
    resid = target - x @ beta
    for j, nm in enumerate(names):
        ratio = float(np.var(resid[:, j]) / np.var(target[:, j]))
        if ratio < _SILENT_TOL:
            other = names[1 - j]
            raise IdentificationError(
                "silent_channel",
                f"{nm!r} is (to rounding, residual variance ratio {ratio:.1e}) an exact linear "
                f"function of past {names[0]!r} and {names[1]!r}: no disturbance enters the "
                f"{'primary' if j == 0 else 'secondary'} channel, so the responses to its "
                f"innovation cannot be identified (is {nm!r} driven only by {other!r} through "
                "the controller?)",
            )


def decompose(
    y1: NDArray[np.float64],
    y2: NDArray[np.float64],
    d1: int,
    d2: int,
    *,
    order: int | None = None,
    max_order: int = 30,
    criterion: Criterion = "aic",
    method: Method = "ls",
    max_innovation_correlation: float = 0.99,
    n_boot: int = 0,
    rng: np.random.Generator | None = None,
    names: tuple[str, str] = ("y1", "y2"),
) -> Decomposition:
    """Seed 004 variance decomposition of ``y1`` with candidate secondary ``y2``.

    Parameters
    ----------
    y1, y2 : ndarray
        Routine SFB data: primary (or its control error) and candidate secondary, same length.
    d1 : int
        Dead time from the secondary to the primary, samples (``>= 0``).
    d2 : int
        Dead time from the manipulated variable to the secondary, samples (``>= 1``).
    order, max_order, criterion, method
        VAR order (fixed) or its selection, and estimator (:func:`fit_var`).
    max_innovation_correlation : float
        Above this ``|corr(e1, e2)|`` the channels are refused as not separable.
    n_boot : int
        Bootstrap replicates for standard errors of the components (0: none).
    rng : numpy.random.Generator
        Required when ``n_boot > 0``.
    names : tuple of str
        Series names for messages.

    Raises
    ------
    IdentificationError
        When the model cannot be identified (module docstring).
    """
    y1 = np.asarray(y1, dtype=float).ravel()
    y2 = np.asarray(y2, dtype=float).ravel()
    if y1.size != y2.size:
        raise ValueError(f"decompose: {names[0]!r} and {names[1]!r} differ in length")
    if int(d1) != d1 or int(d2) != d2 or d1 < 0 or d2 < 1:
        raise IdentificationError(
            "bad_delay", f"need integers d1 >= 0 and d2 >= 1, got d1={d1}, d2={d2} ({names[1]!r})"
        )
    d1, d2 = int(d1), int(d2)
    if 2 * d1 + d2 >= y1.size // 10:
        raise IdentificationError(
            "bad_delay", f"2 d1 + d2 = {2 * d1 + d2} is not small compared with {y1.size} samples"
        )
    check_pair(y1, y2, names)
    y = np.column_stack([y1 - y1.mean(), y2 - y2.mean()])
    p_check = order if order is not None else max_order
    if y.shape[0] > p_check + 5 * (2 * p_check + 1):
        _silent_channels(y, p_check, names)
    model = fit_var(
        y, order=order, max_order=max_order, criterion=criterion, method=method, names=names
    )
    var_y1 = float(np.var(y1))
    dec = _components(model, d1, d2, var_y1, max_innovation_correlation, names)
    if n_boot > 0:
        if rng is None:
            raise ValueError("decompose: the bootstrap needs rng=np.random.default_rng(seed)")
        dec = _with_bootstrap(dec, model, y, n_boot, rng, method, max_innovation_correlation)
    return dec


def decomposition_from_model(
    model: VARModel, d1: int, d2: int, variance: float | None = None
) -> Decomposition:
    """The decomposition of a given bivariate model (e.g.
    :func:`agents.monitor.timeseries.var_from_autocovariance` on the
    exact autocovariances of a known process); ``variance`` defaults to the model's own."""
    dec = _components(model, d1, d2, 1.0, 1.0, ("y1", "y2"))
    var = dec.model_variance if variance is None else variance
    return Decomposition(**{**dec.__dict__, "variance": var})


def _components(
    model: VARModel,
    d1: int,
    d2: int,
    var_y1: float,
    max_corr: float,
    names: tuple[str, str],
) -> Decomposition:
    s = model.sigma
    s11, s12, s22 = float(s[0, 0]), float(s[0, 1]), float(s[1, 1])
    if s11 <= 0.0 or s22 <= 0.0:
        raise IdentificationError(
            "silent_channel",
            f"innovation variance of {names[0 if s11 <= 0 else 1]!r} is not positive",
        )
    rho = s12 / math.sqrt(s11 * s22)
    if abs(rho) > max_corr:
        raise IdentificationError(
            "correlated_innovations",
            f"the innovations of {names[0]!r} and {names[1]!r} are correlated {rho:+.4f} "
            f"(limit {max_corr}): primary and secondary disturbances cannot be separated",
        )
    beta = s12 / s22
    s_a1 = s11 - s12 * s12 / s22
    s_a2 = s22
    d = d1 + d2
    horizon = 2 * d1 + d2
    psi = model.impulse(horizon)
    h1 = psi[:, 0, 0]
    h2 = psi[:, 0, 1] + beta * psi[:, 0, 0]
    b1 = np.array([math.sqrt(s_a1), 0.0])
    b2 = np.array([beta * math.sqrt(s_a2), math.sqrt(s_a2)])
    e1 = model.response_energy(b1)
    e2 = model.response_energy(b2)
    head1 = s_a1 * float(np.sum(h1[:d] ** 2))
    head2 = s_a2 * float(np.sum(h2[:d] ** 2))
    mid2 = s_a2 * float(np.sum(h2[d:horizon] ** 2))
    comps = Components(
        c1a=head1 + head2,
        c1b=mid2,
        c2a=max(e1 - head1, 0.0),
        c2b=max(e2 - head2 - mid2, 0.0),
    )
    return Decomposition(
        components=comps,
        variance=var_y1,
        model_variance=e1 + e2,
        d1=d1,
        d2=d2,
        order=model.order,
        method=model.method,
        innovation_correlation=rho,
        sigma_a=(s_a1, s_a2),
        h1=tuple(float(v) for v in h1),
        h2=tuple(float(v) for v in h2),
    )


def _simulate_var(
    model: VARModel, resid: NDArray[np.float64], n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    k, p = model.k, model.order
    burn = 300
    idx = rng.integers(0, resid.shape[0], size=n + burn)
    e = resid[idx]
    a_rev = np.hstack(list(model.coefs[::-1]))  # [A_p ... A_1], k x kp
    buf = np.zeros((n + burn + p, k))  # row p + t holds y_t; rows t ... t+p-1 are y_(t-p..t-1)
    for t in range(n + burn):
        buf[t + p] = a_rev @ buf[t : t + p].ravel() + e[t]
    out = buf[p:]
    return out[burn:]


def _with_bootstrap(
    dec: Decomposition,
    model: VARModel,
    y: NDArray[np.float64],
    n_boot: int,
    rng: np.random.Generator,
    method: Method,
    max_corr: float,
) -> Decomposition:
    p = model.order
    target, x = lagged(y, p)
    a = np.hstack(list(model.coefs))
    resid = target - x @ a.T
    resid = resid - resid.mean(axis=0)
    keys = ("1a", "1b", "2a", "2b", "low", "high", "point")
    reps: dict[str, list[float]] = {k: [] for k in keys}
    for _ in range(n_boot):
        ys = _simulate_var(model, resid, y.shape[0], rng)
        try:
            m = fit_var(ys, order=p, method=method)
            db = _components(m, dec.d1, dec.d2, float(np.var(ys[:, 0])), max_corr, ("y1", "y2"))
        except IdentificationError:
            continue
        pr = db.prediction()
        for k, v in zip(keys[:4], db.components.to_dict().values(), strict=True):
            reps[k].append(v)
        reps["low"].append(pr.low)
        reps["high"].append(pr.high)
        reps["point"].append(pr.point)
    std = {k: float(np.std(v, ddof=1)) if len(v) > 1 else math.nan for k, v in reps.items()}
    std["replicates"] = float(len(reps["1a"]))
    return Decomposition(**{**dec.__dict__, "std": std})


def rank_secondaries(
    results: Mapping[str, Decomposition | IdentificationError],
    removed_2a: tuple[float, float] = (0.0, 0.5),
) -> list[str]:
    """Candidate secondaries, best first: lowest predicted cascade variance (``point``, ties by
    the band's upper end). Unidentifiable candidates are left out."""
    ok = {n: r for n, r in results.items() if isinstance(r, Decomposition)}
    return sorted(
        ok,
        key=lambda n: (ok[n].prediction(removed_2a).point, ok[n].prediction(removed_2a).high),
    )
