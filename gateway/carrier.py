"""Delivery times of a network node's loop paths, shared by the network nodes and the direct engine.

A loop's sensor path (sensor -> controller) and actuator path (controller -> actuator) are carried
by the node its ``network:`` names:

* ``kind: network`` (wired): constant delays ``tau_d`` and ``tau_a``;
* ``kind: gateway`` (WSN): the sensor path is routed over the gateway's topology from the loop's
  ``sensor_node`` to the gateway, every packet's delay drawn hop by hop with retries and loss
  (:func:`gateway.paths.deliver`); the actuator path goes back from the gateway to the loop's
  ``actuator_node`` the same way, or is wired (``tau_a``) when the loop names none.

An actuator-only loop (``sensor: null``) has no sensor path; a measurement-only loop
(``actuator: null``) no actuator path (nothing is ever sent on it). A **link** (the scenario's
``links:``, data from one controller to another) naming the node is carried like a sensor path:
a constant ``delay`` over a wired network, or routed over the topology from its ``source_node``
to its ``dest_node`` (path ``<link>.link``).

Every path draws from its own generator, seeded from the scenario seed, the network node's name,
the loop and the direction, so the draws do not depend on the order in which engines handle
paths, and the bus engines and the direct engine deliver identical packets at identical times.
"""

from __future__ import annotations

import enum
import math
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np

from core.time import to_ticks, to_units
from gateway import distribution
from gateway.energy import EnergyMeter, projected_lifetime
from gateway.estimates import TimestampEstimator, hops_estimate, ping_estimate
from gateway.paths import Route, deliver
from gateway.topology import Interference, LinkDegraded, NodeDown, NodeUp, Topology
from gateway.tsch.mac import Outcome
from gateway.tsch.network import TschNetwork, effective_links, link_quality_of

__all__ = [
    "CarrierSpec",
    "PathCarrier",
    "initial_routes",
    "initial_hops",
    "Carried",
    "SENSOR",
    "ACTUATOR",
    "LINK",
]

SENSOR, ACTUATOR, LINK = "sensor", "actuator", "link"
_STREAM = {SENSOR: 0, ACTUATOR: 1, LINK: 4}  # generator streams of a path's data
_PING_STREAM = {SENSOR: 2, ACTUATOR: 3, LINK: 5}  # and of its ping probes
_MODEL_STREAM = {SENSOR: 6, ACTUATOR: 7, LINK: 8}  # and of its predicted delay distribution
_TSCH_LINKS_STREAM = 9  # a TSCH network's shadowing draws
_TSCH_STREAM = 10  # and its MAC's


class _Done(enum.Enum):
    """The sentinel of a replayed trace that has run out (an enum, so that it has a type)."""

    DONE = enum.auto()


_DONE: Final = _Done.DONE  # a replayed trace has run out


@dataclass(frozen=True)
class Carried:
    """What a TSCH network did with a packet (:meth:`PathCarrier.drain`): delivered at
    ``t_deliver`` (ticks) or lost (``None``, with the MAC's ``reason``)."""

    loop: str
    direction: str
    token: Any
    t_ready: int
    t_deliver: int | None
    reason: str | None = None


@dataclass(frozen=True)
class CarrierSpec:
    """What one network node's paths are made of (:func:`scenario.views.carrier_spec`).

    Attributes
    ----------
    node : str
        The network or gateway node.
    seed : int
        The scenario's seed (each path's generators are seeded from it, the node and the path).
    loops, links : mapping
        The loops and links it carries, by name (sorted): their scenario configurations.
    gateway : GatewayNodeConfig or None
        The WSN gateway's configuration (topology, events, energy, ping probes); ``None`` for a
        wired network of constant delays.
    traces : mapping
        Wired network: loop -> the sensor-path delays of its samples in order (time units,
        ``None``: lost), replayed before its constant ``tau_d`` takes over.
    """

    node: str
    seed: int
    loops: Mapping[str, Any]
    links: Mapping[str, Any]
    gateway: Any = None
    traces: Mapping[str, Any] = field(default_factory=dict)


