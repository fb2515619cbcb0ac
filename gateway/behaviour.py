"""The network node: carries the loops that name it, wired (``kind: network``) or over a WSN
(``kind: gateway``).

Sensor samples (``plant/<p>/sensor/<s>``) are delivered on ``loop/<l>/meas``; control moves
(``loop/<l>/u``) on ``plant/<p>/actuator/<i>``; what a controller transmits on a link
(``link/<k>/tx``) is delivered on ``link/<k>/rx``. When a packet arrives it is handed to the
node's :class:`gateway.carrier.PathCarrier`, which says what became of it: at once (constant
delays, or per-hop delays with retries and loss drawn from the path's own seeded generator) or
as a TSCH network's slots run. A lost packet is reported on ``net/lost`` and never delivered. A
delivery due now is published in this round (a microstep), a later one is a timer, so in
real-time mode delays pass in wall time through the same clock.

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
    ScheduleSummary,
    keys,
)
from bus_schemas.envelope import RawEnvelope
from core.behaviour import Behaviour
from core.time import to_ticks, to_units
from gateway.carrier import ACTUATOR, LINK, SENSOR, PathCarrier
from gateway.topology import NodeDown, parse_event
from gateway.tsch.schedule import Schedule

__all__ = ["NetworkBehaviour", "NetworkSpec"]


@dataclass(frozen=True)
class NetworkSpec:
    """What a network or gateway node needs of its scenario, computed once
    (:func:`scenario.views.network_spec`).

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
        self._wakes: set[int] = set()  # a TSCH network's pending wake-ups (ends of busy slots)
        self._last_sample: dict[str, int] = {}  # loop -> its last sample's time, ticks
        self._battery_check: int | None = None
        self._battery_version: int | None = None  # the schedule the last prediction was for
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
            self._pump()

        return apply

    def _propose(self, kind: str, source: str, paths: dict) -> None:
        """Propose the configuration (``net/proposal``); without an agent, apply it at once."""
        hops = {p: c["hops"] for p, c in paths.items()}
        self.log.info(
            "network configuration #%d (%s %s): hops %s", self._proposals, source, kind, hops
        )
        self._paths = paths
        tsch = self.carrier.capacity()
        self.publish(
            keys.net_proposal(),
            Proposal(id=self._proposals, event=kind, source=source, paths=paths, tsch=tsch),
        )
        if self.governed:
            self._awaiting = (self._proposals, kind, source, paths)
        else:
            self.publish(
                keys.net_applied(),
                NetApplied(event=kind, source=source, paths=paths, schedule=self._summary()),
            )
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
                NetApplied(
                    event=kind,
                    source=source,
                    paths=paths,
                    proposal=pid,
                    schedule=self._summary(),
                ),
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
                    NetApplied(
                        event="no_alternative",
                        source="agent",
                        paths=paths,
                        proposal=pid,
                        reason=f"{source} {kind}: proposal #{pid} rejected, no alternative left; "
                        "the network runs it",
                    ),
                )
                return
            self._propose("alternative", "alternative", self.carrier.set_routes(routes, self.now))
            self._pump()

    def _on_rates(self, env: RawEnvelope, rates: Rates) -> None:
        if not self._can_carry(rates):
            return
        changed = {}
        for name, loop in self.carrier.loops.items():
            if loop.sensor is None:
                continue
            period = rates.periods.get(name)
            if period is None:
                continue
            period = self.carrier.granted(period)  # a TSCH manager's grant; else as asked
            if period == self._periods[name]:
                continue
            self._periods[name] = period
            last = self._last_sample.get(name)
            nxt = self.now if last is None else max(last + period, self.now)
            self.carrier.set_period(name, to_units(period), self.now, next_sample=nxt)
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
                    schedule=self._summary(),
                ),
            )
            self._pump()

    def _can_carry(self, rates: Rates) -> bool:
        """The network's answer to the agent's periods: it can carry them (a network without
        slot capacity always can), or a TSCH manager refuses them on ``net/applied`` (event
        ``rates_refused``) naming the links that lack cells, and keeps the periods in force."""
        asked = {
            n: to_units(self.carrier.granted(p))
            for n, p in rates.periods.items()
            if n in self.carrier.loops and self.carrier.loops[n].sensor is not None
        }
        plan = self.carrier.infeasible_plan(asked)
        if plan is None:
            return True
        reason = f"the manager cannot carry these periods: {plan.describe_lack()}"
        self.log.warning("rates refused: %s", reason)
        self.publish(
            keys.net_applied(),
            NetApplied(
                event="rates_refused",
                source="agent",
                paths=self._paths,
                proposal=rates.proposal,
                periods=dict(self._periods),
                schedule=_summary_of(plan, {}),
                reason=reason,
            ),
        )
        return False

    def _summary(self) -> ScheduleSummary | None:
        """The schedule in force and the lifetimes it projects (a TSCH gateway)."""
        schedule = self.carrier.schedule
        if schedule is None:
            return None
        energy = self.carrier.energy(self.now)
        self._pump()
        return _summary_of(schedule, {n: e["lifetime_h"] for n, e in energy.items()})

    def _stats(self) -> None:
        self.publish(
            keys.net_stats(),
            NetStats(paths=self.carrier.path_stats(self.now), nodes=self.carrier.energy(self.now)),
        )
        self._pump()

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
        self._pump()

    def _path(self, loop: str, direction: str, out_key: str) -> Any:
        def forward(env: RawEnvelope, body: Any) -> None:
            if direction == SENSOR:
                self._last_sample[loop] = body.t_sampled
            self.carrier.submit(loop, direction, self.now, (out_key, body))
            self._pump()

        return forward

    def _pump(self) -> None:
        """Publish what the network carried up to now (a lost packet on ``net/lost``, a packet
        due later as a timer), and wake when it next has something to do (a TSCH network: the
        end of its next busy slot); check the batteries when one is due to run out."""
        self.carrier.advance(self.now)
        for c in self.carrier.drain():
            out_key, body = c.token
            if c.t_deliver is None:
                self.publish(
                    keys.net_lost(),
                    Loss(loop=c.loop, direction=c.direction, t_ready=c.t_ready, reason=c.reason),
                )
            elif c.t_deliver <= self.now:
                self.publish(out_key, body)
            else:  # delivered later: a delay drawn at once, or a constant (wired) path
                self.at(c.t_deliver, lambda k=out_key, b=body: self.publish(k, b))
        wake = self.carrier.next_wakeup()
        if wake is not None and wake not in self._wakes:
            self._wakes.add(wake)
            self.at(wake, self._woken(wake))
        self._plan_battery_check()

    def _woken(self, t: int) -> Any:
        def wake() -> None:
            self._wakes.discard(t)
            self._pump()

        return wake

    def _plan_battery_check(self) -> None:
        """Plan a battery check for when the next battery is due to run out, computed again
        whenever the schedule changes (a new segment of the MAC) or a check has fired."""
        if self._battery_check is not None:
            return
        version = self.carrier.schedule_version()
        if version == self._battery_version:
            return
        self._battery_version = version
        due = self.carrier.depletion(self.now)
        if due is None or due > self.spec.end:
            return
        at = max(due, self.now)
        self._battery_check = at
        self.at(at, self._check_batteries)

    def _check_batteries(self) -> None:
        """A battery due to run out: the nodes whose charge is spent go down (as ``node_down``:
        the gateway reroutes and proposes); otherwise the check is planned again."""
        self._battery_check = None
        self._battery_version = None
        self.carrier.advance(self.now)
        for node in self.carrier.empty(self.now):
            self.log.warning("node %s: battery empty at t = %s", node, to_units(self.now))
            paths = self.carrier.apply(NodeDown(node=node), self.now)
            self._alternatives = None
            self._propose("battery_empty", "battery", paths)
        self._pump()


def _summary_of(schedule: Schedule, lifetimes: dict[str, float | None]) -> ScheduleSummary:
    return ScheduleSummary(
        cells={f"{a}->{b}": n for (a, b), n in schedule.cells_per_frame().items()},
        lacking={f"{a}->{b}": n for (a, b), n in schedule.lacking.items()},
        lifetime_h=lifetimes,
    )
