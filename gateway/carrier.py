"""Delivery times of a network node's loop paths, shared by the network nodes and the direct engine.

A loop's sensor path (sensor -> controller) and actuator path (controller -> actuator) are carried
by the node its ``network:`` names. :class:`PathCarrier` is what the network behaviour
(:class:`gateway.behaviour.NetworkBehaviour`) carries them with, whatever the network is:
packets go in with :meth:`~PathCarrier.submit` and come out of :meth:`~PathCarrier.drain`, and
what differs between networks is a method each implementation answers in its own way.
:meth:`PathCarrier.from_spec` builds the one the node's :class:`CarrierSpec` describes:

* :class:`WiredCarrier` (``kind: network``): constant delays ``tau_d`` and ``tau_a``, the delay
  elements of seed 000, III.C (a sensor path may first replay a trace of delays);
* :class:`PerHopCarrier` (``kind: gateway``): the sensor path is routed over the gateway's
  topology from the loop's ``sensor_node`` to the gateway, every packet's delay drawn hop by hop
  with retries and loss (:func:`gateway.paths.deliver`: ``tau_d`` is the sum of the per-hop
  delays, seed 000, I, DESIGN.md section 5); the actuator path goes back from the gateway to the
  loop's ``actuator_node`` the same way, or is wired (``tau_a``) when the loop names none;
* :class:`TschCarrier` (``kind: gateway`` with ``mac: tsch``): the same routes, carried slot by
  slot by a TSCH network (:class:`gateway.tsch.network.TschNetwork`: the manager's schedule, the
  MAC's queues, retries and channel hopping), so a packet's fate is known only as the slots run
  and a change of sampling rates must fit the slotframe's cells.

An actuator-only loop (``sensor: null``) has no sensor path; a measurement-only loop
(``actuator: null``) no actuator path (nothing is ever sent on it). A **link** (the scenario's
``links:``, data from one controller to another) naming the node is carried like a sensor path:
a constant ``delay`` over a wired network, or routed over the topology from its ``source_node``
to its ``dest_node`` (path ``<link>.link``). A gateway proposes each configuration with the
paper's three delay estimates (seed 000, III.E step 1).

Every path draws from its own generator, seeded from the scenario seed, the network node's name,
the loop and the direction, so the draws do not depend on the order in which engines handle
paths, and the bus engines and the direct engine deliver identical packets at identical times.
"""

from __future__ import annotations

import enum
import math
import zlib
from abc import ABC, abstractmethod
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
from gateway.tsch.link_quality import LinkQuality
from gateway.tsch.mac import Outcome
from gateway.tsch.network import TschNetwork, effective_links, link_quality_of
from gateway.tsch.schedule import Schedule