def initial_routes(
    spec: CarrierSpec,
) -> tuple[Topology | None, Any, dict[tuple[str, str], Route | None]]:
    """The routes of ``spec``'s network before the run: its topology (``None`` for a wired
    network; over a TSCH network's links as its link quality draws them, with that quality)
    and the route of every path it routes, ``(loop or link, direction) -> Route`` (``None``:
    down). What :class:`PathCarrier` starts from, and all a hop count needs
    (:func:`initial_hops`), without the MAC, the energy or the generators."""
    cfg = spec.gateway
    routes: dict[tuple[str, str], Route | None] = {}
    if cfg is None:
        return None, None, routes
    topology_config, quality = cfg.topology, None
    if cfg.mac == "tsch":
        links_rng = np.random.default_rng(
            [spec.seed, zlib.crc32(spec.node.encode()), _TSCH_LINKS_STREAM]
        )
        quality = link_quality_of(cfg.tsch, cfg.topology, links_rng)
        topology_config = effective_links(cfg.tsch, cfg.topology, quality)
    topology = Topology(topology_config)
    gateway = cfg.gateway_node()
    for name, link in spec.links.items():
        topology.add_path(f"{name}.link", link.source_node, link.dest_node)
        routes[name, LINK] = topology.routes()[f"{name}.link"]
    for name, loop in spec.loops.items():
        if loop.sensor is not None:
            topology.add_path(f"{name}.sensor", loop.sensor_node, gateway)
            routes[name, SENSOR] = topology.routes()[f"{name}.sensor"]
        if loop.actuator_node is not None:
            topology.add_path(f"{name}.actuator", gateway, loop.actuator_node)
            routes[name, ACTUATOR] = topology.routes()[f"{name}.actuator"]
    return topology, quality, routes


def initial_hops(spec: CarrierSpec) -> dict[str, int]:
    """Loop -> hops of its sensor path before the run (0 wired or without a sensor, -1 down),
    for every loop ``spec``'s network carries: what a run's record names each loop's path
    with."""
    _, _, routes = initial_routes(spec)
    out = {}
    for name in spec.loops:
        if (name, SENSOR) not in routes:
            out[name] = 0  # a wired path, or an actuator-only loop over a gateway
        else:
            route = routes[name, SENSOR]
            out[name] = -1 if route is None else route.n_hops
    return out


