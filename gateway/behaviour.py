"""The network node: carries the loops that name it, wired (``kind: network``) or over a WSN
(``kind: gateway``).

Sensor samples (``plant/<p>/sensor/<s>``) are delivered on ``loop/<l>/meas``; control moves
(``loop/<l>/u``) on ``plant/<p>/actuator/<i>``; what a controller transmits on a link
(``link/<k>/tx``) is delivered on ``link/<k>/rx``. When a packet arrives, its delivery time comes
from :class:`gateway.carrier.PathCarrier` (constant delays, or per-hop delays with retries and loss
drawn from the path's own seeded generator); a lost packet is reported on ``net/lost`` and never
delivered. A delivery due now is published in this round (a microstep), a later one is a timer,
so in real-time mode delays pass in wall time through the same clock.

A gateway proposes its configuration (``net/proposal``: routes, hops, the three delay estimates)
at start and after every reconfiguration. With no coordination agent in the scenario it applies
it at once (``net/applied``). Under an agent (seed 000, III.E) it waits for the verdict on
``wncsca/decision``: accepted, it confirms on ``net/applied``; rejected, it proposes its next
alternative (routes with a lower mean delay for the offending paths,
:class:`gateway.topology.Alternatives`), or, with none left, says so (``net/applied`` with event
``no_alternative``) and keeps carrying its best routes. Every network node, wired or not, applies
the sampling periods the agent assigns (``wncsca/rates``) by telling the plants' sensors
(``plant/<p>/sampling/<s>``) and confirms them on ``net/applied`` (event ``rates``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bus_schemas import (
    Decision,
    Estimate,
    Loss,
    Move,
    NetApplied,
    NetStats,
    NetworkEvent,
    Proposal,
    Rates,
    Sample,
    SamplingPeriod,
    keys,
)
from bus_schemas.envelope import RawEnvelope
from core.behaviour import Behaviour
from core.time import to_ticks, to_units
from gateway.carrier import ACTUATOR, LINK, SENSOR, PathCarrier
from gateway.topology import parse_event

__all__ = ["NetworkBehaviour", "NetworkSpec"]


@dataclass(frozen=True)
class NetworkSpec:
    """What a network or gateway node needs of its scenario, computed once
    (:func:`runtime.specs.network_spec`).

    Attributes
    ----------
    carrier : PathCarrier
        Its loops' and links' paths (built from the scenario: routes, delays, generators).
    governed : bool
        Whether a coordination agent judges its proposals and assigns rates.
    end : int
        End of the run, ticks.
    stats_period : int or None
        Period of ``net/stats`` (a gateway; always sent at the end), ticks.
    """

    carrier: PathCarrier
    governed: bool
    end: int
    stats_period: int | None = None


class NetworkBehaviour(Behaviour):
    def __init__(self, name: str, spec: NetworkSpec) -> None:
        super().__init__(name)
        self.spec = spec
        self.carrier = spec.carrier
        self.governed = spec.governed
        self._proposals = 0
        self._awaiting: tuple[int, str, str, dict] | None = None  # id, event, source, paths
        self._paths: dict = {}
        self._alternatives: Any = None
        self._periods = {
            n: to_ticks(lp.tau_s) for n, lp in self.carrier.loops.items() if lp.tau_s is not None
        }
        if self.carrier.topology is not None:
            self.subscribe(keys.network_events(self.name), NetworkEvent, self._on_injected)
            self.at(0, self._announce("initial", "initial", None))
            for t, _, event in self.carrier.events:
                self.at(t, self._announce(event.type, "scenario", event))
            end = spec.end
            if spec.stats_period is not None:
                period = spec.stats_period
                for t in range(period, end, period):
                    self.at(t, self._stats)
            self.at(end, self._stats)
            if self.governed:
                self.subscribe(keys.wncsca_decision(), Decision, self._on_decision)
        if self.governed and self.carrier.loops:
            self.subscribe(keys.wncsca_rates(), Rates, self._on_rates)
        for name, loop in self.carrier.loops.items():
            if loop.sensor is not None:
                self.subscribe(
                    keys.sensor(loop.plant, loop.sensor),
                    Sample,
                    self._path(name, SENSOR, keys.meas(name)),
                )
            if loop.actuator is not None:  # a measurement-only loop has no actuator path
                self.subscribe(
                    keys.move(name),
                    Move,
                    self._path(name, ACTUATOR, keys.actuator(loop.plant, loop.actuator)),
                )

        for name in self.carrier.links:
            self.subscribe(keys.link_tx(name), Estimate, self._path(name, LINK, keys.link_rx(name)))

    def _announce(self, kind: str, source: str, event: Any) -> Any:
        def apply() -> None:
            if event is None:
                paths = self.carrier.configuration(self.now)
            else:
                paths = self.carrier.apply(event, self.now)
            self._alternatives = None  # a new state of the network: alternatives start afresh
            self._propose(kind, source, paths)

        return apply

    def _propose(self, kind: str, source: str, paths: dict) -> None:
        """Propose the configuration (``net/proposal``); without an agent, apply it at once."""
        hops = {p: c["hops"] for p, c in paths.items()}
        self.log.info(
            "network configuration #%d (%s %s): hops %s", self._proposals, source, kind, hops
        )
        self._paths = paths
        self.publish(
            keys.net_proposal(),
            Proposal(id=self._proposals, event=kind, source=source, paths=paths),
        )
        if self.governed:
            self._awaiting = (self._proposals, kind, source, paths)
        else:
            self.publish(keys.net_applied(), NetApplied(event=kind, source=source, paths=paths))
        self._proposals += 1

    def _on_decision(self, env: RawEnvelope, decision: Decision) -> None:
        if decision.subject != "proposal" or decision.network not in (None, self.name):
            return
        if self._awaiting is None or decision.proposal != self._awaiting[0]:
            return  # not about the proposal waiting for a verdict
        pid, kind, source, paths = self._awaiting
        if decision.verdict == "accept":
            self._awaiting = None
            self.publish(
                keys.net_applied(),
                NetApplied(event=kind, source=source, paths=paths, proposal=pid),
            )
        elif decision.verdict == "reject":
            if self._alternatives is None:
                self._alternatives = self.carrier.alternatives()
            routes = self._alternatives.next(decision.paths or None)
            if routes is None:
                self._awaiting = None
                self.log.warning("proposal #%d rejected and no alternative is left", pid)
                self.publish(
                    keys.net_applied(),
                    NetApplied(event="no_alternative", source="agent", paths=paths, proposal=pid),
                )
                return
            self._propose("alternative", "alternative", self.carrier.set_routes(routes, self.now))

    def _on_rates(self, env: RawEnvelope, rates: Rates) -> None:
        changed = {}
        for name, loop in self.carrier.loops.items():
            if loop.sensor is None:
                continue
            period = rates.periods.get(name)
            if period is None or period == self._periods[name]:
                continue
            self._periods[name] = period
            self.carrier.set_period(name, to_units(period), self.now)
            self.publish(keys.sampling(loop.plant, loop.sensor), SamplingPeriod(period=period))
            changed[name] = period
        if changed:
            self.publish(
                keys.net_applied(),
                NetApplied(
                    event="rates",
                    source="agent",
                    paths=self._paths,
                    proposal=rates.proposal,
                    periods=dict(self._periods),
                ),
            )

    def _stats(self) -> None:
        self.publish(
            keys.net_stats(),
            NetStats(paths=self.carrier.path_stats(self.now), nodes=self.carrier.energy(self.now)),
        )

    def _on_injected(self, env: RawEnvelope, msg: NetworkEvent) -> None:
        """An event injected while the run goes on (``wncs inject``), stamped by the clock."""
        try:
            event = parse_event(msg.event)
            paths = self.carrier.apply(event, self.now)
        except ValueError as err:  # e.g. a node that is not there any more: refused, run goes on
            self.log.warning("injected event %s refused: %s", msg.event, err)
            return
        self._alternatives = None
        self._propose(event.type, "injected", paths)

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
