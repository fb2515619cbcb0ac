"""The network node: carries the loops that name it, wired (``kind: network``) or over a WSN
(``kind: gateway``).

Sensor samples (``plant/<p>/sensor/<s>``) are delivered on ``loop/<l>/meas``; control moves
(``loop/<l>/u``) on ``plant/<p>/actuator/<i>``. When a packet arrives, its delivery time comes from
:class:`gateway.carrier.PathCarrier` (constant delays, or per-hop delays with retries and loss
drawn from the path's own seeded generator); a lost packet is reported on ``net/lost`` and never
delivered. A
delivery due now is published in this round (a microstep), a later one is a timer, so in
real-time mode delays pass in wall time through the same clock.
"""

from __future__ import annotations

from typing import Any

from bus_schemas import (
    Loss,
    Move,
    NetApplied,
    NetStats,
    NetworkEvent,
    Proposal,
    Sample,
    keys,
)
from bus_schemas.envelope import RawEnvelope
from gateway.carrier import ACTUATOR, SENSOR, PathCarrier
from runtime.node import Node, NodeContext
from runtime.time import to_ticks

__all__ = ["NetworkNode"]


class NetworkNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        self.carrier = PathCarrier(self.scenario, self.name)
        self._proposals = 0
        if self.carrier.topology is not None:
            self.subscribe(keys.network_events(self.name), NetworkEvent, self._on_injected)
            self.at(0, self._announce("initial", "initial", None))
            for t, _, event in self.carrier.events:
                self.at(t, self._announce(event.type, "scenario", event))
            cfg = self.scenario.nodes[self.name]
            end = to_ticks(self.scenario.end_time)
            if cfg.stats_period is not None:
                period = to_ticks(cfg.stats_period)
                for t in range(period, end, period):
                    self.at(t, self._stats)
            self.at(end, self._stats)
        for name, loop in self.carrier.loops.items():
            self.subscribe(
                keys.sensor(loop.plant, loop.sensor),
                Sample,
                self._path(name, SENSOR, keys.meas(name)),
            )
            self.subscribe(
                keys.move(name),
                Move,
                self._path(name, ACTUATOR, keys.actuator(loop.plant, loop.actuator)),
            )

    def _announce(self, kind: str, source: str, event: Any) -> Any:
        def apply() -> None:
            if event is None:
                paths = self.carrier.configuration(self.now)
            else:
                paths = self.carrier.apply(event, self.now)
            self._publish_configuration(kind, source, paths)

        return apply

    def _publish_configuration(self, kind: str, source: str, paths: dict) -> None:
        """Propose the configuration (``net/proposal``, for the coordination agent) and, as no
        agent decides yet, apply it at once (``net/applied``)."""
        hops = {p: c["hops"] for p, c in paths.items()}
        self.log.info("network configuration (%s %s): hops %s", source, kind, hops)
        self.publish(
            keys.net_proposal(),
            Proposal(id=self._proposals, event=kind, source=source, paths=paths),
        )
        self._proposals += 1
        self.publish(keys.net_applied(), NetApplied(event=kind, source=source, paths=paths))

    def _stats(self) -> None:
        self.publish(
            keys.net_stats(),
            NetStats(paths=self.carrier.path_stats(self.now), nodes=self.carrier.energy(self.now)),
        )

    def _on_injected(self, env: RawEnvelope, msg: NetworkEvent) -> None:
        """An event injected while the run goes on (``wncs inject``), stamped by the clock."""
        from gateway.topology import parse_event

        try:
            event = parse_event(msg.event)
            paths = self.carrier.apply(event, self.now)
        except ValueError as err:  # e.g. a node that is not there any more: refused, run goes on
            self.log.warning("injected event %s refused: %s", msg.event, err)
            return
        self._publish_configuration(event.type, "injected", paths)

    def _path(self, loop: str, direction: str, out_key: str) -> Any:
        def forward(env: RawEnvelope, body: Any) -> None:
            t = self.carrier.deliver(loop, direction, self.now)
            if t is None:
                self.publish(
                    keys.net_lost(), Loss(loop=loop, direction=direction, t_ready=self.now)
                )
            elif t == self.now:
                self.publish(out_key, body)
            else:
                self.at(t, lambda: self.publish(out_key, body))

        return forward
