"""Path-delay estimates for the coordination agent, by the three methods of seed 000.

Seed 000, section I: "we assume that tau_d can be determined experimentally for the WSN
configuration in use, by using either time stamps, 'ping' tests or counting hops" (and section
III.E, step 1: get the control-path delays of a proposed configuration). DESIGN.md, section 5.

1. **Time stamps** (:class:`TimestampEstimator`): each delivered sample carries the time it was
   taken; ``tau_d`` is the mean of ``t_delivered - t_sampled`` over the delivered samples (all, or
   the last ``window``). Lost samples contribute nothing. Needs traffic on the configuration.
2. **Ping probes** (:func:`ping_estimate`): the gateway sends ``k`` probes to the path's far end
   and each is echoed at once; ``tau_d`` is the mean round-trip time over the probes that came
   back, halved. Each leg is drawn through the same per-hop models (:func:`gateway.paths.deliver`),
   out on the reversed route and back on the route. Assumes symmetric paths.
3. **Hop count** (:func:`hops_estimate`): ``tau_d = hops x per-hop delay``, the per-hop delay
   being given (measured) or, by default, the mean per-hop delay of the route's links for
   delivered packets, expected retries included (``Hop.mean_delay``; a route of identical links
   gives exactly ``hops x`` the model's mean). No traffic needed: usable before a proposal is
   applied. For TDMA the mean assumes a random phase of the ready time in the frame, so it
   ignores the alignment of the slot schedule with the route (a schedule ordered along the route
   waits once, not at each hop).

Every estimate is a :class:`DelayEstimate` in time units, with the number of observations and
their standard deviation (the hop-count method has none).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Literal

import numpy as np

from core.time import to_units
from gateway.paths import Route, deliver

__all__ = ["DelayEstimate", "TimestampEstimator", "ping_estimate", "hops_estimate"]


@dataclass(frozen=True)
class DelayEstimate:
    """A path-delay estimate ``tau_d`` (time units) and what it rests on.

    Attributes
    ----------
    method : {"timestamps", "ping", "hops"}
    tau_d : float
        Estimated path delay, time units; ``nan`` when there was nothing to estimate from.
    count : int
        Observations used (delivered samples, returned probes, or hops).
    std : float
        Standard deviation of the observations (one-way delays, or round trips halved), time
        units; ``nan`` for the hop-count method or fewer than two observations.
    """

    method: Literal["timestamps", "ping", "hops"]
    tau_d: float
    count: int
    std: float = math.nan


def _estimate(method: Literal["timestamps", "ping"], delays_units: np.ndarray) -> DelayEstimate:
    n = len(delays_units)
    if n == 0:
        return DelayEstimate(method, math.nan, 0)
    std = float(np.std(delays_units, ddof=1)) if n > 1 else math.nan
    return DelayEstimate(method, float(np.mean(delays_units)), n, std)


class TimestampEstimator:
    """Method 1: mean delay of delivered samples from their time stamps.

    Parameters
    ----------
    window : int, optional
        Use only the last ``window`` deliveries (default: all since the last :meth:`reset`).
    """

    def __init__(self, window: int | None = None) -> None:
        if window is not None and window < 1:
            raise ValueError(f"window: must be >= 1, got {window}")
        self.window = window
        self.reset()

    def reset(self) -> None:
        """Forget the observations (e.g. after a reconfiguration)."""
        self._delays: deque[int] = deque(maxlen=self.window)

    def add(self, t_sampled: int, t_delivered: int) -> None:
        """Record one delivered sample, both times in ticks."""
        if t_delivered < t_sampled:
            raise ValueError(f"add: delivered ({t_delivered}) before sampled ({t_sampled})")
        self._delays.append(t_delivered - t_sampled)

    @property
    def count(self) -> int:
        return len(self._delays)

    def estimate(self) -> DelayEstimate:
        """Mean delivered delay (time units) with its count and standard deviation."""
        return _estimate("timestamps", to_units(1) * np.asarray(self._delays, dtype=float))


def ping_estimate(
    route: Route,
    t_start: int,
    rng: np.random.Generator,
    probes: int = 10,
    interval: int = 0,
) -> DelayEstimate:
    """Method 2: round trip / 2, averaged over ``probes`` ping probes.

    Parameters
    ----------
    route : Route
        The path to estimate (e.g. sensor -> gateway); probes go out on ``route.reversed()``
        from ``route.dst`` and the echo comes back on ``route``.
    t_start : int
        Time the first probe leaves, ticks.
    rng : numpy.random.Generator
        Generator for the probes' draws (use one apart from the path's data traffic so probing
        does not change the data's draws).
    probes : int
        Number of probes ``k``.
    interval : int
        Ticks between probe departures (0: all leave at ``t_start``). A probe is not delayed
        by the others (no queueing).

    Returns
    -------
    DelayEstimate
        ``tau_d = mean(RTT) / 2`` over the probes that returned (``count``).
    """
    if probes < 1:
        raise ValueError(f"probes: must be >= 1, got {probes}")
    if interval < 0:
        raise ValueError(f"interval: must be >= 0, got {interval}")
    back_route = route.reversed()
    halves = []
    for i in range(probes):
        t0 = t_start + i * interval
        out = deliver(back_route, t0, rng)
        if out.t_deliver is None:
            continue
        echo = deliver(route, out.t_deliver, rng)
        if echo.t_deliver is None:
            continue
        halves.append(to_units(echo.t_deliver - t0) / 2.0)
    return _estimate("ping", np.asarray(halves, dtype=float))


def hops_estimate(route: Route, per_hop: float | None = None) -> DelayEstimate:
    """Method 3: hops x per-hop delay.

    Parameters
    ----------
    route : Route
        The path's route.
    per_hop : float, optional
        Estimated per-hop delay, time units (e.g. measured). Default: the mean per-hop delay of
        the route's links for delivered packets, expected retries included.
    """
    if per_hop is None:
        per_hop = route.mean_delay / route.n_hops
    elif not per_hop >= 0:
        raise ValueError(f"per_hop: must be >= 0, got {per_hop}")
    return DelayEstimate("hops", route.n_hops * per_hop, route.n_hops)
