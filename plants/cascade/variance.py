"""Variances of seed 004's closed loops: analytic, minimum-variance bounds and their components.

The closed loops of :func:`plants.cascade.model.closed_loop` (seed 004 eq. (1), (2)): their
variance (:func:`variance`, :func:`output_variance`), and :func:`minimum_variance_cascade` /
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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from plants.cascade.model import CascadeProcessConfig, closed_loop, delays, open_loop
from plants.cascade.transfer import TF

__all__ = [
    "variance",
    "output_variance",
    "autocovariance",
    "minimum_variance_sfb",
    "minimum_variance_cascade",
    "Components",
    "true_components",
    "with_measurement_noise",
]


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
