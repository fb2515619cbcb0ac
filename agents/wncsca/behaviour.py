"""The WNCSCA node: the coordination agent on the bus (seed 000, section II and III.E).

It listens to ``net/proposal`` (every gateway's configurations), ``net/applied`` (a gateway
with no alternative left), ``ops/mode`` and ``ops/setpoint/<loop>``; it answers on
``wncsca/decision`` (accept / reject with reasons and bounds / refuse a malformed request /
keep the last accepted configuration) and assigns periods and loop states on ``wncsca/rates``,
which the network nodes apply and the controllers follow; accepted set points go to the
controllers on ``loop/<l>/sp`` at their time. Requests arrive typed (:class:`~bus_schemas.Proposal`,
:class:`~bus_schemas.ModeRequest`, :class:`~bus_schemas.Setpoint`); one that does not fit its
schema reaches the ``on_invalid`` handler of its subscription and is refused on the bus naming
every field that is wrong, and nothing changes; what the schema cannot know (an unknown loop or
mode, a network that is no gateway) the core refuses
(:class:`~agents.wncsca.coordinator.Coordinator`). The wall-clock time of each decision goes on
``wncsca/timing`` (a measurement: left out of the history digest).

With ``identify:`` the agent first runs its identification experiment
(:mod:`agents.wncsca.experiment`): it passes the experiment's set-point moves on, keeps every
delivered ``loop/<l>/meas`` sample, and at the experiment's end publishes its identified model on
``wncsca/model`` (:class:`~bus_schemas.ModelEstimate`), a ``model`` decision, and its judgement
again of each running configuration on that model.

With ``watch:`` the agent keeps what its loops deliver for the test's length after each step it
judged, and at the end says on ``wncsca/decision`` (subject ``model``) whether its model still
fits (:mod:`agents.wncsca.watch`); when it does not, it identifies again (``identify:``: the
experiment from then on) or widens its stated uncertainty and judges the running configurations
again.
"""

from __future__ import annotations

import time
from functools import partial
from typing import Any

from agents.wncsca.coordinator import Coordinator, Negotiation
from agents.wncsca.decision import Decision as AgentDecision
from agents.wncsca.experiment import Experiment
from agents.wncsca.window import Window
from bus_schemas import Decision, ModeRequest, Proposal, Rates, Sample, Setpoint, Timing, keys
from bus_schemas.bodies import NetApplied
from bus_schemas.envelope import RawEnvelope
from bus_schemas.errors import SchemaError
from core.behaviour import Behaviour, Handler, InvalidHandler
from core.time import to_ticks

__all__ = ["WncscaBehaviour"]


