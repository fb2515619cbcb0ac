"""Delay distributions of the gateway's paths, for the coordination agent (issue 14).

A path's delay is a random variable: per-hop draws from the links' delay models, a geometric
number of attempts per hop, and loss when a hop's retries run out (:func:`gateway.paths.deliver`).
The agent needs its whole law, not only its mean, to guarantee overshoots on a jittery, lossy
network. Two sources, one form (:class:`bus_schemas.DelayDistribution`):

* :func:`predict`: the model's law of a route, by seeded Monte Carlo over :func:`deliver` (the
  exact composition of sums of per-hop draws with geometric attempt counts has no closed form for
  the uniform and TDMA models; ``n`` packets from the path's own probe generator, so the data's
  draws are untouched and a run is reproducible). Its loss is the closed form
  ``1 - prod_h (1 - (1 - p_h)^(r_h + 1))`` (:attr:`gateway.paths.Route.delivery_probability`),
  not the sampled one.
* :func:`measured`: the delivered packets' delays from their time stamps, and the share lost.

The quantile function is kept at :data:`PROBABILITIES` (dense in the upper tail, where the
guarantee is decided) and read back piecewise linearly (:func:`quantile`, :func:`mean`; the
agent draws from it by the inverse-CDF method), with a compact histogram of :data:`BINS` bins
for display.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from bus_schemas import DelayDistribution
from core.time import TICKS_PER_UNIT
from gateway.paths import Route, deliver

__all__ = [
    "PROBABILITIES",
    "BINS",
    "predict",
    "measured",
    "from_delays",
    "quantile",
    "mean",
]

PROBABILITIES: tuple[float, ...] = (
    *(k / 40 for k in range(36)),  # 0, 0.025, ..., 0.875
    0.9,
    0.925,
    0.95,
    0.975,
    0.99,
    0.995,
    0.999,
    1.0,
)
"""Probabilities at which a distribution's quantiles are kept."""

BINS = 20
"""Bins of the compact histogram."""

PREDICTION_PACKETS = 4000
"""Packets drawn per route for the model's prediction."""


def from_delays(
    delays: NDArray[np.float64] | Sequence[float],
    sent: int,
    loss: float,
    source: Literal["model", "measured"],
) -> DelayDistribution:
    """The distribution of these delivered ``delays`` (time units) out of ``sent`` packets, with
    loss probability ``loss``; ``None``-free: needs at least one delay."""
    d = np.sort(np.asarray(delays, dtype=float))
    if len(d) == 0:
        raise ValueError("from_delays: no delivered packet to build a distribution from")
    q = np.quantile(d, PROBABILITIES)
    q = np.maximum.accumulate(q)  # rounding may break monotonicity by an ulp
    lo, hi = float(d[0]), float(d[-1])
    edges = np.linspace(lo, hi if hi > lo else lo + 1e-6, BINS + 1)
    counts, _ = np.histogram(d, bins=edges)
    return DelayDistribution(
        source=source,
        probabilities=PROBABILITIES,
        delays=tuple(float(v) for v in q),
        loss=float(min(max(loss, 0.0), 1.0)),
        count=int(sent),
        edges=tuple(float(v) for v in edges),
        counts=tuple(int(c) for c in counts),
    )


def predict(
    route: Route, t_ready: int, rng: np.random.Generator, n: int = PREDICTION_PACKETS
) -> DelayDistribution:
    """The model's delay distribution of ``route`` for packets ready from ``t_ready`` (ticks; the
    TDMA model's phase is spread uniformly over one frame by spreading the ready times over one
    time unit), by ``n`` seeded deliveries; loss by its closed form."""
    if n < 1:
        raise ValueError(f"n: must be >= 1, got {n}")
    starts = t_ready + rng.integers(0, TICKS_PER_UNIT, size=n)
    delays = []
    for t0 in starts:
        out = deliver(route, int(t0), rng)
        if out.t_deliver is not None:
            delays.append((out.t_deliver - int(t0)) / TICKS_PER_UNIT)
    loss = 1.0 - route.delivery_probability
    if not delays:
        delays = [np.inf]
    return from_delays(np.asarray(delays), n, loss, "model")


def measured(carried: Sequence[tuple[int, int | None]]) -> DelayDistribution | None:
    """The distribution of what a path carried (``(t_ready, t_deliver or None)`` in ticks);
    ``None`` when nothing was delivered."""
    delays = [(d - r) / TICKS_PER_UNIT for r, d in carried if d is not None]
    if not delays:
        return None
    return from_delays(delays, len(carried), 1.0 - len(delays) / len(carried), "measured")


Table = DelayDistribution | tuple[Sequence[float], Sequence[float]]
"""A distribution, or its quantile table ``(probabilities, delays)``."""


def _table(dist: Table) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if isinstance(dist, DelayDistribution):
        return np.asarray(dist.probabilities, dtype=float), np.asarray(dist.delays, dtype=float)
    return np.asarray(dist[0], dtype=float), np.asarray(dist[1], dtype=float)


def quantile(dist: Table, p: float | NDArray[np.float64]) -> Any:
    """The delay at probability ``p`` of a delivered packet (piecewise linear), time units."""
    probs, delays = _table(dist)
    return np.interp(p, probs, delays)


def mean(dist: Table) -> float:
    """Mean delay of a delivered packet under the piecewise-linear quantile function."""
    probs, delays = _table(dist)
    return float(np.sum(np.diff(probs) * (delays[1:] + delays[:-1]) / 2.0))
