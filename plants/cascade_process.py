"""Sampled primary/secondary process with delays and stochastic disturbances (seed 004).

Seed 004 (Lakshminarayanan et al. 2006, *Estimation of variance reduction opportunities through
cascade control*), Figure 1: a chain of linear sampled stages from the manipulated variable ``u``
to the primary controlled variable ``y1``; each stage output may serve as a secondary
measurement. With two stages (the paper's structure)::

    y2 = T2 u  + N2 a2,        T2 = q^-d2 T2~                       (Fig. 1)
    y1 = T1 y2 + N1 a1,        T1 = q^-d1 T1~

``a1``, ``a2`` are independent zero-mean white noise sequences (standard deviations
``noise_std``), ``N1``, ``N2`` rational with monic numerator and denominator (so ``a_j`` is the
innovation of its channel), ``d1`` (secondary to primary) and ``d2`` (``u`` to secondary) whole
samples of dead time. In general the chain has ``m`` stages, stage 0 nearest ``u`` and stage
``m-1`` the primary::

    y_0 = G_0 u       + N_0 a_0
    y_j = G_j y_(j-1) + N_j a_j          (j = 1 ... m-1),       G_j = q^-delay_j B_j / A_j

Every stage output is measured with additive white noise ``v_j`` (``meas_noise_std``; the paper
adds 5 % measurement noise to all outputs, :func:`with_measurement_noise`).

Linear feedback laws ``u = -sum_l K_l(q^-1) ym_l`` (about zero set points) cover both structures:

* simple feedback (SFB, Fig. 1): ``K_primary = Q``, closed loop eq. (1)::

      y1 = N1/(1 + Q T1 T2) a1 + T1 N2/(1 + Q T1 T2) a2

* cascade (Fig. 2): ``u = Q2 (r2 - y2)``, ``r2 = Q1 (r1 - y1)``, i.e. ``K_secondary = Q2``,
  ``K_primary = Q1 Q2``; closed loop eq. (2)::

      y1 = N1/(1 + Q1 T1 T2*) a1 + T1 N2*/(1 + Q1 T1 T2*) a2,
      T2* = Q2 T2/(1 + Q2 T2),   N2* = N2/(1 + Q2 T2)

:func:`closed_loop` returns these transfer functions exactly (rational arithmetic in ``q^-1``),
:func:`variance` their variance, and :func:`minimum_variance_cascade` /
:func:`minimum_variance_sfb` eq. (8) / eq. (7): with ``d = d1 + d2`` and the expansions
eq. (3)-(5), ``N1 = P1 + R1 q^-d``, ``P2 T1~ = S + V q^-d``, ``S2`` the first ``d2`` terms of
``S`` (the Lemma after eq. (10))::

    sigma2_mv,SFB = var(P1 a1 + S  q^-d1 a2)      (7)   P1: first d1+d2 terms, S: first d1+d2
    sigma2_mv,CAS = var(P1 a1 + S2 q^-d1 a2)      (8)   S2: first d2 terms

i.e. the SFB keeps the response of ``y1`` to ``a2`` at lags ``d1 ... 2 d1 + d2 - 1`` that the
cascade can remove. :func:`true_components` gives the four components of the paper's variance
decomposition (``1a, 1b, 2a, 2b``, eq. (11)-(15)) from the exact closed-loop impulse responses.
These per-source references are exact for the paper's two-stage structure; in a longer chain a
source entering between the candidate secondary and the primary is counted as if it were
measured where it enters, which no controller using only ``(y1, y_s)`` can exploit.
:func:`autocovariance` gives the exact autocovariances of the measured outputs instead, from
which :func:`agents.monitor.timeseries.var_from_autocovariance` and
:func:`agents.monitor.decomposition.decomposition_from_model` give the decomposition the
data-driven estimator converges to (the "population" reference).

:func:`simulate` runs the loop sample by sample with any law object (``step(t, measurements)``),
e.g. the PI and PI-P laws of :mod:`controllers.cascade`, so that the monitor's prediction can be
compared with the cascade actually implemented on the same process and the same noise.

Examples
--------
The paper's Examples 1-3 print their transfer functions as images that are not in the seed text;
:data:`EXAMPLE_1`, :data:`EXAMPLE_2`, :data:`EXAMPLE_3` are **ours**, built in their spirit from
first-order stages ``K e^(-theta s)/(tau s + 1)`` sampled with a zero-order hold (1 sample =
1 min, so a stage's delay is ``theta + 1`` samples), with unit gains:

* ``EXAMPLE_1`` -- cascade helps a lot (the paper's Example 1: 1b and 2b about 65 %): secondary
  ``tau = 2``, ``theta = 0`` (``d2 = 1``); primary ``tau = 8``, ``theta = 4`` (``d1 = 5``); a
  strong drifting secondary disturbance ``0.3 a2/((1 - 0.5 q^-1)(1 - 0.97 q^-1))`` and a weaker
  primary one ``0.2 a1/(1 - 0.97 q^-1)``: 1b + 2b are about 70 % of the variance.
* ``EXAMPLE_2`` -- cascade helps little (the paper's Example 2, a packed-bed reactor with
  preheater): similar time constants (``tau = 2`` and ``5``), much longer primary dead time
  (``d1 = 9``, ``d2 = 1``), a slowly drifting primary disturbance
  ``0.3 a1/((1 - 0.8 q^-1)(1 - 0.98 q^-1))`` and a weak secondary one: 2a is about half of the
  variance, 1b + 2b almost nothing.
* ``EXAMPLE_3`` -- two candidate secondaries ``u -> y3 -> y2 -> y1`` (the paper's Example 3,
  Case 3): ``y3`` and ``y2`` with ``tau = 2``, ``theta = 0``; ``y1`` with ``tau = 8``,
  ``theta = 4``; the strongest disturbance ``a2`` enters at ``y2``, downstream of ``y3``: ``y2``
  sees it before the primary does (``d1 = 5``, ``d2 = 2``), ``y3`` never sees it (``d1 = 6``,
  ``d2 = 1``).

The paper's Example 2 disturbance is non-stationary; ours drift with poles 0.97-0.98 instead,
because an integrated disturbance at the primary makes ``u`` and every upstream measurement
drift without bound, and a non-stationary secondary has no autoregressive model
(``unstable_model``). The measurement noise is the paper's 5 %: ``meas_noise_std`` is 5 % of the
standard deviation of each noise-free output under the variance-optimal SFB PI
(:func:`with_measurement_noise`; ``bench/monitor_examples.py --retune`` recomputes it), and the
same absolute sensors serve the cascade. The controller settings are in :mod:`controllers.cascade`
(:data:`~controllers.cascade.EXAMPLE_SFB`, :data:`~controllers.cascade.EXAMPLE_CASCADE`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

__all__ = [
    "TF",
    "StageConfig",
    "CascadeProcessConfig",
    "FeedbackLaw",
    "RoutineRun",
    "foptd_stage",
    "delays",
    "open_loop",
    "closed_loop",
    "variance",
    "output_variance",
    "autocovariance",
    "minimum_variance_sfb",
    "minimum_variance_cascade",
    "Components",
    "true_components",
    "with_measurement_noise",
    "simulate",
    "EXAMPLE_1",
    "EXAMPLE_2",
    "EXAMPLE_3",
    "EXAMPLES",
]

_IMPULSE_TOL = 1e-13
_MAX_IMPULSE = 400_000


# ------------------------------------------------------------------------------------------------
# Rational transfer functions in q^-1
# ------------------------------------------------------------------------------------------------
class TF:
    """Rational transfer function ``num(q^-1) / den(q^-1)`` (coefficients of ``q^0, q^-1, ...``).

    Exact common factors ``(1 - q^-1)`` (integrators of non-stationary disturbances and of PI
    laws) are cancelled after every operation, so closed loops stay free of marginal poles.
    """

    __slots__ = ("num", "den")

    def __init__(self, num: Iterable[float], den: Iterable[float] = (1.0,)) -> None:
        n = np.atleast_1d(np.asarray(list(num), dtype=float))
        d = np.atleast_1d(np.asarray(list(den), dtype=float))
        if d.size == 0 or d[0] == 0.0:
            raise ValueError("TF: den[0] must be non-zero")
        n, d = n / d[0], d / d[0]
        self.num, self.den = _cancel_integrators(_trim(n), _trim(d))

    @classmethod
    def delay(cls, d: int) -> TF:
        """``q^-d``."""
        return cls(np.r_[np.zeros(d), 1.0])

    def __mul__(self, other: TF | float) -> TF:
        if not isinstance(other, TF):
            return TF(self.num * float(other), self.den)
        return TF(np.convolve(self.num, other.num), np.convolve(self.den, other.den))

    __rmul__ = __mul__

    def __add__(self, other: TF | float) -> TF:
        if not isinstance(other, TF):
            other = TF([float(other)])
        if np.array_equal(self.den, other.den):
            return TF(_padd(self.num, other.num), self.den)
        return TF(
            _padd(np.convolve(self.num, other.den), np.convolve(other.num, self.den)),
            np.convolve(self.den, other.den),
        )

    __radd__ = __add__

    def __neg__(self) -> TF:
        return TF(-self.num, self.den)

    def __sub__(self, other: TF | float) -> TF:
        return self + (-other)

    def feedback_sensitivity(self) -> TF:
        """``1 / (1 + self)``."""
        return TF(self.den, _padd(self.den, self.num))

    def __truediv__(self, other: TF) -> TF:
        return TF(np.convolve(self.num, other.den), np.convolve(self.den, other.num))

    def spectral_radius(self) -> float:
        """Largest pole modulus (poles are the roots of ``z^n den(z^-1)``)."""
        d = _trim(self.den)
        if d.size <= 1:
            return 0.0
        return float(np.max(np.abs(np.roots(d))))

    def is_stable(self) -> bool:
        """All poles strictly inside the unit circle (margin 1e-9)."""
        return self.spectral_radius() < 1.0 - 1e-9

    def impulse(self, n: int | None = None) -> NDArray[np.float64]:
        """Impulse response ``h_0 ... h_(n-1)``; ``n=None``: until it has decayed to 1e-13.

        Raises
        ------
        ValueError
            If ``n`` is None and the transfer function is not stable.
        """
        from scipy.signal import lfilter

        if n is None:
            rho = self.spectral_radius()
            if rho >= 1.0 - 1e-9:
                raise ValueError(f"TF.impulse: unstable (largest pole modulus {rho:.6f})")
            tail = 0 if rho == 0.0 else math.ceil(math.log(_IMPULSE_TOL) / math.log(rho))
            n = min(_MAX_IMPULSE, self.num.size + self.den.size + 10 + 2 * tail)
        x = np.zeros(int(n))
        x[0] = 1.0
        return lfilter(self.num, self.den, x)

    def h2(self) -> float:
        """Sum of squared impulse-response coefficients (``inf`` if unstable)."""
        if not self.is_stable():
            return math.inf
        return float(np.sum(self.impulse() ** 2))

    def __repr__(self) -> str:
        return f"TF(num={self.num.tolist()}, den={self.den.tolist()})"


def _trim(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Drop trailing coefficients that are zero to rounding."""
    if p.size == 0:
        return np.zeros(1)
    scale = float(np.max(np.abs(p))) or 1.0
    k = p.size
    while k > 1 and abs(p[k - 1]) <= 1e-14 * scale:
        k -= 1
    return p[:k].copy()