class WncscaBehaviour(Behaviour):
    """The agent node ``name`` around its core (the node kind's build,
    :func:`scenario.views.agent_behaviour`, hands it the coordinator of its spec)."""

    def __init__(self, name: str, core: Coordinator) -> None:
        super().__init__(name)
        self.core = core
        self._requests: dict[str, Setpoint] = {}  # loop -> its last accepted set-point request
        t0 = time.perf_counter()
        bounds = self.core.bounds  # once, before the run: III.E step 2's tau_d-max
        self.log.info(
            "delay bounds at the benchmark periods: %s (%.2f s)",
            {n: round(b.tau_d_max, 4) for n, b in bounds.items()},
            time.perf_counter() - t0,
        )
        self.subscribe(
            keys.net_proposal(), Proposal, self._on_proposal, on_invalid=self._on_bad_proposal
        )
        self.subscribe(keys.net_applied(), NetApplied, self._on_applied)
        self.subscribe(keys.ops_mode(), ModeRequest, self._on_mode, on_invalid=self._on_bad_mode)
        for loop in self.core.loops:
            self.subscribe(
                keys.setpoint(loop),
                Setpoint,
                self._on_setpoint(loop),
                on_invalid=self._on_bad_setpoint(loop),
            )
            cfg = self.core.config
            if loop in cfg.alarm or cfg.identify is not None or cfg.watch is not None:
                self.subscribe(keys.meas(loop), Sample, self._on_meas(loop))
        self._initial_links = self.core.govern_links()  # wired links: judged before the run
        for v in self._initial_links:
            (self.log.info if v.verdict == "accept" else self.log.warning)("%s", v.reasons[0])
        self.at(0, self._start)

    def _start(self) -> None:
        for v in self._initial_links:
            self.publish(
                keys.wncsca_decision(),
                Decision(
                    subject="links",
                    verdict=v.verdict,
                    reasons=v.reasons,
                    delays={n: v.delay for n in v.links},
                    offending=() if v.verdict == "accept" else v.links,
                    links=(v.as_dict(),),
                ),
            )
        started = self.core.start_identification()
        if started is not None:
            self._publish_mode(started)
            self._run_experiment()
        self._publish_rates()

    def _publish_mode(self, d: AgentDecision) -> None:
        self.publish(
            keys.wncsca_decision(), Decision(subject="mode", verdict=d.verdict, reasons=d.reasons)
        )

    def _run_experiment(self) -> None:
        """Pass the experiment's set-point moves on at their times (unless it was aborted by
        then), and fit its data at its end."""
        exp = self.core.experiment
        assert exp is not None
        for t, loop, value in exp.changes:

            def move(loop: str = loop, value: float = value) -> None:
                if self.core.experiment is exp:
                    self._pass_on(loop, value)

            self.at(to_ticks(t), move)
        self.at(to_ticks(exp.end), lambda: self._identified(exp))

    def _identified(self, exp: Experiment) -> None:
        if self.core.experiment is not exp:
            return  # aborted
        t0 = time.perf_counter()
        result = self.core.identified(self.now)
        if result.estimate is not None:
            self.publish(keys.wncsca_model(), result.estimate)
        self._publish_model(result.decision)
        self._publish_judged_again(result.negotiations, t0)

    def _publish_model(self, d: AgentDecision) -> None:
        log = self.log.info if d.verdict == "accept" else self.log.warning
        for reason in d.reasons:
            log("%s", reason)
        self.publish(
            keys.wncsca_decision(), Decision(subject="model", verdict=d.verdict, reasons=d.reasons)
        )

    def _publish_judged_again(self, negotiations: list[Negotiation], t0: float) -> None:
        """The running configurations judged again on a new model, and the rates after."""
        for neg in negotiations:
            self._publish_decision(neg, [])
            self._publish_timing(neg, t0)
        accepted = [n for n in negotiations if n.decision.verdict == "accept"]
        self._publish_rates(accepted[-1] if accepted else None)

    def _watched(self, window: Window) -> None:
        """The model watch's window after a judged step is over: its verdict on the model, and
        an identification started or the configurations judged again when it no longer fits."""
        if self.core.watching is not window or to_ticks(window.end) != self.now:
            return  # abandoned (the loops' rates or set points changed under it), or extended
        t0 = time.perf_counter()
        result = self.core.watched(self.now)
        if result.decision is None:
            return
        self._publish_model(result.decision)
        if result.identification is not None:
            self._publish_mode(result.identification)
            self._run_experiment()
            self._publish_rates()
        elif result.negotiations:
            self._publish_judged_again(result.negotiations, t0)

    def _on_proposal(self, env: RawEnvelope, proposal: Proposal) -> None:
        t0 = time.perf_counter()
        neg = self.core.on_proposal(env.src, proposal)
        self._publish_decision(neg, sorted(proposal.paths))
        if neg.decision.verdict == "accept":
            self._publish_rates(neg)
        self._publish_timing(neg, t0)

    def _on_bad_proposal(self, env: RawEnvelope, raw: Any, err: SchemaError) -> None:
        t0 = time.perf_counter()
        neg = self.core.on_malformed_proposal(env.src, raw, err.problems)
        self._publish_decision(neg, [])
        self._publish_timing(neg, t0)

    def _publish_timing(self, neg: Negotiation, t0: float) -> None:
        self.publish(
            keys.wncsca_timing(),
            Timing(proposal=neg.decision.proposal, decision_s=time.perf_counter() - t0),
        )

    def _on_applied(self, env: RawEnvelope, msg: NetApplied) -> None:
        if msg.event == "rates_refused":  # a TSCH manager's "cannot": said, periods unchanged
            reason = f"{env.src}: rates refused: {msg.reason}"
            self.log.warning("%s", reason)
            self.publish(
                keys.wncsca_decision(),
                Decision(subject="rates", network=env.src, verdict="reject", reasons=(reason,)),
            )
        if msg.event == "no_alternative":
            d = self.core.on_no_alternative(env.src, msg.proposal)
            self.log.warning("%s", d.reasons[0])
            self.publish(
                keys.wncsca_decision(),
                Decision(
                    subject="proposal",
                    network=env.src,
                    proposal=msg.proposal,
                    verdict="keep",
                    reasons=d.reasons,
                ),
            )

    def _on_mode(self, env: RawEnvelope, request: ModeRequest) -> None:
        exp = self.core.experiment
        d = self.core.on_mode(request)
        self._publish_mode(d)
        if exp is not None and self.core.experiment is None:  # aborted: set points back
            for loop, value in sorted(exp.base.items()):
                self._pass_on(loop, value)
        if d.verdict == "accept":
            self._publish_rates()

    def _on_bad_mode(self, env: RawEnvelope, raw: Any, err: SchemaError) -> None:
        d = self.core.on_malformed_mode(err.problems)
        self.publish(
            keys.wncsca_decision(), Decision(subject="mode", verdict=d.verdict, reasons=d.reasons)
        )

    def _on_bad_setpoint(self, loop: str) -> InvalidHandler:
        def handle(env: RawEnvelope, raw: Any, err: SchemaError) -> None:
            d = self.core.on_malformed_setpoint(loop, err.problems)
            self.publish(
                keys.wncsca_decision(),
                Decision(subject="setpoint", verdict=d.verdict, reasons=d.reasons),
            )

        return handle

    def _on_setpoint(self, loop: str) -> Handler:
        def handle(env: RawEnvelope, request: Setpoint) -> None:
            mode = self.core.mode
            d, value, when = self.core.on_setpoint(loop, request, self.now)
            self.publish(
                keys.wncsca_decision(),
                Decision(subject="setpoint", verdict=d.verdict, reasons=d.reasons),
            )
            if value is None:
                return
            if self.core.mode != mode or self.core.relax_at is not None:
                self._publish_rates()
            if self.core.relax_at is not None:
                self.at(self.core.relax_at, self._relax)
            watching = self.core.watching
            if watching is not None:  # a new window, or the open one extended to a later end
                self.at(to_ticks(watching.end), lambda: self._watched(watching))
            self._requests[loop] = request  # a later request ends this one's pending moves
            for t, v in ((when, value), *self.core.ramp):
                if t == self.now:
                    self._pass_on(loop, v)
                else:
                    self.at(t, partial(self._pass_on_for, request, loop, v))

        return handle

    def _relax(self) -> None:
        d = self.core.relax()
        if d is None:
            return
        self.publish(
            keys.wncsca_decision(),
            Decision(subject="setpoint", verdict=d.verdict, reasons=d.reasons),
        )
        self._publish_rates()

    def _pass_on_for(self, request: Setpoint, loop: str, value: float) -> None:
        """A move of ``request`` at its time, unless a later request for ``loop`` replaced it."""
        if self._requests.get(loop) is request:
            self._pass_on(loop, value)

    def _pass_on(self, loop: str, value: float) -> None:
        self.core.pass_on(loop, value, self.now)
        self.publish(keys.loop_setpoint(loop), Setpoint(value=value))

    def _on_meas(self, loop: str) -> Handler:
        def handle(env: RawEnvelope, sample: Sample) -> None:
            self.core.observe(loop, sample.value, sample.t_sampled, self.now)
            d = self.core.on_sample(loop, sample.value, self.now)
            if d is None:
                return
            self.log.warning("%s", d.reasons[0])
            self.publish(
                keys.wncsca_decision(),
                Decision(subject="mode", verdict=d.verdict, reasons=d.reasons),
            )
            self._publish_rates()

        return handle

    def _publish_decision(self, neg: Negotiation, path_names: list[str]) -> None:
        """The verdict on a proposal, with the offending loops' paths (for the alternative)."""
        d = neg.decision
        paths = tuple(p for p in path_names if str(p).rpartition(".")[0] in d.offending)
        self.log.info(
            "proposal #%s from %s: %s (%s)",
            d.proposal,
            neg.network,
            d.verdict,
            "; ".join(d.reasons),
        )
        self.publish(
            keys.wncsca_decision(),
            Decision(
                subject="proposal",
                network=neg.network,
                proposal=d.proposal,
                verdict=d.verdict,
                reasons=d.reasons,
                delays=d.delays,
                bounds=d.bounds,
                offending=d.offending,
                paths=paths,
                links=tuple(v.as_dict() for v in neg.links),
            ),
        )

    def _publish_rates(self, neg: Negotiation | None = None) -> None:
        r = self.core.rates()
        assignment = neg.assignment.as_dict() if neg is not None and neg.assignment else None
        if assignment is not None:
            assignment.pop("decision_time_s", None)  # wall clock: on wncsca/timing instead
        self.publish(
            keys.wncsca_rates(),
            Rates(
                mode=r["mode"],
                periods={n: to_ticks(p) for n, p in r["periods"].items()},
                closed=r["closed"],
                control_periods={n: to_ticks(p) for n, p in self.core.control_periods.items()},
                proposal=self.core.proposal,
                method=self.core.method,
                overshoot_pct={n: _finite(v) for n, v in self.core.predicted.items()},
                assignment=assignment,
                energy=neg.energy if neg is not None else None,
                link_periods={n: to_ticks(h) for n, h in sorted(self.core.link_periods.items())},
            ),
        )


def _finite(v: float) -> float | None:
    return v if v == v and abs(v) != float("inf") else None
