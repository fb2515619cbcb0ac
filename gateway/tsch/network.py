"""A gateway's TSCH network: link quality, the manager's schedule, the MAC, energy and batteries,
and the delay estimates the coordination agent is proposed (issue 15).

:class:`TschNetwork` is what :class:`gateway.carrier.TschCarrier` runs when the gateway says
``mac: tsch``. The topology (:mod:`gateway.topology`) still routes (shortest paths by the
configured metric over links whose PRR is, with ``link_model: pathloss`` or ``trace``, the mean
PDR over the hopping channels); the manager (:func:`gateway.tsch.schedule.schedule_for`) gives
every routed path cells for its packet period, and is rebuilt whenever routes or periods change;
the MAC (:mod:`gateway.tsch.mac`) carries the packets slot by slot.

Link quality per (transmitter, receiver, channel, time):

* ``prr``: the topology link's PRR (after ``link_degraded`` events) on every channel;
* ``pathloss``: :class:`gateway.tsch.link_quality.PositionLinks` from the nodes' positions, its
  shadowing drawn once from the network's own generator;
* ``trace``: :class:`gateway.tsch.link_quality.TraceLinks` replayed from a k7 file;

always 0 when either end is down or no topology link joins them, capped by ``link_degraded``
events (``pathloss``/``trace``) and by ``interference`` bursts (every model).

The proposal's estimates (seed 000, III.E step 1) come from this model: **time stamps** of what
the path delivered (the carrier's), **ping**: probes sent one at a time through a copy of the MAC
(current schedule and queues, a generator of its own), one-way delays averaged; **hops**: the
route's hops times the mean per-hop delay of its links under the schedule (the mean wait for the
link's next cell from a uniform instant, plus the slot, times the expected attempts). The
**predicted distribution** is :data:`PREDICTION_PROBES` probes through a copy of the MAC.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from bus_schemas import DelayDistribution
from core.time import TICKS_PER_UNIT
from gateway import distribution
from gateway.tsch.config import TschConfig
from gateway.tsch.energy import RADIOS, charge_uC
from gateway.tsch.k7 import read_k7
from gateway.tsch.link_quality import (
    InterferenceBurst,
    LinkQuality,
    PositionLinks,
    TraceLinks,
    WithInterference,
)
from gateway.tsch.mac import Outcome, TschMac
from gateway.tsch.schedule import Schedule, grant, schedule_for

__all__ = [
    "TschNetwork",
    "slot_ticks_of",
    "link_quality_of",
    "effective_links",
    "PREDICTION_PROBES",
]

PREDICTION_PROBES = 400
"""Probes through a copy of the MAC for a route's predicted delay distribution."""
_PROBE_FRAMES = 64  # a probe not through after this many slotframes counts as lost
_FOREVER_S = 1e15  # an interference burst with no duration lasts "for ever" (finite for pydantic)


def slot_ticks_of(config: TschConfig, seconds_per_unit: float) -> int:
    """The slot duration in ticks; ``ValueError`` unless it is a whole number >= 1 of ticks."""
    exact = config.slot_duration / seconds_per_unit * TICKS_PER_UNIT
    ticks = round(exact)
    if ticks < 1 or abs(ticks - exact) > 1e-6 * max(exact, 1.0):
        raise ValueError(
            f"tsch.slot_duration: {config.slot_duration} s is {exact:g} ticks at "
            f"seconds_per_unit {seconds_per_unit}; it must be a whole number >= 1 of ticks "
            f"(1 time unit = {TICKS_PER_UNIT} ticks)"
        )
    return ticks


class _TopologyPrr:
    """``link_model: prr``: the topology link's PRR on every channel."""

    def __init__(self, topology: Any) -> None:
        self.topology = topology

    def pdr(self, a: str, b: str, channel: int, t: float) -> float:
        try:
            return float(self.topology.link(a, b).prr)
        except ValueError:
            return 0.0

    def rssi(self, a: str, b: str, channel: int, t: float) -> float | None:
        return None