__all__ = [
    "CarrierSpec",
    "PathCarrier",
    "WiredCarrier",
    "PerHopCarrier",
    "TschCarrier",
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

_PathKey = tuple[str, str]  # (loop or link, direction)
_Routes = dict[_PathKey, Route | None]


class _Done(enum.Enum):
    """The sentinel of a replayed trace that has run out (an enum, so that it has a type)."""

    DONE = enum.auto()


_DONE: Final = _Done.DONE  # a replayed trace has run out


@dataclass(frozen=True)
class Carried:
    """What the network did with a packet (:meth:`PathCarrier.drain`): delivered at
    ``t_deliver`` (ticks) or lost (``None``, with a TSCH MAC's ``reason``)."""

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


def _path_rng(seed: int, node: str, name: str, stream: int, *more: int) -> np.random.Generator:
    """The generator of one path's ``stream`` (:data:`_STREAM`, ...), from the scenario's seed,
    the network node and the path's loop or link (and ``more``, e.g. a time)."""
    return np.random.default_rng(
        [seed, zlib.crc32(node.encode()), zlib.crc32(name.encode()), stream, *more]
    )


def initial_routes(
    spec: CarrierSpec,
) -> tuple[Topology | None, Any, _Routes]:
    """The routes of ``spec``'s network before the run: its topology (``None`` for a wired
    network; over a TSCH network's links as its link quality draws them, with that quality)
    and the route of every path it routes, ``(loop or link, direction) -> Route`` (``None``:
    down). What :class:`PathCarrier` starts from, and all a hop count needs
    (:func:`initial_hops`), without the MAC, the energy or the generators."""
    if spec.gateway is None:
        return None, None, {}
    return _gateway_routes(spec)


def _gateway_routes(spec: CarrierSpec) -> tuple[Topology, LinkQuality | None, _Routes]:
    """:func:`initial_routes` of a gateway (``spec.gateway`` set)."""
    cfg = spec.gateway
    if cfg is None:
        raise ValueError(f"{spec.node}: a wired network has no topology to route over")
    routes: _Routes = {}
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


class PathCarrier(ABC):
    """The loop paths of one network node: the protocol the network behaviour carries packets
    with, and the bookkeeping every kind of network shares (routes, wired paths, what each
    path carried, time stamps).

    Build one with :meth:`from_spec`. A packet enters with :meth:`submit`; what became of it
    (:class:`Carried`) comes out of :meth:`drain`, after :meth:`advance` has run the network up
    to now; :meth:`next_wakeup` says when the network next has something to do. What differs
    between networks is a method each implementation answers in its own way: how a packet's
    delivery time is found (:meth:`deliver`), a reconfiguration (:meth:`apply`,
    :meth:`set_routes`), whether sampling periods fit (:meth:`granted`,
    :meth:`infeasible_plan`), what a proposal tells of the schedule (:meth:`capacity`,
    :attr:`schedule`), energy and batteries (:meth:`energy`, :meth:`depletion`, :meth:`empty`).
    """

    topology: Topology | None
    """The routing topology (``None``: a wired network, nothing to reconfigure)."""

    def __init__(self, spec: CarrierSpec, routes: _Routes) -> None:
        self.node = spec.node
        self._seed = spec.seed
        self.loops = dict(spec.loops)
        self.links = dict(spec.links)
        self.routes = routes
        self._const: dict[_PathKey, int] = {}  # the wired paths' constant delays, ticks
        self.periods = {n: lp.tau_s for n, lp in self.loops.items() if lp.tau_s is not None}
        self.link_periods = {n: lk.period for n, lk in self.links.items()}
        self.stamps = {path: TimestampEstimator() for path in routes}
        # what each routed path carried: (t_ready, t_deliver or None), for net/stats
        self.carried: dict[_PathKey, list[tuple[int, int | None]]] = {path: [] for path in routes}
        self.events: list[tuple[int, int, Any]] = []  # scheduled reconfigurations: (t, i, event)
        self._pending: list[Carried] = []

    @staticmethod
    def from_spec(spec: CarrierSpec) -> PathCarrier:
        """The carrier of ``spec``'s network: :class:`WiredCarrier` without a gateway,
        :class:`TschCarrier` for a gateway with ``mac: tsch``, else :class:`PerHopCarrier`."""
        if spec.gateway is None:
            return WiredCarrier(spec)
        if spec.gateway.mac == "tsch":
            return TschCarrier(spec)
        return PerHopCarrier(spec)

    # -- packets ------------------------------------------------------------------------------

    def submit(self, loop: str, direction: str, t_ready: int, token: Any) -> None:
        """A packet of path ``(loop, direction)`` enters the network at ``t_ready``; what
        becomes of it comes out of :meth:`drain` (here at once, by :meth:`deliver`)."""
        t = self.deliver(loop, direction, t_ready)
        self._pending.append(Carried(loop, direction, token, t_ready, t))

    def deliver(self, loop: str, direction: str, t_ready: int) -> int | None:
        """Delivery time (ticks) of a packet ready at ``t_ready``; ``None`` if it is lost.
        ``loop`` is the link's name for ``direction == LINK``. A wired path adds its constant
        delay; a routed one is the implementation's."""
        const = self._const.get((loop, direction))
        if const is not None:
            return t_ready + const
        return self._deliver_routed(loop, direction, t_ready)

    @abstractmethod
    def _deliver_routed(self, loop: str, direction: str, t_ready: int) -> int | None:
        """:meth:`deliver` on a path that is not wired."""

    def advance(self, t: int) -> None:
        """Run the network up to ``t`` (a network that delivers at once has nothing to run)."""
        return

    def next_wakeup(self) -> int | None:
        """When the network next has something to do, ticks (``None``: nothing)."""
        return None

    def drain(self) -> list[Carried]:
        """What happened to the packets since the last call, in order."""
        out, self._pending = self._pending, []
        return out

    # -- reconfiguration ----------------------------------------------------------------------

    @abstractmethod
    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        """Apply a reconfiguration event at ``t``; reroute every path; return
        :meth:`configuration` after it."""

    @abstractmethod
    def alternatives(self) -> Any:
        """The gateway's further proposals for the topology as it is now
        (:class:`gateway.topology.Alternatives`)."""

    @abstractmethod
    def configuration(self, t: int) -> dict[str, dict[str, Any]]:
        """Path (``<loop>.<direction>``) -> hops, route, delay estimates and predicted delay
        distribution at ``t``: what a proposal carries."""

    def set_routes(self, routes: dict[str, Any], t: int) -> dict[str, dict[str, Any]]:
        """Carry the paths over ``routes`` (path name -> route, e.g. an alternative) from ``t``;
        return :meth:`configuration` after it."""
        self._idle_to(t)
        return self._rerouted(routes, t)

    def _rerouted(self, routes: Mapping[str, Any], t: int) -> dict[str, dict[str, Any]]:
        """Take every path's route from ``routes`` (path name -> route) at ``t``, replan, and
        return :meth:`configuration` after it."""
        for loop, direction in list(self.routes):
            self.routes[loop, direction] = routes[f"{loop}.{direction}"]
        self._replan(t)
        return self.configuration(t)

    def set_period(self, loop: str, period: float, t: int, next_sample: int | None = None) -> None:
        """Loop ``loop``'s sensor samples every ``period`` (time units) from ``t``: for the
        projected lifetimes (and a TSCH network's schedule: its chains start at the slot of
        ``next_sample``, the loop's next sample in ticks, default ``t``). Idle listening is
        charged up to ``t`` first."""
        self._idle_to(t)
        self.periods[loop] = period
        self._replan(t)

    def _idle_to(self, t: int) -> None:
        """Charge idle listening up to ``t``, before routes or periods change (a network whose
        energy is not metered that way: nothing)."""
        return

    def _replan(self, t: int) -> None:
        """Follow a change of routes or periods at ``t`` (a network without a schedule:
        nothing)."""
        return

    # -- sampling periods and the schedule ----------------------------------------------------

    def granted(self, period: int) -> int:
        """The sampling period (ticks) the network grants for ``period`` ticks (here the period
        itself)."""
        return period

    def infeasible_plan(self, periods: Mapping[str, float]) -> Schedule | None:
        """The schedule that lacks cells for the loops sampling at ``periods`` (time units),
        if the network cannot carry them; ``None`` if it can (here always: no slot capacity)."""
        return None

    def capacity(self) -> dict[str, Any] | None:
        """What the coordination agent needs to ask the network's manager itself
        (``Proposal.tsch``); ``None``: no manager."""
        return None

    @property
    def schedule(self) -> Schedule | None:
        """The schedule in force (``None``: no schedule)."""
        return None

    def schedule_version(self) -> int:
        """A count that changes whenever the schedule in force does (here always 0)."""
        return 0

    # -- energy -------------------------------------------------------------------------------

    @abstractmethod
    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """Per topology node at ``t``: charge spent (mAh), battery (%), projected lifetime (h)
        at the current routes and the loops' sampling periods (``None``: mains powered)."""

    def depletion(self, t: int) -> int | None:
        """When the next battery is due to run out, ticks (``None``: none will, or the network
        does not follow its batteries down)."""
        return None

    def empty(self, t: int) -> list[str]:
        """The nodes that are up and whose battery is spent at ``t`` (here none)."""
        return []

    # -- what the paths are and carried -------------------------------------------------------

    def hops(self, loop: str, direction: str = SENSOR) -> int:
        """Hops of a path (0 for a wired path or a loop without a sensor; -1 when the path is
        down)."""
        if (loop, direction) in self._const:
            return 0
        if (loop, direction) not in self.routes:
            return 0  # an actuator-only loop over a gateway: no sensor path
        route = self.routes[loop, direction]
        return -1 if route is None else route.n_hops

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

    def _carried(self, path: _PathKey, t_ready: int, t_deliver: int | None) -> None:
        """Record what routed path ``path`` did with a packet ready at ``t_ready``."""
        self.carried[path].append((t_ready, t_deliver))
        if t_deliver is not None:
            self.stamps[path].add(t_ready, t_deliver)


class WiredCarrier(PathCarrier):
    """A wired network (``kind: network``): every path a constant delay, the delay elements of
    seed 000, III.C (``tau_d`` on the sensor path, ``tau_a`` on the actuator path, a link's
    ``delay``), a sensor path first replaying its trace of delays (:attr:`CarrierSpec.traces`)
    if it has one. Nothing is routed, so there is nothing to reconfigure or propose."""

    topology = None

    def __init__(self, spec: CarrierSpec) -> None:
        super().__init__(spec, {})
        for name, link in self.links.items():
            self._const[name, LINK] = to_ticks(link.delay)
        for name, loop in self.loops.items():
            self._const[name, SENSOR] = to_ticks(loop.tau_d)
            self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
        self._traces = {
            (loop, SENSOR): iter([None if d is None else to_ticks(d) for d in trace])
            for loop, trace in spec.traces.items()
        }

    def deliver(self, loop: str, direction: str, t_ready: int) -> int | None:
        """:meth:`PathCarrier.deliver`: the next delay of the path's trace while it lasts
        (``None``: lost), then the path's constant delay."""
        trace = self._traces.get((loop, direction))
        if trace is not None:
            replayed = next(trace, _DONE)
            if replayed is not _DONE:
                return None if replayed is None else t_ready + replayed
        return super().deliver(loop, direction, t_ready)

    def _deliver_routed(self, loop: str, direction: str, t_ready: int) -> int | None:
        raise KeyError(f"{self.node}: no path {loop}.{direction}")

    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        raise ValueError(f"{self.node}: a wired network has no topology to reconfigure")

    def alternatives(self) -> Any:
        raise ValueError(f"{self.node}: a wired network has no alternative routes")

    def configuration(self, t: int) -> dict[str, dict[str, Any]]:
        """No routed path: nothing to propose."""
        return {}

    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """No radio: nothing spent."""
        return {}


class _RoutedCarrier(PathCarrier):
    """What the two kinds of gateway share: the paths routed over the topology
    (:func:`initial_routes`), a loop's actuator path wired (``tau_a``) when it names no
    ``actuator_node``, the scheduled reconfigurations, ping probes, and proposals."""

    topology: Topology

    def __init__(self, spec: CarrierSpec, topology: Topology, routes: _Routes) -> None:
        super().__init__(spec, routes)
        cfg = spec.gateway
        self.topology = topology
        for name, loop in self.loops.items():
            if loop.actuator_node is None:
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
        self._ping_probes = cfg.ping_probes
        self._ping_rng = {
            path: _path_rng(spec.seed, spec.node, path[0], _PING_STREAM[path[1]]) for path in routes
        }
        self.events = sorted(
            ((to_ticks(e.t), i, e.event) for i, e in enumerate(cfg.events)),
            key=lambda x: (x[0], x[1]),
        )

    def alternatives(self) -> Any:
        return self.topology.alternatives()

    def configuration(self, t: int) -> dict[str, dict[str, Any]]:
        """Path (``<loop>.<direction>``) -> hops (-1: down), route and the paper's three delay
        estimates (seed 000, III.E step 1) at time ``t``: time stamps of the samples delivered
        since the previous configuration, i.e. measured on the route being replaced (``None`` at
        start; the estimator then restarts), ping probes drawn at ``t`` apart from the data's
        draws (:meth:`_estimates`), and hops x the model's mean per-hop delay; with the model's
        predicted delay distribution."""
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
            if route is not None:
                estimates["ping"], estimates["hops"], predicted = self._estimates(path, route, t)
            self.stamps[path].reset()
            out[f"{loop}.{direction}"] = {
                "hops": -1 if route is None else route.n_hops,
                "route": [] if route is None else list(route.nodes),
                "estimates": estimates,
                "distribution": predicted,
            }
        return out

    @abstractmethod
    def _estimates(
        self, path: _PathKey, route: Route, t: int
    ) -> tuple[float | None, float | None, dict[str, Any]]:
        """The ping and hops estimates of ``route`` at ``t`` (time units, ``None``: infinite)
        and its predicted delay distribution (dumped)."""


class PerHopCarrier(_RoutedCarrier):
    """A WSN gateway with a per-hop delay model (``kind: gateway``, ``mac`` not ``tsch``): a
    packet's delay is drawn at once, hop by hop with retries and loss, from its path's own
    generator (:func:`gateway.paths.deliver`; ``tau_d`` the sum of the per-hop delays, seed 000,
    I); the radios' charge is metered per packet and idle listening (:class:`EnergyMeter`)."""

    def __init__(self, spec: CarrierSpec) -> None:
        topology, _, routes = _gateway_routes(spec)
        super().__init__(spec, topology, routes)
        paths = [(n, d) for n in self.loops for d in (SENSOR, ACTUATOR)]
        self._rng = {
            (name, direction): _path_rng(spec.seed, spec.node, name, _STREAM[direction])
            for name, direction in [*paths, *((n, LINK) for n in self.links)]
        }
        self.meter = EnergyMeter(spec.gateway.energy, topology)

    def _deliver_routed(self, loop: str, direction: str, t_ready: int) -> int | None:
        route = self.routes[loop, direction]
        if route is None:
            self._carried((loop, direction), t_ready, None)
            return None  # no route: the path is down and its packets are lost
        delivery = deliver(route, t_ready, self._rng[loop, direction])
        self._carried((loop, direction), t_ready, delivery.t_deliver)
        self.meter.record(route, delivery)
        return delivery.t_deliver

    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        """:meth:`PathCarrier.apply`; idle listening is charged up to ``t`` first. Interference
        is refused: the per-hop models have no channels."""
        if isinstance(event, Interference):
            raise ValueError(
                "interference needs a TSCH network (mac: tsch); the per-hop models have no channels"
            )
        self.meter.advance(t)
        return self._rerouted(self.topology.apply(event).routes, t)

    def _idle_to(self, t: int) -> None:
        self.meter.advance(t)

    def _estimates(
        self, path: _PathKey, route: Route, t: int
    ) -> tuple[float | None, float | None, dict[str, Any]]:
        """Ping probes of the per-hop model from the path's probe generator
        (:func:`gateway.estimates.ping_estimate`), hops x the mean per-hop delay, and the
        model's distribution (:meth:`_predicted`)."""
        ping = ping_estimate(route, t, self._ping_rng[path], probes=self._ping_probes)
        hops = _finite(hops_estimate(route).tau_d)
        return _finite(ping.tau_d), hops, self._predicted(path, route, t)

    def _predicted(self, path: _PathKey, route: Route, t: int) -> dict[str, Any]:
        """The model's delay distribution of ``route`` (:func:`gateway.distribution.predict`),
        drawn from a generator of its own, seeded by the path and ``t``: the same route proposed
        at the same time gets the same prediction in every engine."""
        loop, direction = path
        rng = _path_rng(self._seed, self.node, loop, _MODEL_STREAM[direction], t)
        return distribution.predict(route, t, rng).model_dump()

    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """:meth:`PathCarrier.energy` by the meter, lifetimes projected by
        :func:`gateway.energy.projected_lifetime`."""
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


class TschCarrier(_RoutedCarrier):
    """A TSCH gateway (``kind: gateway`` with ``mac: tsch``; docs/tsch.md): the routes carried
    slot by slot by a :class:`gateway.tsch.network.TschNetwork` under its manager's schedule,
    which follows every change of routes and periods. A packet goes into the MAC's queues and
    comes out delivered or lost (with the MAC's reason) as the slots run (:meth:`advance`); a
    change of sampling periods is granted in whole slotframes and must fit the slotframe's
    cells (:meth:`infeasible_plan`); the estimates, the energy and the batteries are the
    network's own."""

    def __init__(self, spec: CarrierSpec) -> None:
        topology, quality, routes = _gateway_routes(spec)
        super().__init__(spec, topology, routes)
        cfg = spec.gateway
        self.tsch = TschNetwork(
            cfg.tsch,
            cfg.energy,
            topology,
            quality,
            seed=[spec.seed, zlib.crc32(spec.node.encode()), _TSCH_STREAM],
        )
        self._next_sample: dict[str, int] = {}  # loop -> its next sample, ticks
        self._tokens: dict[int, tuple[str, str, Any, int]] = {}
        self._serial = 0
        self._replan(0)

    # -- packets go in, outcomes come out as its slots run ------------------------------------

    def submit(self, loop: str, direction: str, t_ready: int, token: Any) -> None:
        """:meth:`PathCarrier.submit`: a routed packet joins the MAC's queue (a wired path's
        comes out at once)."""
        if (loop, direction) in self._const:
            super().submit(loop, direction, t_ready, token)
            return
        self._serial += 1
        self._tokens[self._serial] = (loop, direction, token, t_ready)
        route = self.routes[loop, direction]
        early = self.tsch.mac.submit(self._serial, None if route is None else route.nodes, t_ready)
        if early is not None:
            self._take([early])

    def _deliver_routed(self, loop: str, direction: str, t_ready: int) -> int | None:
        raise RuntimeError(f"{self.node}: a TSCH network carries with submit(), not deliver()")

    def advance(self, t: int) -> None:
        """Run the TSCH network's slots that start before ``t``."""
        self._take(self.tsch.mac.advance(t))

    def next_wakeup(self) -> int | None:
        """The end of the TSCH network's next busy slot, ticks."""
        return self.tsch.mac.next_wakeup()

    def _take(self, outcomes: list[Outcome]) -> None:
        for o in outcomes:
            loop, direction, token, t_ready = self._tokens.pop(o.id)
            done = o.t if o.delivered else None
            self._carried((loop, direction), t_ready, done)
            self._pending.append(Carried(loop, direction, token, t_ready, done, o.reason))

    # -- reconfiguration ----------------------------------------------------------------------

    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        """:meth:`PathCarrier.apply`: the slots up to ``t`` run first; interference and a
        degraded link change the channels' quality, a node going down or up the MAC's queues;
        the manager then schedules the new routes."""
        self.advance(t)
        routes = self.topology.apply(event).routes
        if isinstance(event, Interference):
            self.tsch.interfere(event.channels, event.prr, t, event.duration, event.receivers)
        elif isinstance(event, LinkDegraded):
            self.tsch.degrade(event.a, event.b, event.prr)
        elif isinstance(event, NodeDown | NodeUp):
            self._take(self.tsch.mac.set_down(event.node, isinstance(event, NodeDown), t))
        return self._rerouted(routes, t)

    def set_period(self, loop: str, period: float, t: int, next_sample: int | None = None) -> None:
        self._next_sample[loop] = t if next_sample is None else next_sample
        super().set_period(loop, period, t, next_sample)

    def _replan(self, t: int) -> None:
        """The manager's schedule for the routes and periods now, applied from ``t``."""
        self._take(
            self.tsch.reschedule(
                self.route_nodes(), self.path_periods(), t, offsets=self.path_offsets()
            )
        )

    def path_offsets(self) -> dict[str, int]:
        """Path name -> the slot of its next packet. A sensor path's is its loop's next sample;
        the actuator path's follows the sensor path's chain (its move is made when the sample
        arrives); a link's is 0."""
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

    # -- sampling periods and the schedule ----------------------------------------------------

    def granted(self, period: int) -> int:
        """The sampling period (ticks) the TSCH manager grants for ``period`` ticks."""
        return self.tsch.granted(period)

    def plan(self, periods: Mapping[str, float]) -> Schedule:
        """The manager's schedule if the loops sampled at ``periods`` (time units), not applied."""
        trial = {**self.periods, **periods}
        ticks = {
            f"{n}.{d}": to_ticks(self.link_periods[n] if d == LINK else trial[n])
            for (n, d) in self.routes
            if d == LINK or n in trial
        }
        return self.tsch.plan(self.route_nodes(), ticks, self.path_offsets())

    def infeasible_plan(self, periods: Mapping[str, float]) -> Schedule | None:
        """:meth:`plan` for ``periods`` if it lacks cells, else ``None``."""
        plan = self.plan(periods)
        return None if plan.feasible else plan

    def capacity(self) -> dict[str, Any]:
        return self.tsch.capacity()

    @property
    def schedule(self) -> Schedule:
        return self.tsch.schedule

    def schedule_version(self) -> int:
        """The MAC's schedule segments so far."""
        return len(self.tsch.mac.segments)

    # -- estimates and energy -----------------------------------------------------------------

    def _estimates(
        self, path: _PathKey, route: Route, t: int
    ) -> tuple[float | None, float | None, dict[str, Any]]:
        """Ping probes through a copy of the MAC, hops x the mean per-hop delay, and the
        network's predicted distribution (:class:`gateway.tsch.network.TschNetwork`)."""
        name = f"{path[0]}.{path[1]}"
        ping = _finite(self.tsch.ping(name, route.nodes, t, self._ping_probes))
        hops = _finite(self.tsch.hops_estimate(route.nodes, t))
        return ping, hops, self.tsch.predict(name, route.nodes, t).model_dump()

    def energy(self, t: int) -> dict[str, dict[str, float | None]]:
        """:meth:`PathCarrier.energy` of the TSCH network, its slots run up to ``t`` first."""
        self.advance(t)
        return self.tsch.energy(t)

    def depletion(self, t: int) -> int | None:
        """When the next battery runs out by the expected charge per slotframe from ``t`` on."""
        due = self.tsch.depletion(t)
        return None if due is None else due[0]

    def empty(self, t: int) -> list[str]:
        return self.tsch.empty(t)


def _dumped(dist: Any) -> dict[str, Any] | None:
    return None if dist is None else dist.model_dump()


def _finite(value: float) -> float | None:
    """JSON-safe: ``None`` for nan or inf."""
    return float(value) if math.isfinite(value) else None
