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

import math
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from core.time import to_ticks
from gateway import distribution
from gateway.energy import EnergyMeter, projected_lifetime
from gateway.estimates import TimestampEstimator, hops_estimate, ping_estimate
from gateway.paths import Route, deliver
from gateway.topology import Topology

__all__ = ["CarrierSpec", "PathCarrier", "SENSOR", "ACTUATOR", "LINK"]

SENSOR, ACTUATOR, LINK = "sensor", "actuator", "link"
_STREAM = {SENSOR: 0, ACTUATOR: 1, LINK: 4}  # generator streams of a path's data
_PING_STREAM = {SENSOR: 2, ACTUATOR: 3, LINK: 5}  # and of its ping probes
_DONE = object()  # a replayed trace has run out
_MODEL_STREAM = {SENSOR: 6, ACTUATOR: 7, LINK: 8}  # and of its predicted delay distribution


@dataclass(frozen=True)
class CarrierSpec:
    """What one network node's paths are made of (:func:`runtime.specs.carrier_spec`).

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
        self.routes: dict[tuple[str, str], Route | None] = {}
        topology = None
        self.wireless = cfg is not None
        if cfg is not None:
            topology = Topology(cfg.topology)
            gateway = cfg.gateway_node()
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
        for name, link in self.links.items():
            if topology is None:
                self._const[name, LINK] = to_ticks(link.delay)
                continue
            topology.add_path(f"{name}.link", link.source_node, link.dest_node)
            self.routes[name, LINK] = topology.routes()[f"{name}.link"]
        for name, loop in self.loops.items():
            if topology is None:
                self._const[name, SENSOR] = to_ticks(loop.tau_d)
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
                continue
            if loop.sensor is not None:
                topology.add_path(f"{name}.sensor", loop.sensor_node, gateway)
                self.routes[name, SENSOR] = topology.routes()[f"{name}.sensor"]
            if loop.actuator_node is None:
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
            else:
                topology.add_path(f"{name}.actuator", gateway, loop.actuator_node)
                self.routes[name, ACTUATOR] = topology.routes()[f"{name}.actuator"]
        self.topology = topology
        self.periods = {n: lp.tau_s for n, lp in self.loops.items() if lp.tau_s is not None}
        self.link_periods = {n: lk.period for n, lk in self.links.items()}
        self.meter = EnergyMeter(cfg.energy, topology) if topology is not None else None
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

    def apply(self, event: Any, t: int) -> dict[str, dict[str, Any]]:
        """Apply a reconfiguration event at ``t``; reroute every path; return
        :meth:`configuration` after it. Idle listening is charged up to ``t`` first."""
        if self.topology is None or self.meter is None:
            raise ValueError(f"{self.node}: a wired network has no topology to reconfigure")
        self.meter.advance(t)
        routes = self.topology.apply(event).routes
        for loop, direction in list(self.routes):
            self.routes[loop, direction] = routes[f"{loop}.{direction}"]
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
        return self.configuration(t)

    def set_period(self, loop: str, period: float, t: int) -> None:
        """Loop ``loop``'s sensor samples every ``period`` (time units) from ``t``: for the
        projected lifetimes. Idle listening is charged up to ``t`` first."""
        if self.meter is not None:
            self.meter.advance(t)
        self.periods[loop] = period

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
            if route is not None:
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
            delays = np.array([(d - r) / 1e6 for r, d in done if d is not None])
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
        route = self.routes.get((loop, direction), self)
        if route is self:
            return 0  # an actuator-only loop over a gateway: no sensor path
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


def _dumped(dist: Any) -> dict[str, Any] | None:
    return None if dist is None else dist.model_dump()


def _finite(value: float) -> float | None:
    """JSON-safe: ``None`` for nan or inf."""
    return float(value) if math.isfinite(value) else None
