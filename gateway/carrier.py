"""Delivery times of a network node's loop paths, shared by the network nodes and the direct engine.

A loop's sensor path (sensor -> controller) and actuator path (controller -> actuator) are carried
by the node its ``network:`` names:

* ``kind: network`` (wired): constant delays ``tau_d`` and ``tau_a``;
* ``kind: gateway`` (WSN): the sensor path is routed over the gateway's topology from the loop's
  ``sensor_node`` to the gateway, every packet's delay drawn hop by hop with retries and loss
  (:func:`gateway.paths.deliver`); the actuator path goes back from the gateway to the loop's
  ``actuator_node`` the same way, or is wired (``tau_a``) when the loop names none.

Every path draws from its own generator, seeded from the scenario seed, the network node's name,
the loop and the direction, so the draws do not depend on the order in which engines handle
paths, and the bus engines and the direct engine deliver identical packets at identical times.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from gateway.paths import Route, deliver
from gateway.topology import Topology
from runtime.time import to_ticks

__all__ = ["PathCarrier", "path_hops", "SENSOR", "ACTUATOR"]

SENSOR, ACTUATOR = "sensor", "actuator"


class PathCarrier:
    """The loop paths of one network node.

    Parameters
    ----------
    scenario : Scenario
        The validated scenario.
    node : str
        Name of a ``network`` or ``gateway`` node.
    """

    def __init__(self, scenario: Any, node: str) -> None:
        cfg = scenario.nodes[node]
        self.node = node
        self.kind = cfg.kind
        self.loops = {n: lp for n, lp in sorted(scenario.loops.items()) if lp.network == node}
        self._rng: dict[tuple[str, str], np.random.Generator] = {}
        self._const: dict[tuple[str, str], int] = {}
        self.routes: dict[tuple[str, str], Route | None] = {}
        topology = None
        if cfg.kind == "gateway":
            topology = Topology(cfg.topology)
            gateway = cfg.gateway_node()
        for name, loop in self.loops.items():
            for direction in (SENSOR, ACTUATOR):
                self._rng[name, direction] = np.random.default_rng(
                    [
                        scenario.seed,
                        zlib.crc32(node.encode()),
                        zlib.crc32(name.encode()),
                        0 if direction == SENSOR else 1,
                    ]
                )
            if topology is None:
                self._const[name, SENSOR] = to_ticks(loop.tau_d)
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
                continue
            topology.add_path(f"{name}.sensor", loop.sensor_node, gateway)
            self.routes[name, SENSOR] = topology.routes()[f"{name}.sensor"]
            if loop.actuator_node is None:
                self._const[name, ACTUATOR] = to_ticks(loop.tau_a)
            else:
                topology.add_path(f"{name}.actuator", gateway, loop.actuator_node)
                self.routes[name, ACTUATOR] = topology.routes()[f"{name}.actuator"]
        self.topology = topology
        self.events = (
            sorted(
                ((to_ticks(e.t), i, e.event) for i, e in enumerate(cfg.events)),
                key=lambda x: (x[0], x[1]),
            )
            if cfg.kind == "gateway"
            else []
        )

    def apply(self, event: Any) -> dict[str, int]:
        """Apply a reconfiguration event; reroute every path; return path -> hops after it."""
        if self.topology is None:
            raise ValueError(f"{self.node}: a wired network has no topology to reconfigure")
        routes = self.topology.apply(event).routes
        for loop, direction in list(self.routes):
            self.routes[loop, direction] = routes[f"{loop}.{direction}"]
        return self.configuration()

    def configuration(self) -> dict[str, int]:
        """Path (``<loop>.<direction>``) -> hops now (-1: down) for the routed paths."""
        return {
            f"{loop}.{direction}": (-1 if route is None else route.n_hops)
            for (loop, direction), route in sorted(self.routes.items())
        }

    def hops(self, loop: str, direction: str = SENSOR) -> int:
        """Hops of a path (0 for a wired path; -1 when the path is down)."""
        if (loop, direction) in self._const:
            return 0
        route = self.routes[loop, direction]
        return -1 if route is None else route.n_hops

    def deliver(self, loop: str, direction: str, t_ready: int) -> int | None:
        """Delivery time (ticks) of a packet ready at ``t_ready``; ``None`` if it is lost."""
        const = self._const.get((loop, direction))
        if const is not None:
            return t_ready + const
        route = self.routes[loop, direction]
        if route is None:
            return None  # no route: the path is down and its packets are lost
        return deliver(route, t_ready, self._rng[loop, direction]).t_deliver


def path_hops(scenario: Any) -> dict[str, int]:
    """Loop -> hops of its sensor path (0 wired, -1 down), for every loop of the scenario."""
    out: dict[str, int] = {}
    for name, cfg in sorted(scenario.nodes.items()):
        if cfg.kind in ("network", "gateway"):
            carrier = PathCarrier(scenario, name)
            out.update({loop: carrier.hops(loop) for loop in carrier.loops})
    return out