def link_quality_of(
    config: TschConfig, topology_config: Any, rng: np.random.Generator
) -> LinkQuality | None:
    """The position or trace link model (``None`` for ``prr``, which reads the topology).

    Raises
    ------
    ValueError
        A node without a position under ``pathloss``; a trace that does not read.
    """
    if config.link_model == "pathloss":
        missing = [n for n, spec in topology_config.nodes.items() if spec.position is None]
        if missing:
            raise ValueError(
                f"tsch.link_model: pathloss needs every node's position; {missing[0]!r} has none"
            )
        positions = {n: spec.position for n, spec in topology_config.nodes.items()}
        return PositionLinks(positions, sorted(set(config.sequence)), config.pathloss, rng)
    if config.link_model == "trace":
        assert config.trace is not None  # the config's validator says so
        trace = read_k7(config.trace.file)
        return TraceLinks(trace, dict(config.trace.node_map) or None)
    return None


def effective_links(config: TschConfig, topology_config: Any, quality: LinkQuality | None) -> Any:
    """The topology to route on: unchanged under ``prr``; otherwise each declared link's PRR is
    its mean PDR over the hopping channels at t = 0 (the worse direction; a link that carries
    nothing is dropped), or, with no links declared, every pair whose mean PDR reaches
    ``min_link_pdr`` becomes a link."""
    if quality is None:
        return topology_config
    channels = sorted(set(config.sequence))

    def mean_pdr(a: str, b: str) -> float:
        there = np.mean([quality.pdr(a, b, ch, 0.0) for ch in channels])
        back = np.mean([quality.pdr(b, a, ch, 0.0) for ch in channels])
        return float(min(there, back))

    links = []
    if topology_config.links:
        for link in topology_config.links:
            p = mean_pdr(link.a, link.b)
            if p > 0:
                links.append(link.model_copy(update={"prr": min(p, 1.0)}))
    else:
        names = sorted(topology_config.nodes)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                p = mean_pdr(a, b)
                if p >= config.min_link_pdr:
                    links.append({"a": a, "b": b, "prr": min(p, 1.0)})
    data = topology_config.model_dump()
    data["links"] = [lk if isinstance(lk, dict) else lk.model_dump() for lk in links]
    return type(topology_config).model_validate(data)