class PathCarrier:
    """The loop paths of one network node, from its :class:`CarrierSpec`."""

    def __init__(self, spec: CarrierSpec) -> None:
        cfg = spec.gateway
        node = self.node = spec.node
        self._seed = spec.seed
        self.loops = dict(spec.loops)
        self.links = dict(spec.links)
        self._rng: dict[tuple[str, str], np.random.Generator] = {}
        self._const: dict[tuple[str, str], int] = {}
        self._traces = {
            (loop, SENSOR): iter([None if d is None else to_ticks(d) for d in trace])
            for loop, trace in spec.traces.items()
        }
        self.wireless = cfg is not None
        self.tsch: TschNetwork | None = None
        paths = [(n, d) for n in self.loops for d in (SENSOR, ACTUATOR)]
        for name, direction in [*paths, *((n, LINK) for n in self.links)]:
            self._rng[name, direction] = np.random.default_rng(
                [
                    spec.seed,
                    zlib.crc32(node.encode()),
                    zlib.crc32(name.encode()),
                    _STREAM[direction],
                ]
            )
        topology, quality, self.routes = initial_routes(spec)
        for name, link in self.links.items():
            if topology is None:
                self._const[name, LINK] = to_ticks(link.delay)
        for name, loop in self.loops.items():
            if topology is None:
                self._const[name, SENSOR] = to_ticks(loop.tau_d)
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
            elif loop.actuator_node is None:
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
        self.topology = topology
        self.periods = {n: lp.tau_s for n, lp in self.loops.items() if lp.tau_s is not None}
        self.link_periods = {n: lk.period for n, lk in self.links.items()}
        self.meter = (
            EnergyMeter(cfg.energy, topology)
            if topology is not None and cfg is not None and cfg.mac != "tsch"
            else None
        )
        if cfg is not None and cfg.mac == "tsch":
            self.tsch = TschNetwork(
                cfg.tsch,
                cfg.energy,
                topology,
                quality,
                seed=[spec.seed, zlib.crc32(node.encode()), _TSCH_STREAM],
            )
        self._pending: list[Carried] = []
        self._next_sample: dict[str, int] = {}  # a TSCH network: loop -> its next sample, ticks
        self._tokens: dict[int, tuple[str, str, Any, int]] = {}
        self._serial = 0
        self.stamps = {path: TimestampEstimator() for path in self.routes}
        # what each routed path carried: (t_ready, t_deliver or None), for net/stats
        self.carried: dict[tuple[str, str], list[tuple[int, int | None]]] = {
            path: [] for path in self.routes
        }
        self._ping_probes = cfg.ping_probes if cfg is not None else 0
        self._ping_rng = {
            path: np.random.default_rng(
                [
                    spec.seed,
                    zlib.crc32(node.encode()),
                    zlib.crc32(path[0].encode()),
                    _PING_STREAM[path[1]],
                ]
            )
            for path in self.routes
        }
        self.events = (
            sorted(
                ((to_ticks(e.t), i, e.event) for i, e in enumerate(cfg.events)),
                key=lambda x: (x[0], x[1]),
            )
            if self.wireless
            else []
        )
        if self.tsch is not None:
            self._reschedule(0)

    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        """Apply a reconfiguration event at ``t``; reroute every path; return
        :meth:`configuration` after it. Idle listening is charged up to ``t`` first."""
        if self.topology is None:
            raise ValueError(f"{self.node}: a wired network has no topology to reconfigure")
        if isinstance(event, Interference) and self.tsch is None:
            raise ValueError(
                "interference needs a TSCH network (mac: tsch); the per-hop models have no channels"
            )
        if self.meter is not None:
            self.meter.advance(t)
        if self.tsch is not None:
            self._take(self.tsch.mac.advance(t))
        routes = self.topology.apply(event).routes
        if self.tsch is not None:
            if isinstance(event, Interference):
                self.tsch.interfere(event.channels, event.prr, t, event.duration, event.receivers)
            elif isinstance(event, LinkDegraded):
                self.tsch.degrade(event.a, event.b, event.prr)
            elif isinstance(event, NodeDown | NodeUp):
                self._take(self.tsch.mac.set_down(event.node, isinstance(event, NodeDown), t))
        for loop, direction in list(self.routes):
            self.routes[loop, direction] = routes[f"{loop}.{direction}"]
        if self.tsch is not None:
            self._reschedule(t)
        return self.configuration(t)

    def alternatives(self) -> Any:
        """The gateway's further proposals for the topology as it is now
        (:class:`gateway.topology.Alternatives`)."""
        if self.topology is None:
            raise ValueError(f"{self.node}: a wired network has no alternative routes")
        return self.topology.alternatives()

    def set_routes(self, routes: dict[str, Any], t: int) -> dict[str, dict[str, Any]]:
        """Carry the paths over ``routes`` (path name -> route, e.g. an alternative) from ``t``;
        return :meth:`configuration` after it."""
        if self.meter is not None:
            self.meter.advance(t)
        for loop, direction in list(self.routes):
            self.routes[loop, direction] = routes[f"{loop}.{direction}"]
        if self.tsch is not None:
            self._reschedule(t)
        return self.configuration(t)

    def set_period(self, loop: str, period: float, t: int, next_sample: int | None = None) -> None:
        """Loop ``loop``'s sensor samples every ``period`` (time units) from ``t``: for the
        projected lifetimes (and a TSCH network's schedule: its chains start at the slot of
        ``next_sample``, the loop's next sample in ticks, default ``t``). Idle listening is
        charged up to ``t`` first."""
        self._next_sample[loop] = t if next_sample is None else next_sample
        if self.meter is not None:
            self.meter.advance(t)
        self.periods[loop] = period
        if self.tsch is not None:
            self._reschedule(t)

    def configuration(self, t: int) -> dict[str, dict[str, Any]]:
        """Path (``<loop>.<direction>``) -> hops (-1: down), route and the paper's three delay
        estimates (seed 000, III.E step 1) at time ``t``: time stamps of the samples delivered
        since the previous configuration, i.e. measured on the route being replaced (``None`` at
        start; the estimator then restarts), ping probes drawn at ``t`` from the path's own
        probe generator (apart from the data's draws), and hops x the model's mean per-hop
        delay."""
        out = {}
        for (loop, direction), route in sorted(self.routes.items()):
            path = (loop, direction)
            stamps = self.stamps[path].estimate()
            estimates: dict[str, float | None] = {
                "timestamps": _finite(stamps.tau_d),
                "ping": None,
                "hops": None,
            }
            predicted = None
            if route is not None and self.tsch is not None:
                name = f"{loop}.{direction}"
                estimates["ping"] = _finite(self.tsch.ping(name, route.nodes, t, self._ping_probes))
                estimates["hops"] = _finite(self.tsch.hops_estimate(route.nodes, t))
                predicted = self.tsch.predict(name, route.nodes, t).model_dump()
            elif route is not None:
                ping = ping_estimate(route, t, self._ping_rng[path], probes=self._ping_probes)
                estimates["ping"] = _finite(ping.tau_d)
                estimates["hops"] = _finite(hops_estimate(route).tau_d)
                predicted = self._predicted(path, route, t)
            self.stamps[path].reset()
            out[f"{loop}.{direction}"] = {
                "hops": -1 if route is None else route.n_hops,
                "route": [] if route is None else list(route.nodes),
                "estimates": estimates,
                "distribution": predicted,
            }
        return out

    def _predicted(self, path: tuple[str, str], route: Route, t: int) -> dict[str, Any]:
        """The model's delay distribution of ``route`` (:func:`gateway.distribution.predict`),
        drawn from a generator of its own, seeded by the path and ``t``: the same route proposed
        at the same time gets the same prediction in every engine."""
        loop, direction = path
        rng = np.random.default_rng(
            [
                self._seed,
                zlib.crc32(self.node.encode()),
                zlib.crc32(loop.encode()),
                _MODEL_STREAM[direction],
                t,
            ]
        )
        return distribution.predict(route, t, rng).model_dump()

    def path_stats(self, t: int) -> dict[str, dict[str, Any]]:
        """Per routed path: hops now, and of the packets it was given that are due by ``t``:
        delivered delays (mean, p95, max; time units), sent, lost, and their distribution
        (:func:`gateway.distribution.measured`)."""
        out = {}
        for (loop, direction), route in sorted(self.routes.items()):
            done = [(r, d) for r, d in self.carried[loop, direction] if d is None or d <= t]
            delays = np.array([to_units(d - r) for r, d in done if d is not None])
            out[f"{loop}.{direction}"] = {
                "hops": -1 if route is None else route.n_hops,
                "delay_mean": float(delays.mean()) if len(delays) else None,
                "delay_p95": float(np.percentile(delays, 95)) if len(delays) else None,
                "delay_max": float(delays.max()) if len(delays) else None,
                "sent": len(done),
                "lost": sum(1 for _, d in done if d is None),
                "distribution": _dumped(distribution.measured(done)),
            }
        return out

    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """Per topology node at ``t``: charge spent (mAh), battery (%), projected lifetime (h)
        at the current routes and the loops' sampling periods (``None``: mains powered)."""
        if self.tsch is not None:
            self._take(self.tsch.mac.advance(t))
            return self.tsch.energy(t)
        if self.meter is None or self.topology is None:
            return {}
        self.meter.advance(t)
        routes = {f"{lp}.{d}": r for (lp, d), r in self.routes.items() if d in (SENSOR, LINK)}
        periods = {f"{lp}.{d}": self.periods[lp] for (lp, d) in self.routes if d == SENSOR}
        periods.update({f"{n}.{d}": self.link_periods[n] for (n, d) in self.routes if d == LINK})
        projected = projected_lifetime(
            self.topology, routes, periods, self.meter.config, self.meter
        )
        return {
            name: {
                "energy_mAh": self.meter.charge(name).total_mAh,
                "battery_pct": self.meter.battery_pct(name),
                "lifetime_h": _finite(projected[name].lifetime_s / 3600.0),
            }
            for name in sorted(self.topology.nodes)
        }

    def hops(self, loop: str, direction: str = SENSOR) -> int:
        """Hops of a path (0 for a wired path or a loop without a sensor; -1 when the path is
        down)."""
        if (loop, direction) in self._const:
            return 0
        if (loop, direction) not in self.routes:
            return 0  # an actuator-only loop over a gateway: no sensor path
        route = self.routes[loop, direction]
        return -1 if route is None else route.n_hops

    def deliver(self, loop: str, direction: str, t_ready: int) -> int | None:
        """Delivery time (ticks) of a packet ready at ``t_ready``; ``None`` if it is lost.
        ``loop`` is the link's name for ``direction == LINK``."""
        trace = self._traces.get((loop, direction))
        if trace is not None:
            replayed = next(trace, _DONE)
            if replayed is not _DONE:
                return None if replayed is None else t_ready + replayed
        const = self._const.get((loop, direction))
        if const is not None:
            return t_ready + const
        route = self.routes[loop, direction]
        if self.tsch is not None:
            raise RuntimeError(f"{self.node}: a TSCH network carries with submit(), not deliver()")
        if route is None:
            self.carried[loop, direction].append((t_ready, None))
            return None  # no route: the path is down and its packets are lost
        delivery = deliver(route, t_ready, self._rng[loop, direction])
        self.carried[loop, direction].append((t_ready, delivery.t_deliver))
        if self.meter is not None:
            self.meter.record(route, delivery)
        if delivery.t_deliver is not None:
            self.stamps[loop, direction].add(t_ready, delivery.t_deliver)
        return delivery.t_deliver

    # -- a TSCH network: packets go in, outcomes come out as its slots run ------------------

    @property
    def slotted(self) -> bool:
        """Whether packets are carried by a TSCH network (:meth:`submit`, :meth:`advance`,
        :meth:`drain`) rather than given their delivery time at once (:meth:`deliver`)."""
        return self.tsch is not None

    def path_periods(self) -> dict[str, int]:
        """Path name -> its packets' period, ticks (a loop's sensor and actuator paths: its
        sampling period; a link: its period)."""
        out = {}
        for name, direction in self.routes:
            period = self.link_periods[name] if direction == LINK else self.periods.get(name)
            if period is not None:
                out[f"{name}.{direction}"] = to_ticks(period)
        return out

    def route_nodes(self) -> dict[str, tuple[str, ...] | None]:
        """Path name -> the nodes of its route (``None``: down)."""
        return {
            f"{n}.{d}": None if r is None else r.nodes for (n, d), r in sorted(self.routes.items())
        }

    def granted(self, period: int) -> int:
        """The sampling period (ticks) a TSCH manager grants for ``period`` ticks (the period
        itself on other networks)."""
        return period if self.tsch is None else self.tsch.granted(period)

    def path_offsets(self) -> dict[str, int]:
        """A TSCH network: path name -> the slot of its next packet. A sensor path's is its
        loop's next sample; the actuator path's follows the sensor path's chain (its move is
        made when the sample arrives); a link's is 0."""
        assert self.tsch is not None
        slot = self.tsch.slot_ticks
        per_hop = 1 + self.tsch.config.retry_cells
        out = {}
        for name, direction in sorted(self.routes):
            if direction == LINK:
                out[f"{name}.{direction}"] = 0
                continue
            first = self._next_sample.get(name, 0) // slot
            if direction == ACTUATOR:
                sensor = self.routes.get((name, SENSOR))
                first += per_hop * (sensor.n_hops if sensor is not None else 0)
            out[f"{name}.{direction}"] = first
        return out

    def _reschedule(self, t: int) -> None:
        assert self.tsch is not None
        self._take(
            self.tsch.reschedule(
                self.route_nodes(), self.path_periods(), t, offsets=self.path_offsets()
            )
        )

    def plan(self, periods: Mapping[str, float]) -> Any:
        """The manager's schedule if the loops sampled at ``periods`` (time units), not applied."""
        assert self.tsch is not None
        trial = {**self.periods, **periods}
        ticks = {
            f"{n}.{d}": to_ticks(self.link_periods[n] if d == LINK else trial[n])
            for (n, d) in self.routes
            if d == LINK or n in trial
        }
        return self.tsch.plan(self.route_nodes(), ticks, self.path_offsets())

    def submit(self, loop: str, direction: str, t_ready: int, token: Any) -> None:
        """A packet of path ``(loop, direction)`` enters the network at ``t_ready``; what
        becomes of it comes out of :meth:`drain` (a wired or constant path: at once)."""
        const = self._const.get((loop, direction))
        if const is not None or self.tsch is None:
            t = self.deliver(loop, direction, t_ready)
            self._pending.append(Carried(loop, direction, token, t_ready, t))
            return
        self._serial += 1
        self._tokens[self._serial] = (loop, direction, token, t_ready)
        route = self.routes[loop, direction]
        early = self.tsch.mac.submit(self._serial, None if route is None else route.nodes, t_ready)
        if early is not None:
            self._take([early])

    def advance(self, t: int) -> None:
        """Run the TSCH network's slots that start before ``t``."""
        if self.tsch is not None:
            self._take(self.tsch.mac.advance(t))

    def next_wakeup(self) -> int | None:
        """When the TSCH network next has something to do (end of a busy slot, ticks)."""
        return None if self.tsch is None else self.tsch.mac.next_wakeup()

    def drain(self) -> list[Carried]:
        """What happened to the packets since the last call, in order."""
        out, self._pending = self._pending, []
        return out

    def _take(self, outcomes: list[Outcome]) -> None:
        for o in outcomes:
            loop, direction, token, t_ready = self._tokens.pop(o.id)
            done = o.t if o.delivered else None
            self.carried[loop, direction].append((t_ready, done))
            if done is not None:
                self.stamps[loop, direction].add(t_ready, done)
            self._pending.append(Carried(loop, direction, token, t_ready, done, o.reason))


def _dumped(dist: Any) -> dict[str, Any] | None:
    return None if dist is None else dist.model_dump()


def _finite(value: float) -> float | None:
    """JSON-safe: ``None`` for nan or inf."""
    return float(value) if math.isfinite(value) else None
