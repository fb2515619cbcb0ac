"""Routes through the WSN and the delivery of one packet along a route.

A :class:`Route` is the sequence of hops a path's packets take (a snapshot of the links'
parameters when the route was chosen; :mod:`gateway.topology` builds routes). :func:`deliver`
carries one packet: hop by hop, it draws the number of attempts (each succeeding with the link's
PRR, at most ``retry_limit + 1``) and the hop's duration from the link's delay model
(:mod:`gateway.delay_models`), starting each hop at the integer tick the previous one ended.
The end-to-end delay is the sum of the per-hop delays (DESIGN.md, section 5).

Random draws, in order, per hop: one ``Generator.geometric(prr)`` for the attempts (skipped when
``prr == 1``); if the hop delivers, the delay model's draws for its attempts (none for the
constant and TDMA models). A lost packet makes no further draws. The caller owns the generator
(one per path, seeded from the scenario seed and the path name), so a run is reproducible.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from gateway.delay_models import (
    DelayModel,
    expected_attempts,
    hop_success_probability,
)

__all__ = ["Hop", "Route", "Delivery", "deliver"]


@dataclass(frozen=True)
class Hop:
    """One directed hop of a route, with the parameters of its link.

    Parameters
    ----------
    src, dst : str
        Sending and receiving node.
    prr : float
        Packet reception ratio of one attempt, in (0, 1].
    delay : DelayModel
        Per-hop delay model of the link.
    retry_limit : int
        Retries after a failed attempt (``retry_limit + 1`` attempts at most).
    slot : int
        The link's TDMA slot index (ignored by the other models).
    """

    src: str
    dst: str
    prr: float
    delay: DelayModel
    retry_limit: int
    slot: int = 0

    def reversed(self) -> Hop:
        """The same link used in the other direction."""
        return Hop(self.dst, self.src, self.prr, self.delay, self.retry_limit, self.slot)

    @property
    def success_probability(self) -> float:
        """Probability that the hop delivers within its retry limit."""
        return hop_success_probability(self.prr, self.retry_limit)

    @property
    def expected_attempts(self) -> float:
        """Expected attempts per packet offered to the hop (delivered or not)."""
        return expected_attempts(self.prr, self.retry_limit)

    @property
    def mean_delay(self) -> float:
        """Mean delay of the hop for delivered packets, retries included (time units)."""
        mean: float = self.delay.mean_hop(self.prr, self.retry_limit)  # DelayModel: typed Any
        return mean


@dataclass(frozen=True)
class Route:
    """A loop-free sequence of hops from ``nodes[0]`` to ``nodes[-1]``."""

    hops: tuple[Hop, ...]

    def __post_init__(self) -> None:
        if not self.hops:
            raise ValueError("Route: at least one hop")
        for a, b in itertools.pairwise(self.hops):
            if a.dst != b.src:
                raise ValueError(f"Route: hop {a.src}->{a.dst} not followed by {b.src}->{b.dst}")

    @property
    def nodes(self) -> tuple[str, ...]:
        """Nodes visited, source first."""
        return (self.hops[0].src,) + tuple(h.dst for h in self.hops)

    @property
    def src(self) -> str:
        return self.hops[0].src

    @property
    def dst(self) -> str:
        return self.hops[-1].dst

    @property
    def n_hops(self) -> int:
        return len(self.hops)

    def reversed(self) -> Route:
        """The route from ``dst`` back to ``src`` over the same links."""
        return Route(tuple(h.reversed() for h in reversed(self.hops)))

    @property
    def delivery_probability(self) -> float:
        """Probability that a packet reaches ``dst``: the product of the hops' success."""
        return float(np.prod([h.success_probability for h in self.hops]))

    @property
    def expected_transmissions(self) -> float:
        """Expected attempts per packet over the whole route (a hop is tried only if reached)."""
        total, reach = 0.0, 1.0
        for h in self.hops:
            total += reach * h.expected_attempts
            reach *= h.success_probability
        return total

    @property
    def transmissions_per_delivery(self) -> float:
        """Expected attempts spent per packet delivered: the route's energy cost."""
        return self.expected_transmissions / self.delivery_probability

    @property
    def mean_delay(self) -> float:
        """Sum of the hops' mean delays for delivered packets (time units)."""
        return float(sum(h.mean_delay for h in self.hops))

    def describe(self) -> str:
        return " -> ".join(self.nodes)


class Delivery(NamedTuple):
    """Outcome of one packet on a route (unpacks as ``t_deliver, attempts, hops``).

    Attributes
    ----------
    t_deliver : int or None
        Delivery time at the route's destination, ticks; ``None`` if the packet was lost.
    attempts : tuple of int
        Attempts made on each hop reached, in route order; a lost packet's last entry is the
        hop where it was lost (``retry_limit + 1`` attempts there).
    hops : int
        Hop count of the route.
    """

    t_deliver: int | None
    attempts: tuple[int, ...]
    hops: int

    @property
    def lost(self) -> bool:
        return self.t_deliver is None


def deliver(route: Route, t_ready: int, rng: np.random.Generator) -> Delivery:
    """Carry one packet ready at the source at ``t_ready`` ticks along ``route``.

    Parameters
    ----------
    route : Route
        The hops to take.
    t_ready : int
        Time the packet is ready for its first transmission, ticks.
    rng : numpy.random.Generator
        The caller's generator for this path; the only source of randomness.

    Returns
    -------
    Delivery
        Delivery time in ticks (``None`` if lost), attempts per hop, and the hop count. The
        delay is ``t_deliver - t_ready``: the sum of the per-hop delays, each an integer number
        of ticks (per-attempt rounding, see :mod:`gateway.delay_models`).
    """
    t = int(t_ready)
    attempts: list[int] = []
    for hop in route.hops:
        a = 1 if hop.prr >= 1.0 else int(rng.geometric(hop.prr))
        if a > hop.retry_limit + 1:
            attempts.append(hop.retry_limit + 1)
            return Delivery(None, tuple(attempts), route.n_hops)
        attempts.append(a)
        t += hop.delay.hop_ticks(t, a, rng, hop.slot)
    return Delivery(t, tuple(attempts), route.n_hops)