def _padd(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    n = max(a.size, b.size)
    out = np.zeros(n)
    out[: a.size] += a
    out[: b.size] += b
    return out


def _divide_by_integrator(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``p(q^-1) / (1 - q^-1)`` for ``p`` with a root at ``q = 1`` (the quotient's coefficients
    are the partial sums of ``p``)."""
    return np.cumsum(p)[:-1] if p.size > 1 else np.zeros(1)


def _has_unit_root(p: NDArray[np.float64]) -> bool:
    return p.size > 1 and abs(float(np.sum(p))) <= 1e-9 * float(np.sum(np.abs(p)))


def _cancel_integrators(
    num: NDArray[np.float64], den: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    while _has_unit_root(num) and _has_unit_root(den):
        num, den = _trim(_divide_by_integrator(num)), _trim(_divide_by_integrator(den))
    return num, den


# ------------------------------------------------------------------------------------------------
# Configuration
# ------------------------------------------------------------------------------------------------
class StageConfig(BaseModel):
    """One stage ``y_j = q^-delay B/A y_(j-1) + C/D a_j``, measured as ``y_j + v_j``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(min_length=1, description="measurement name (column name in routine data)")
    delay: int = Field(ge=0, description="dead time from the stage input to its output, samples")
    num: tuple[float, ...] = Field(min_length=1, description="B: b0 + b1 q^-1 + ..., b0 != 0")
    den: tuple[float, ...] = Field(default=(1.0,), description="A: 1 + a1 q^-1 + ... (monic)")
    noise_num: tuple[float, ...] = Field(default=(1.0,), description="C: 1 + c1 q^-1 + ...")
    noise_den: tuple[float, ...] = Field(default=(1.0,), description="D: 1 + d1 q^-1 + ...")
    noise_std: float = Field(default=0.0, ge=0, description="standard deviation of a_j")
    meas_noise_std: float = Field(default=0.0, ge=0, description="standard deviation of v_j")

    @field_validator("num")
    @classmethod
    def _leading_gain(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if v[0] == 0.0:
            raise ValueError("num[0] must be non-zero (put dead time in 'delay')")
        return v

    @field_validator("den", "noise_num", "noise_den")
    @classmethod
    def _monic(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if len(v) == 0 or v[0] != 1.0:
            raise ValueError("must be monic: first coefficient 1.0")
        return v

    def process_tf(self) -> TF:
        """``G_j = q^-delay B / A``."""
        return TF(np.r_[np.zeros(self.delay), self.num], self.den)

    def noise_tf(self) -> TF:
        """``N_j = C / D``."""
        return TF(self.noise_num, self.noise_den)


class CascadeProcessConfig(BaseModel):
    """A chain of stages from the manipulated variable (first) to the primary output (last)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    stages: tuple[StageConfig, ...] = Field(min_length=1)
    dt: float = Field(default=1.0, gt=0, description="sampling interval (time unit of the run)")
    description: str = ""

    @model_validator(mode="after")
    def _check(self) -> CascadeProcessConfig:
        names = [s.name for s in self.stages]
        if len(set(names)) != len(names):
            raise ValueError(f"stages: names must be unique, got {names}")
        if self.stages[0].delay < 1:
            raise ValueError(
                f"stages[0] ({names[0]!r}).delay must be >= 1 (u acts one sample later at the "
                "earliest)"
            )
        return self

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.stages)

    @property
    def primary(self) -> str:
        """Name of the primary controlled variable (the last stage)."""
        return self.stages[-1].name

    def index(self, name: str) -> int:
        """Stage index of measurement ``name`` (``KeyError`` naming the known ones)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no stage named {name!r}; stages are {list(self.names)}") from None


def foptd_stage(
    name: str,
    *,
    gain: float,
    tau: float,
    dead_time: float,
    dt: float = 1.0,
    noise_pole: float = 0.0,
    noise_std: float = 0.0,
    drift_pole: float = 0.0,
    meas_noise_std: float = 0.0,
) -> StageConfig:
    """Stage ``gain e^(-dead_time s)/(tau s + 1)`` sampled with a zero-order hold.

    ``dead_time`` must be a multiple of ``dt``; the hold adds one sample, so the stage's
    ``delay`` is ``dead_time/dt + 1``. The disturbance is ``a_j/(1 - noise_pole q^-1)``, times
    ``1/(1 - drift_pole q^-1)`` (a slow drift; ``drift_pole = 1`` is the integrated, non-stationary
    disturbance of the paper's Example 2, which makes the signals upstream of it drift too).
    """
    k = round(dead_time / dt)
    if abs(k * dt - dead_time) > 1e-9 * max(1.0, dead_time):
        raise ValueError(f"{name}: dead_time {dead_time} is not a multiple of dt {dt}")
    phi = math.exp(-dt / tau)
    noise_den = np.array([1.0, -noise_pole]) if noise_pole else np.array([1.0])
    if drift_pole:
        noise_den = np.convolve(noise_den, [1.0, -drift_pole])
    return StageConfig(
        name=name,
        delay=k + 1,
        num=(gain * (1.0 - phi),),
        den=(1.0, -phi),
        noise_den=tuple(float(c) for c in _trim(noise_den)),
        noise_std=noise_std,
        meas_noise_std=meas_noise_std,
    )


# ------------------------------------------------------------------------------------------------
# Open and closed loop
# ------------------------------------------------------------------------------------------------
def delays(config: CascadeProcessConfig, secondary: str) -> tuple[int, int]:
    """``(d1, d2)``: dead time secondary -> primary and ``u`` -> secondary, samples."""
    s = config.index(secondary)
    if s == len(config.stages) - 1:
        raise ValueError(f"secondary {secondary!r} is the primary")
    d2 = sum(st.delay for st in config.stages[: s + 1])
    d1 = sum(st.delay for st in config.stages[s + 1 :])
    return d1, d2


def open_loop(config: CascadeProcessConfig) -> tuple[list[TF], list[list[TF | None]]]:
    """``P[l]`` (``u -> y_l``) and ``W[j][l]`` (``a_j -> y_l`` without the noise std; None if
    ``l < j``: a disturbance never reaches upstream stages in open loop)."""
    m = len(config.stages)
    g = [s.process_tf() for s in config.stages]
    p: list[TF] = []
    acc = TF([1.0])
    for j in range(m):
        acc = acc * g[j]
        p.append(acc)
    w: list[list[TF | None]] = [[None] * m for _ in range(m)]
    for j in range(m):
        acc = config.stages[j].noise_tf()
        w[j][j] = acc
        for k in range(j + 1, m):
            acc = acc * g[k]
            w[j][k] = acc
    return p, w


def closed_loop(
    config: CascadeProcessConfig,
    feedback: Mapping[str, TF],
    output: str | None = None,
    *,
    measured: bool = True,
) -> dict[tuple[str, str], TF]:
    """Closed-loop transfer functions from every noise source to one output.

    Parameters
    ----------
    config : CascadeProcessConfig
        The process.
    feedback : mapping
        ``{measurement name: K_l}`` of the linear law ``u = -sum_l K_l ym_l`` (see
        :meth:`controllers.cascade.SFBPIConfig.feedback` and
        :meth:`controllers.cascade.PIPCascadeConfig.feedback`).
    output : str, optional
        Stage name of the output (default: the primary), or ``"u"`` for the manipulated variable.
    measured : bool
        Response of the measured ``y_l + v_l`` (default) or of the true ``y_l``.

    Returns
    -------
    dict
        ``{("a", name): TF, ("v", name): TF}`` for unit-variance sources (multiply variances by
        ``noise_std**2``, ``meas_noise_std**2``).
    """
    m = len(config.stages)
    names = config.names
    output = output or config.primary
    g = [s.process_tf() for s in config.stages]
    p, _ = open_loop(config)
    ks = {config.index(n): k for n, k in feedback.items()}

    def between(j: int, last: int) -> TF:  # G_(j+1) ... G_last, the chain from y_j to y_last
        acc = TF([1.0])
        for i in range(j + 1, last + 1):
            acc = acc * g[i]
        return acc

    def loop_sum(idx: Iterable[int]) -> TF:  # sum_k K_k P_k over k in idx
        acc = TF([0.0])
        for k in idx:
            acc = acc + ks[k] * p[k]
        return acc

    one_plus_loop = loop_sum(ks) + 1.0
    is_u = output == "u"
    li = -1 if is_u else config.index(output)
    out: dict[tuple[str, str], TF] = {}
    # Structural forms without subtractions (exact cancellations are numerically fragile):
    #   y_l/a_j = N_j G_(j,l] (1 + sum_{k<j} K_k P_k)/(1 + L)       l >= j
    #   y_l/a_j = -P_l N_j M_j/(1 + L),  M_j = sum_{k>=j} K_k G_(j,k]  l < j
    #   u/a_j   = -N_j M_j/(1 + L)
    for j in range(m):
        nj = config.stages[j].noise_tf()
        mj = TF([0.0])
        for k in ks:
            if k >= j:
                mj = mj + ks[k] * between(j, k)
        if is_u:
            tf = -(nj * mj) / one_plus_loop
        elif li >= j:
            up = loop_sum(k for k in ks if k < j) + 1.0
            tf = nj * between(j, li) * up / one_plus_loop
        else:
            tf = -(p[li] * nj * mj) / one_plus_loop
        out[("a", names[j])] = tf
    #   y_l/v_k = -P_l K_k/(1 + L), and (1 + sum_{i != l} K_i P_i)/(1 + L) for measured l = k
    for k in range(m):
        if is_u:
            tf = -ks[k] / one_plus_loop if k in ks else TF([0.0])
        elif measured and k == li:
            tf = (loop_sum(i for i in ks if i != k) + 1.0) / one_plus_loop
        else:
            tf = -(p[li] * ks[k]) / one_plus_loop if k in ks else TF([0.0])
        out[("v", names[k])] = tf
    return out


def _source_std(config: CascadeProcessConfig, key: tuple[str, str]) -> float:
    st = config.stages[config.index(key[1])]
    return st.noise_std if key[0] == "a" else st.meas_noise_std


def variance(config: CascadeProcessConfig, responses: Mapping[tuple[str, str], TF]) -> float:
    """Variance of an output from its closed-loop responses (``inf`` if the loop is unstable)."""
    total = 0.0
    for key, tf in responses.items():
        s = _source_std(config, key)
        if s > 0.0:
            total += s * s * tf.h2()
    return total


def output_variance(
    config: CascadeProcessConfig,
    feedback: Mapping[str, TF],
    output: str | None = None,
    *,
    measured: bool = True,
) -> float:
    """Analytic variance of ``output`` (default: measured primary) under ``feedback``."""
    return variance(config, closed_loop(config, feedback, output, measured=measured))


def autocovariance(
    config: CascadeProcessConfig,
    feedback: Mapping[str, TF],
    outputs: Sequence[str],
    max_lag: int,
    *,
    measured: bool = True,
) -> NDArray[np.float64]:
    """Exact autocovariances ``Gamma(h)[a, b] = E[y_a(t+h) y_b(t)]``, ``h = 0 ... max_lag``, of the
    (measured) ``outputs`` under ``feedback``, from the closed-loop impulse responses.

    Returns an array of shape ``(max_lag + 1, k, k)``; raises ``ValueError`` if the loop is
    unstable.
    """
    resp = {o: closed_loop(config, feedback, o, measured=measured) for o in outputs}
    k = len(outputs)
    gam = np.zeros((max_lag + 1, k, k))
    for key in resp[outputs[0]]:
        std = _source_std(config, key)
        if std == 0.0:
            continue
        hs = [resp[o][key] for o in outputs]
        n = max(h.impulse().size for h in hs) + max_lag
        imp = [h.impulse(n) for h in hs]
        for a in range(k):
            for b in range(k):
                for lag in range(max_lag + 1):
                    gam[lag, a, b] += std * std * float(np.dot(imp[a][lag:], imp[b][: n - lag]))
    return gam


def _open_loop_to_primary(config: CascadeProcessConfig) -> dict[str, NDArray[np.float64]]:
    """Open-loop impulse responses ``a_j -> y1`` (length long enough for the invariants)."""
    _, w = open_loop(config)
    n = sum(s.delay for s in config.stages) * 2 + 4
    return {config.stages[j].name: w[j][-1].impulse(n) for j in range(len(config.stages))}


def minimum_variance_sfb(config: CascadeProcessConfig, secondary: str) -> float:
    """Seed 004 eq. (7): ``var(P1 a1 + S q^-d1 a2)`` for the SFB loop and this secondary.

    Disturbances entering at or upstream of ``secondary`` are "secondary" (``a2``: invariant over
    lags ``< 2 d1 + d2``), the others "primary" (``a1``: lags ``< d1 + d2``); the primary's
    measurement noise counts as primary (lag 0 only).
    """
    return _invariant(config, secondary, cascade=False)


def minimum_variance_cascade(config: CascadeProcessConfig, secondary: str) -> float:
    """Seed 004 eq. (8): ``var(P1 a1 + S2 q^-d1 a2)``, the minimum variance under cascade control
    (with ``secondary`` as the inner measurement): the secondary channel is invariant only over
    lags ``< d1 + d2``. This is the component 1a."""
    return _invariant(config, secondary, cascade=True)


def _invariant(config: CascadeProcessConfig, secondary: str, *, cascade: bool) -> float:
    d1, d2 = delays(config, secondary)
    s = config.index(secondary)
    h = _open_loop_to_primary(config)
    total = config.stages[-1].meas_noise_std ** 2
    for j, st in enumerate(config.stages):
        horizon = d1 + d2 if (j > s or cascade) else 2 * d1 + d2
        total += st.noise_std**2 * float(np.sum(h[st.name][:horizon] ** 2))
    return total


@dataclass(frozen=True)
class Components:
    """Seed 004 variance components of ``y1`` for one secondary (eq. (11)-(15)).

    ``c1a`` SFB and cascade invariant, ``c1b`` additional SFB invariant, ``c2a`` remainder due to
    the primary noise, ``c2b`` remainder due to the secondary noise.
    """

    c1a: float
    c1b: float
    c2a: float
    c2b: float

    @property
    def total(self) -> float:
        return self.c1a + self.c1b + self.c2a + self.c2b


def true_components(
    config: CascadeProcessConfig, feedback: Mapping[str, TF], secondary: str
) -> Components:
    """The four components from the exact closed-loop impulse responses under ``feedback``.

    Sources at or upstream of ``secondary`` form the secondary channel (``H2``), the others and the
    primary's measurement noise the primary channel (``H1``). With ``d = d1 + d2``::

        1a = sum_{i<d} H1_i^2 s1 + sum_{i<d} H2_i^2 s2
        1b = sum_{d<=i<2d1+d2} H2_i^2 s2
        2a = sum_{i>=d} H1_i^2 s1,       2b = sum_{i>=2d1+d2} H2_i^2 s2

    For a single source per channel (the paper's two-stage structure) this is exactly the
    decomposition the data-driven estimator targets; for several sources per channel it is the
    per-source sum, which the bivariate innovations model can only approximate.
    """
    d1, d2 = delays(config, secondary)
    s = config.index(secondary)
    resp = closed_loop(config, feedback)
    c = dict(c1a=0.0, c1b=0.0, c2a=0.0, c2b=0.0)
    for (kind, name), tf in resp.items():
        j = config.index(name)
        std = _source_std(config, (kind, name))
        if std == 0.0:
            continue
        h = tf.impulse() if tf.is_stable() else None
        if h is None:
            return Components(math.inf, math.inf, math.inf, math.inf)
        h2 = std * std * h**2
        d = d1 + d2
        if kind == "a" and j <= s:
            c["c1a"] += float(h2[:d].sum())
            c["c1b"] += float(h2[d : 2 * d1 + d2].sum())
            c["c2b"] += float(h2[2 * d1 + d2 :].sum())
        else:
            c["c1a"] += float(h2[:d].sum())
            c["c2a"] += float(h2[d:].sum())
    return Components(**c)


def with_measurement_noise(
    config: CascadeProcessConfig, feedback: Mapping[str, TF], fraction: float = 0.05
) -> CascadeProcessConfig:
    """Copy of ``config`` whose measurement noise std is ``fraction`` times the (noise-free)
    standard deviation of each stage output under ``feedback`` (the paper's "5 % measurement
    noise"). The noise levels are absolute afterwards, so a cascade on the same process sees the
    same sensors."""
    clean = config.model_copy(
        update={
            "stages": tuple(s.model_copy(update={"meas_noise_std": 0.0}) for s in config.stages)
        }
    )
    stages = []
    for st in clean.stages:
        var = output_variance(clean, feedback, st.name, measured=False)
        if not math.isfinite(var):
            raise ValueError(
                f"with_measurement_noise: stage {st.name!r} is not stationary under this law "
                "(unstable loop, or an integrated disturbance downstream of it)"
            )
        sd = math.sqrt(var)
        stages.append(st.model_copy(update={"meas_noise_std": fraction * sd}))
    return CascadeProcessConfig(stages=tuple(stages), dt=config.dt, description=config.description)


# ------------------------------------------------------------------------------------------------
# Sample-by-sample simulation
# ------------------------------------------------------------------------------------------------
class FeedbackLaw(Protocol):
    """A control law executed once per sample: ``u = law.step(t, measurements)``."""

    def step(self, t: float, measurements: Mapping[str, float]) -> float: ...


class _Stage:
    """Direct-form difference equation ``A y = q^-delay B x`` with explicit history."""

    __slots__ = ("b", "a", "delay", "xh", "yh")

    def __init__(self, b: Sequence[float], a: Sequence[float], delay: int) -> None:
        self.b = list(b)
        self.a = list(a[1:])
        self.delay = delay
        self.xh = [0.0] * (delay + len(self.b))  # xh[i] = x(t - i)
        self.yh = [0.0] * len(self.a)  # yh[i] = y(t - 1 - i)

    def step(self, x: float) -> float:
        xh, yh = self.xh, self.yh
        xh.pop()
        xh.insert(0, x)
        y = 0.0
        for i, bi in enumerate(self.b):
            y += bi * xh[self.delay + i]
        for i, ai in enumerate(self.a):
            y -= ai * yh[i]
        if yh:
            yh.pop()
            yh.insert(0, y)
        return y


@dataclass(frozen=True)
class RoutineRun:
    """Result of :func:`simulate`: measured and true outputs by stage name, ``u``, time."""

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    measured: dict[str, NDArray[np.float64]]
    true: dict[str, NDArray[np.float64]]

    def variance(self, name: str, *, measured: bool = True) -> float:
        """Sample variance (about the mean) of a stage output."""
        x = (self.measured if measured else self.true)[name]
        return float(np.var(x))


def simulate(
    config: CascadeProcessConfig,
    law: FeedbackLaw,
    n: int,
    rng: np.random.Generator,
    *,
    burn_in: int = 1000,
) -> RoutineRun:
    """Routine closed-loop operation at zero set points, sample by sample.

    At each sample ``t_k = k dt`` the stage outputs are computed from past inputs (stage 0 from
    ``u(t_(k-1))`` and earlier), measured with noise, and the law returns ``u(t_k)``.

    Parameters
    ----------
    config : CascadeProcessConfig
        The process.
    law : FeedbackLaw
        Any object with ``step(t, measurements) -> u`` (measurements by stage name).
    n : int
        Samples returned (after ``burn_in`` samples that are discarded).
    rng : numpy.random.Generator
        Source of ``a_j`` and ``v_j``; the same seed gives the same noise whatever the law, so
        SFB and cascade runs can be compared on the same disturbances.
    burn_in : int
        Leading samples dropped (the loop starts at rest).
    """
    from scipy.signal import lfilter

    if n < 1 or burn_in < 0:
        raise ValueError(f"simulate: n ({n}) must be >= 1 and burn_in ({burn_in}) >= 0")
    total = n + burn_in
    m = len(config.stages)
    a = rng.standard_normal((m, total))
    v = rng.standard_normal((m, total))
    dist = np.empty((m, total))
    for j, st in enumerate(config.stages):
        dist[j] = st.noise_std * lfilter(st.noise_num, st.noise_den, a[j])
        v[j] *= st.meas_noise_std
    stages = []
    for j, st in enumerate(config.stages):
        # stage 0 is fed u(t-1) at step t, hence one sample less of explicit delay
        stages.append(_Stage(st.num, st.den, st.delay - 1 if j == 0 else st.delay))
    names = config.names
    y_true = np.empty((m, total))
    y_meas = np.empty((m, total))
    u = np.empty(total)
    u_prev = 0.0
    dt = config.dt
    dist_l = dist.T.tolist()
    v_l = v.T.tolist()
    for k in range(total):
        x = u_prev
        meas: dict[str, float] = {}
        dk, vk = dist_l[k], v_l[k]
        for j in range(m):
            y = stages[j].step(x) + dk[j]
            y_true[j, k] = y
            ym = y + vk[j]
            y_meas[j, k] = ym
            meas[names[j]] = ym
            x = y
        u_prev = float(law.step(k * dt, meas))
        u[k] = u_prev
    sl = slice(burn_in, total)
    return RoutineRun(
        t=np.arange(n) * dt,
        u=u[sl].copy(),
        measured={nm: y_meas[j, sl].copy() for j, nm in enumerate(names)},
        true={nm: y_true[j, sl].copy() for j, nm in enumerate(names)},
    )


# ------------------------------------------------------------------------------------------------
# Examples (ours, in the spirit of seed 004 Examples 1-3; 1 sample = 1 min)
# ------------------------------------------------------------------------------------------------
EXAMPLE_1 = CascadeProcessConfig(
    description="cascade helps a lot: fast secondary, slow delayed primary, strong a2",
    stages=(
        foptd_stage(
            "y2",
            gain=1.0,
            tau=2.0,
            dead_time=0.0,
            noise_pole=0.5,
            drift_pole=0.97,
            noise_std=0.3,
            meas_noise_std=0.0957,
        ),
        foptd_stage(
            "y1",
            gain=1.0,
            tau=8.0,
            dead_time=4.0,
            drift_pole=0.97,
            noise_std=0.2,
            meas_noise_std=0.0559,
        ),
    ),
)

EXAMPLE_2 = CascadeProcessConfig(
    description="cascade helps little: similar time constants, long primary dead time, "
    "drifting primary disturbance",
    stages=(
        foptd_stage(
            "y2",
            gain=1.0,
            tau=2.0,
            dead_time=0.0,
            noise_pole=0.5,
            noise_std=0.1,
            meas_noise_std=0.334,
        ),
        foptd_stage(
            "y1",
            gain=1.0,
            tau=5.0,
            dead_time=8.0,
            noise_pole=0.8,
            drift_pole=0.98,
            noise_std=0.3,
            meas_noise_std=0.213,
        ),
    ),
)

EXAMPLE_3 = CascadeProcessConfig(
    description="two candidate secondaries u -> y3 -> y2 -> y1, strong a2 at y2",
    stages=(
        foptd_stage(
            "y3",
            gain=1.0,
            tau=2.0,
            dead_time=0.0,
            noise_pole=0.5,
            drift_pole=0.97,
            noise_std=0.2,
            meas_noise_std=0.144,
        ),
        foptd_stage(
            "y2",
            gain=1.0,
            tau=2.0,
            dead_time=0.0,
            noise_pole=0.5,
            drift_pole=0.97,
            noise_std=0.3,
            meas_noise_std=0.132,
        ),
        foptd_stage(
            "y1",
            gain=1.0,
            tau=8.0,
            dead_time=4.0,
            drift_pole=0.97,
            noise_std=0.4,
            meas_noise_std=0.0934,
        ),
    ),
)

EXAMPLES: dict[str, CascadeProcessConfig] = {
    "example_1": EXAMPLE_1,
    "example_2": EXAMPLE_2,
    "example_3": EXAMPLE_3,
}