class TschNetwork:
    """The TSCH side of one gateway (module docstring).

    Parameters
    ----------
    config : TschConfig
        The gateway's ``tsch:``.
    energy : EnergyConfig
        Its ``energy:`` (``seconds_per_unit``, batteries, mains-powered kinds).
    topology : Topology
        The routing topology (the carrier's; node states and link PRRs are read from it).
    quality : LinkQuality or None
        The position or trace model (:func:`link_quality_of`), ``None`` under ``prr``.
    seed : sequence of int
        Seeds the MAC's generator and the probes' (streams of their own).
    """

    def __init__(
        self,
        config: TschConfig,
        energy: Any,
        topology: Any,
        quality: LinkQuality | None,
        seed: Sequence[int],
    ) -> None:
        self.config = config
        self.energy_config = energy
        self.topology = topology
        self.seconds_per_unit = float(energy.seconds_per_unit)
        self.slot_ticks = slot_ticks_of(config, self.seconds_per_unit)
        self.frame_ticks = self.slot_ticks * config.length
        self.slot_s = config.slot_duration
        self.trace_scale = (
            config.trace.seconds_per_unit
            if config.trace is not None and config.trace.seconds_per_unit is not None
            else self.seconds_per_unit
        )
        self.links = WithInterference(quality if quality is not None else _TopologyPrr(topology))
        self.caps: dict[tuple[str, str], float] = {}
        self.radio = RADIOS[config.radio]
        self._seed = list(seed)
        self.routes: dict[str, tuple[str, ...] | None] = {}
        self.periods: dict[str, int] = {}
        self.offsets: dict[str, int] = {}
        empty = Schedule(config.length, config.offsets)
        self.mac = TschMac(
            empty,
            slot_ticks=self.slot_ticks,
            hopping=config.sequence,
            pdr=self.pdr,
            rng=np.random.default_rng([*self._seed, 11]),
            queue_capacity=config.queue_capacity,
            max_retries=config.max_retries,
            min_be=config.min_be,
            max_be=config.max_be,
        )

    # -- link quality ---------------------------------------------------------------------------

    def seconds(self, t: int) -> float:
        """Link-model time (seconds) of tick ``t``."""
        scale = self.trace_scale if self.config.link_model == "trace" else self.seconds_per_unit
        return t / TICKS_PER_UNIT * scale

    def pdr(self, a: str, b: str, channel: int, t: int) -> float:
        """PDR of one frame ``a -> b`` on ``channel`` at tick ``t`` (module docstring)."""
        topo = self.topology
        if not (topo.is_up(a) and topo.is_up(b)):
            return 0.0
        try:
            topo.link(a, b)
        except ValueError:
            return 0.0
        p = self.links.pdr(a, b, channel, self.seconds(t))
        cap = self.caps.get((a, b) if a <= b else (b, a))
        return p if cap is None else min(p, cap)

    def mean_pdr(self, a: str, b: str, t: int) -> float:
        """PDR of ``a -> b`` averaged over the hopping sequence at ``t``."""
        seq = self.config.sequence
        return float(np.mean([self.pdr(a, b, ch, t) for ch in seq]))

    def interfere(
        self,
        channels: Sequence[int],
        prr: float,
        t: int,
        duration: float | None,
        receivers: Sequence[str] | None,
    ) -> None:
        """Interference from ``t`` (ticks) for ``duration`` time units (``None``: to the end)
        on ``channels``: their PDR is capped at ``prr``."""
        start = self.seconds(t)
        end = _FOREVER_S if duration is None else self.seconds(t + round(duration * TICKS_PER_UNIT))
        self.links.add(
            InterferenceBurst(
                t_start=start,
                t_end=end,
                channels=tuple(channels),
                prr=prr,
                receivers=None if receivers is None else frozenset(receivers),
            )
        )

    def degrade(self, a: str, b: str, prr: float) -> None:
        """``link_degraded`` under ``pathloss``/``trace``: the link's PDR capped at ``prr``."""
        if self.config.link_model != "prr":
            self.caps[(a, b) if a <= b else (b, a)] = prr

    # -- the manager ----------------------------------------------------------------------------

    def capacity(self) -> dict[str, Any]:
        """What the coordination agent needs to ask the manager itself (``Proposal.tsch``)."""
        cfg = self.config
        return {
            "slot_ticks": self.slot_ticks,
            "length": cfg.length,
            "channel_offsets": cfg.offsets,
            "retry_cells": cfg.retry_cells,
            "static": cfg.schedule != "auto",
            "cells": [
                {
                    "slot": c.slot,
                    "channel": c.channel,
                    "tx": c.tx,
                    "rx": c.rx,
                    "shared": c.shared,
                    "every": c.every,
                    "phase": c.phase,
                }
                for c in cfg.cells()
            ],
        }

    def granted(self, period: int) -> int:
        """The period (ticks) the manager grants a flow asking for ``period`` ticks
        (:func:`gateway.tsch.schedule.grant`)."""
        return grant(max(1, period // self.slot_ticks), self.config.length) * self.slot_ticks

    def plan(
        self,
        routes: Mapping[str, Sequence[str] | None],
        periods: Mapping[str, int],
        offsets: Mapping[str, int] | None = None,
    ) -> Schedule:
        """The manager's schedule for ``routes``, ``periods`` (ticks) and ``offsets`` (slot of
        each path's next packet), not applied."""
        cfg = self.config
        return schedule_for(
            routes,
            periods,
            slot_ticks=self.slot_ticks,
            length=cfg.length,
            channels=cfg.offsets,
            retry_cells=cfg.retry_cells,
            written=cfg.cells(),
            static=cfg.schedule != "auto",
            offsets=offsets,
        )

    def reschedule(
        self,
        routes: Mapping[str, Sequence[str] | None],
        periods: Mapping[str, int],
        t: int,
        offsets: Mapping[str, int] | None = None,
    ) -> list[Outcome]:
        """Apply the manager's schedule for ``routes``, ``periods`` and ``offsets`` from ``t``;
        the outcomes of the slots run up to ``t`` and of the packets left without a cell."""
        self.routes = {p: None if r is None else tuple(r) for p, r in routes.items()}
        self.periods = dict(periods)
        self.offsets = dict(offsets or {})
        return self.mac.set_schedule(self.plan(self.routes, self.periods, self.offsets), t)

    @property
    def schedule(self) -> Schedule:
        return self.mac.schedule

    # -- estimates ------------------------------------------------------------------------------

    def _probe_rng(self, path: str, stream: int, t: int) -> np.random.Generator:
        return np.random.default_rng([*self._seed, zlib.crc32(path.encode()), stream, t])

    def _instant(self, path: str, clock: int, rng: np.random.Generator) -> int:
        """The first instant at or after ``clock`` at which ``path`` sends a packet (its
        period and offset under the schedule), or a uniform one within a slotframe."""
        period = self.periods.get(path)
        if period is None:
            return clock + int(rng.integers(0, self.frame_ticks))
        period = self.granted(period)
        phase = self.offsets.get(path, 0) * self.slot_ticks % period
        return clock + (phase - clock) % period

    def probe(
        self, path: str, route: Sequence[str], t: int, n: int, rng: np.random.Generator
    ) -> list[tuple[int, int | None]]:
        """``n`` probes sent one at a time along ``route`` through a copy of the MAC from ``t``,
        each at the path's next sending instant after the previous one is through (as its
        samples are sent), or at a uniform instant for a path with no period, while the other
        paths send their packets at their own instants (the cross traffic the probe queues
        behind): ``(t_sent, t_delivered or None)`` in ticks."""
        twin = self.mac.clone(rng)
        twin.advance(t)
        others = {
            p: (self.granted(self.periods[p]), r)
            for p, r in sorted(self.routes.items())
            if p != path and r is not None and p in self.periods
        }
        upcoming = {p: self._instant(p, t, rng) for p in others}
        serial = 0

        def run_until(until: int) -> list[Outcome]:
            """Advance the copy to ``until``, sending the other paths' packets on the way."""
            nonlocal serial
            out: list[Outcome] = []
            while True:
                due = min(upcoming.values(), default=None)
                if due is None or due > until:
                    break
                out += twin.advance(due)
                for p in [p for p, at in upcoming.items() if at == due]:
                    serial += 1
                    twin.submit(("cross", serial), others[p][1], due)
                    upcoming[p] = due + others[p][0]
            out += twin.advance(until)
            return out

        out: list[tuple[int, int | None]] = []
        clock = t
        frames = max((c.every for c in twin.schedule.cells), default=1) * _PROBE_FRAMES
        for i in range(n):
            t0 = self._instant(path, clock, rng)
            run_until(t0)
            early = twin.submit(("probe", i), route, t0)
            if early is not None:
                out.append((t0, None))
                clock = t0 + 1
                continue
            limit = t0 + frames * self.frame_ticks
            done: int | None = None
            lost = False
            while done is None and not lost:
                wake = twin.next_wakeup()
                if wake is None or wake > limit:
                    lost = True
                    break
                for o in run_until(wake):
                    if o.id == ("probe", i):
                        if o.delivered:
                            done = o.t
                        else:
                            lost = True
            out.append((t0, done))
            clock = (done if done is not None else t0) + 1
        return out

    def ping(self, path: str, route: Sequence[str], t: int, probes: int) -> float:
        """Mean one-way probe delay (time units); ``nan`` when none came through."""
        done = self.probe(path, route, t, probes, self._probe_rng(path, 1, t))
        got = [d - s for s, d in done if d is not None]
        return float(np.mean(got)) / TICKS_PER_UNIT if got else math.nan

    def predict(self, path: str, route: Sequence[str], t: int) -> DelayDistribution:
        """The predicted delay distribution of ``route`` (:data:`PREDICTION_PROBES` probes)."""
        done = self.probe(path, route, t, PREDICTION_PROBES, self._probe_rng(path, 2, t))
        delays = [(d - s) / TICKS_PER_UNIT for s, d in done if d is not None]
        loss = 1.0 - len(delays) / len(done)
        if not delays:
            delays = [math.inf]
        return distribution.from_delays(np.asarray(delays), len(done), loss, "model")

    def per_hop(self, a: str, b: str, t: int) -> float:
        """Mean delay of one hop ``a -> b`` under the schedule (time units): the mean wait for
        the link's next cell from a uniform instant, plus the slot, times the expected attempts
        ``1/p`` (``inf`` when the link has no cell or never gets through)."""
        sched = self.mac.schedule
        cells = [c for c in sched.cells if c.link == (a, b)]
        p = self.mean_pdr(a, b, t)
        if not cells or p <= 0:
            return math.inf
        every = max(c.every for c in cells)
        hyper = sched.length * every
        starts = sorted(
            {f * sched.length + c.slot for c in cells for f in range(every) if c.active_in(f)}
        )
        gaps = np.diff([*starts, starts[0] + hyper])
        wait = float(np.sum(gaps**2) / (2 * hyper))
        return (wait + 1.0) * self.slot_ticks / TICKS_PER_UNIT / p

    def hops_estimate(self, route: Sequence[str], t: int) -> float:
        """Hops times the mean per-hop delay of the route's links (time units)."""
        hops = list(zip(route[:-1], route[1:], strict=True))
        per = [self.per_hop(a, b, t) for a, b in hops]
        return len(hops) * float(np.mean(per))

    # -- energy ---------------------------------------------------------------------------------

    def capacity_mAh(self, node: str) -> float | None:
        """Battery capacity of ``node`` (``None``: mains powered)."""
        cfg = self.energy_config
        if self.topology.nodes[node].kind in cfg.mains_powered:
            return None
        return float(cfg.batteries.get(node, cfg.battery_mAh))

    def charge_mAh(self, t: int) -> dict[str, float]:
        """Charge every node has spent by ``t`` (run the MAC to ``t`` first)."""
        nodes = sorted(self.topology.nodes)
        counts = self.mac.slot_counts(nodes, t)
        return {n: charge_uC(self.radio, counts[n], self.slot_s) / 3.6e6 for n in nodes}

    def frame_charge_uC(
        self,
        t: int,
        schedule: Schedule | None = None,
        routes: Mapping[str, Sequence[str] | None] | None = None,
        periods: Mapping[str, int] | None = None,
    ) -> dict[str, float]:
        """Each node's expected charge per slotframe under the schedule and the paths' periods
        (default: those in force): its listening cells, the packets it receives and the
        attempts it makes (``1/p`` per packet per hop, at most ``max_retries + 1``), sleep
        otherwise."""
        sched = self.mac.schedule if schedule is None else schedule
        routes = self.routes if routes is None else routes
        periods = self.periods if periods is None else periods
        length = sched.length
        radio, slot_s = self.radio, self.slot_s
        listens: dict[str, float] = {}
        for _slot, rx, every, _phase in {(c.slot, c.rx, c.every, c.phase) for c in sched.cells}:
            listens[rx] = listens.get(rx, 0.0) + 1.0 / every
        rx_frames: dict[str, float] = {}
        tx_cost: dict[str, float] = {}
        tx_slots: dict[str, float] = {}
        r = self.config.max_retries
        for path, route in sorted(routes.items()):
            period = periods.get(path)
            if route is None or period is None:
                continue
            per_frame = self.frame_ticks / self.granted(period)
            for a, b in zip(route[:-1], route[1:], strict=True):
                p = self.mean_pdr(a, b, t)
                attempts = (1 - (1 - p) ** (r + 1)) / p if p > 0 else r + 1.0
                delivered = 1 - (1 - p) ** (r + 1)
                tx_slots[a] = tx_slots.get(a, 0.0) + per_frame * attempts
                tx_cost[a] = tx_cost.get(a, 0.0) + per_frame * (
                    delivered * radio.charge_uC("tx_ack", slot_s)
                    + (attempts - delivered) * radio.charge_uC("tx_noack", slot_s)
                )
                rx_frames[b] = rx_frames.get(b, 0.0) + per_frame * delivered
        out = {}
        for node in sorted(self.topology.nodes):
            received = rx_frames.get(node, 0.0)
            listen = max(listens.get(node, 0.0), received)
            busy = listen + tx_slots.get(node, 0.0)
            out[node] = (
                tx_cost.get(node, 0.0)
                + received * radio.charge_uC("rx_ack", slot_s)
                + (listen - received) * radio.charge_uC("idle", slot_s)
                + max(length - busy, 0.0) * radio.charge_uC("sleep", slot_s)
            )
        return out

    def lifetimes_h(
        self, routes: Mapping[str, Sequence[str] | None], periods: Mapping[str, int]
    ) -> dict[str, float | None]:
        """Each battery node's lifetime (hours) from a full battery under the manager's schedule
        for ``routes`` and ``periods`` (ticks), not applied (``None``: mains powered or spending
        nothing)."""
        schedule = self.plan(routes, periods)
        rate = self.frame_charge_uC(0, schedule, routes, periods)
        out: dict[str, float | None] = {}
        for node in sorted(self.topology.nodes):
            cap = self.capacity_mAh(node)
            out[node] = None if cap is None else self._hours(cap, rate[node])
        return out

    def _hours(self, left_mAh: float, frame_uC: float) -> float | None:
        """Hours until ``left_mAh`` is spent at ``frame_uC`` per slotframe (``None``: never)."""
        frame_s = self.frame_ticks / TICKS_PER_UNIT * self.seconds_per_unit
        per_s = frame_uC / 3.6e6 / frame_s  # mAh per second
        return left_mAh / per_s / 3600.0 if per_s > 0 else None

    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """Per node at ``t``: charge spent (mAh), battery left (%) and projected lifetime (h) at
        the schedule's expected charge per slotframe (``None``: mains powered or spending
        nothing)."""
        spent = self.charge_mAh(t)
        rate = self.frame_charge_uC(t)
        out: dict[str, dict[str, float | None]] = {}
        for node in sorted(self.topology.nodes):
            cap = self.capacity_mAh(node)
            if cap is None:
                out[node] = {"energy_mAh": spent[node], "battery_pct": 100.0, "lifetime_h": None}
                continue
            left = max(cap - spent[node], 0.0)
            out[node] = {
                "energy_mAh": spent[node],
                "battery_pct": 100.0 * left / cap,
                "lifetime_h": self._hours(left, rate[node]),
            }
        return out

    def depletion(self, t: int) -> tuple[int, list[str]] | None:
        """When the next battery runs out (ticks), by the expected charge per slotframe from
        ``t`` on, and whose; ``None`` if none will. Nodes already empty give ``t``."""
        spent = self.charge_mAh(t)
        rate = self.frame_charge_uC(t)
        best: tuple[int, list[str]] | None = None
        for node in sorted(self.topology.nodes):
            cap = self.capacity_mAh(node)
            if cap is None or not self.topology.is_up(node):
                continue
            left_uC = (cap - spent[node]) * 3.6e6
            if left_uC <= 0:
                at = t
            elif rate[node] <= 0:
                continue
            else:
                at = t + math.ceil(left_uC / rate[node] * self.frame_ticks)
            if best is None or at < best[0]:
                best = (at, [node])
            elif at == best[0]:
                best[1].append(node)
        return best

    def empty(self, t: int) -> list[str]:
        """The nodes that are up and whose battery is spent at ``t``."""
        spent = self.charge_mAh(t)
        out = []
        for node in sorted(self.topology.nodes):
            cap = self.capacity_mAh(node)
            if cap is not None and self.topology.is_up(node) and spent[node] >= cap:
                out.append(node)
        return out
