"""The coordination agent's state machine, free of bus code (seed 000, section II and III.E;
DESIGN section 6): judge proposals, negotiate control periods, follow operating modes.

:class:`Coordinator` is what ``agents/wncsca/node.py`` calls for each message; every method
returns what is to be published. Modes:

* ``startup``, ``setpoint_change``: every loop closed at its negotiated control period (the
  benchmark period until a configuration has been accepted);
* ``identification``: closed, at the mode's configured periods (others at their control period);
* ``steady_state``: loops open (controller output held), sensors at the monitoring periods;
* ``fault_detection``: open, at the fault-detection periods (between monitoring and control);
* ``regulation``: closed at the control periods (a confirmed alarm).

While the loops are open, a loop with an ``alarm`` band is watched: a delivered sample farther
than the band from its set point turns steady state into fault detection (faster reports), and
``confirm`` such samples in fault detection close the loops (regulation) until operations ask
for another mode.

A set-point request first restores the control periods and closes the loops (mode
``setpoint_change``), then the change is passed on, at its announced time. Under the chance
method the step is judged first (:func:`agents.wncsca.steps.judge_step`): applied at the
control periods, applied with tightened periods for its transient (relaxed after the test's
length: :meth:`Coordinator.relax`), or refused with the predicted overshoot.

Requests arrive typed (:class:`~bus_schemas.Proposal`, :class:`~bus_schemas.ModeRequest`,
:class:`~bus_schemas.Setpoint`, validated by the behaviour's subscriptions); a body that is none
of them reaches ``on_malformed_*`` with the schema's problems and is refused naming each field.
Units: the agent reasons in time units (periods, delays, set-point times as floats); whole
ticks appear only at its edges: the ``Rates`` body it publishes, the TSCH manager's cells
(:mod:`agents.wncsca.capacity`) and the trial simulators, which run on the engines' tick grid.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

from agents.wncsca.assignment import Assignment
from agents.wncsca.bounds import DelayBound, delay_bounds
from agents.wncsca.capacity import Manager, describe, path_ticks
from agents.wncsca.chance import LoopLaw
from agents.wncsca.config import MODES, LinksConfig, ParameterUncertainty
from agents.wncsca.decision import (
    Decision,
    ProposalError,
    control_path_delays,
    decide,
    path_delay,
)
from agents.wncsca.experiment import Experiment
from agents.wncsca.fast import fast_periods
from agents.wncsca.guarantee import judge_by_risk, path_laws
from agents.wncsca.identification import Identified, identify
from agents.wncsca.links import LinkGroup, LinkVerdict, judge_links
from agents.wncsca.model import LoopModel
from agents.wncsca.paper import successive_approximation
from agents.wncsca.spec import AgentSpec, ClosedLoopSpec
from agents.wncsca.steps import judge_step, safe_alternative, staircase, test_length
from agents.wncsca.watch import Score, Watch, score
from agents.wncsca.window import Window
from bus_schemas import ModelEstimate, ModeRequest, Proposal, Setpoint, TschCapacity
from bus_schemas.bodies import PathConfig
from core.time import to_ticks, to_units
from gateway.carrier import TschCarrier
from gateway.energy import projected_lifetime
from gateway.paths import Route
from gateway.topology import Topology

__all__ = ["Coordinator", "Negotiation", "Identification", "Watched", "assign"]

_OPEN_MODES = ("steady_state", "fault_detection")


def assign(
    model: LoopModel,
    delays: Mapping[str, float],
    weights: Mapping[str, float] | None = None,
) -> Assignment:
    """Control periods under ``delays`` by the configured method (the fast method falls back to
    the paper's for laws it cannot linearise, and says so)."""
    cfg = model.config
    if cfg.method == "fast":
        try:
            return fast_periods(model, delays, objective=cfg.objective, weights=weights)
        except ValueError as err:
            result = successive_approximation(model, delays)
            result.reason = f"fast method not applicable ({err}); paper method used"
            return result
    return successive_approximation(model, delays)


@dataclass
class Negotiation:
    """What the agent decided about one proposal: the verdict and, if accepted, the periods."""

    decision: Decision
    network: str
    assignment: Assignment | None = None
    energy: dict[str, Any] | None = None
    links: list[LinkVerdict] = field(default_factory=list)


@dataclass(frozen=True)
class _Read:
    """A proposal as read (:meth:`Coordinator._read_proposal`)."""

    pid: int
    paths: dict[str, PathConfig]
    """The loops' paths."""
    link_paths: dict[str, PathConfig]
    """The links' paths (``<link>.link``)."""
    all_paths: Mapping[str, PathConfig]
    """Every path (a TSCH manager schedules them all)."""
    capacity: TschCapacity | None
    """The TSCH manager's capacity (``None``: not a TSCH gateway)."""
    others: dict[str, float]
    """The delays of the loops other networks carry (0 where none is accepted yet)."""


@dataclass
class Identification:
    """What an identification experiment ended in (:meth:`Coordinator.identified`): the
    estimate as published, the decision on the agent's model, and the re-judgement of every
    configuration the networks run, on the identified model."""

    estimate: ModelEstimate | None
    decision: Decision
    negotiations: list[Negotiation]


@dataclass
class Watched:
    """What the model watch found at a window's end (:meth:`Coordinator.watched`): its score
    (``None``: nothing to compare), the decision on the model, and, when it no longer fits, the
    identification started or the re-judgement of every running configuration on the widened
    uncertainty."""

    score: Score | None
    decision: Decision | None
    identification: Decision | None = None
    negotiations: list[Negotiation] = field(default_factory=list)


class _Ended(Exception):
    """A step of a negotiation ends it (a refusal, a rejection) with ``negotiation``."""

    def __init__(self, negotiation: Negotiation) -> None:
        super().__init__(negotiation.decision.verdict)
        self.negotiation = negotiation


class Coordinator:
    """The WNCSCA of one run.

    Parameters
    ----------
    spec : AgentSpec
        What the agent knows of its run (its configuration, judged loops, networks and links:
        :func:`scenario.views.agent_spec`).
    model : LoopModel
        The agent's model of its loops, handed its simulator
        (:func:`scenario.views.coordinator` builds both).
    """

    def __init__(self, spec: AgentSpec, model: LoopModel) -> None:
        self.spec = spec
        self.config = spec.config
        self.model = model
        self.loops = self.model.loops
        self.benchmark = dict(self.model.benchmark)
        self.control_periods = dict(self.benchmark)
        self.predicted: dict[str, float] = {}
        self.method: str | None = None
        self.mode = "startup"
        self.accepted: dict[str, int] = {}  # network -> last accepted proposal id
        self._rejected: dict[str, Decision] = {}  # network -> its last rejection
        self.at_risk: dict[str, tuple[int | None, tuple[str, ...]]] = {}
        """Network -> the rejected proposal it runs for want of an alternative, and the loops
        that rejection named (:meth:`on_no_alternative`)."""
        self.proposal: int | None = None  # the last accepted proposal (any network)
        self.carried = {
            n: [lp for lp in self.loops if spec.loop_networks[lp] == n] for n in spec.carriers
        }
        # wired loops: constant delays from the scenario; WSN loops: from accepted proposals
        self.delays: dict[str, float] = {
            lp: spec.loop_delays[lp]
            for lp in self.loops
            if not spec.is_wireless(spec.loop_networks[lp])
        }
        # linked controllers (seed 001): update periods by analysis (agents/wncsca/links.py)
        self.link_groups: list[LinkGroup] = list(spec.link_groups)
        self.link_delays: dict[str, float] = {
            n: lk.delay for n, lk in spec.links.items() if not spec.is_wireless(lk.network)
        }
        self.link_periods: dict[str, float] = {n: lk.period for n, lk in spec.links.items()}
        self._bounds: dict[str, DelayBound] | None = None
        self.setpoints = dict(spec.setpoints)
        # the chance method: each loop's delay law of the accepted configuration, and a
        # tightened step's transient (the periods to relax back to, and when)
        self.laws: dict[str, LoopLaw] = {}
        self._relaxed: dict[str, float] | None = None
        self.relax_at: int | None = None
        self._strikes = {n: 0 for n in self.loops}
        # TSCH gateways: their managers, as the last accepted proposal describes them
        self.managers: dict[str, Manager] = {}
        self._proposals: dict[str, Proposal] = {}  # network -> its last accepted proposal
        self._judged: dict[str, Proposal] = {}  # network -> its last proposal judged
        self.ramp: tuple[tuple[int, float], ...] = ()
        """The later moves (ticks, value) of the ramp the last set-point request was applied
        as (:meth:`on_setpoint`; the behaviour passes them on at their times)."""
        self.experiment: Experiment | None = None
        """The identification experiment under way (:meth:`start_identification`)."""
        self.experiments = 0
        """Experiments started so far (each draws its noise from a stream of its own)."""
        self.sigma: dict[str, float] = {}
        """Loop -> the last identification's residual RMS (the model watch's noise level)."""
        self.history: list[tuple[float, str, float]] = []
        """Every set-point change passed on to the loops (time units, loop, value), in order."""
        self.watch = Watch(self.config.watch) if self.config.watch is not None else None
        self._recent: dict[str, dict[int, tuple[float, int]]] = {n: {} for n in self.loops}
        """The model watch's memory: loop -> sampling instant -> (value, delay), ticks, of the
        samples delivered over the last :data:`_KEPT` test lengths (a window's replay starts
        where the plant last sat settled, and its delays are those the samples travelled)."""
        self._kept_since = 0
        """Ticks: :attr:`_recent` holds every delivered sample taken since then."""
        self.watching: Window | None = None
        """The window after a judged step that the model watch will judge at its end."""

    @property
    def bounds(self) -> dict[str, DelayBound]:
        """Each loop's largest tolerable delay at the benchmark periods (computed once)."""
        if self._bounds is None:
            self._bounds = delay_bounds(self.model) if self.loops else {}
        return self._bounds

    # -- links (seed 001) ------------------------------------------------------------------
    def govern_links(self) -> list[LinkVerdict]:
        """Judge the link groups whose links are all wired (their delays are known before the
        run; a gateway's come with its proposals); an accepted group's update period becomes
        the assigned one."""
        out = []
        for group in self.link_groups:
            if any(n not in self.link_delays for n in group.links):
                continue
            verdict = judge_links(group, self.link_delays, self._links_config())
            if verdict.verdict == "accept":
                self.link_periods.update(verdict.periods)
            out.append(verdict)
        return out

    def _links_config(self) -> LinksConfig:
        """The ``links:`` configuration of the agent (link groups exist only with one)."""
        if self.config.links is None:
            raise ValueError("links: the agent has link groups but no links configuration")
        return self.config.links

    # -- proposals -------------------------------------------------------------------------
    def on_proposal(self, network: str, proposal: Proposal) -> Negotiation:
        """Judge ``proposal`` from ``network``: read it, judge the control paths and the links,
        check the periods against a TSCH manager's capacity, and commit what was accepted (each
        step may end the negotiation: a refusal, a rejection)."""
        self._judged[network] = proposal
        try:
            read = self._read_proposal(network, proposal)
            decision, risk = self._judge_control(network, read)
            decision, links, link_delays = self._judge_proposed_links(network, read, decision)
            delays = {**self.delays, **{n: decision.delays[n] for n in self.carried[network]}}
            manager = self._manager(read)
            result = self._periods(network, read, decision, links, delays, risk, manager)
        except _Ended as ended:
            if ended.negotiation.decision.verdict == "reject":
                self._rejected[network] = ended.negotiation.decision
            return ended.negotiation
        self.at_risk.pop(network, None)  # a configuration judged safe runs again
        self._rejected.pop(network, None)
        self.link_delays.update(link_delays)
        for v in links:
            self.link_periods.update(v.periods)
        self.delays = delays
        self.accepted[network] = read.pid
        self._proposals[network] = proposal
        self.proposal = read.pid
        if manager is not None:
            self.managers[network] = manager
        if result is None:  # a network carrying links only: no periods to negotiate
            return Negotiation(decision, network, links=links)
        if result.feasible:
            if dict(result.periods) != self.control_periods:
                self.watching = None  # the window's loops no longer sample as it assumes
            self.control_periods = dict(result.periods)
            self._relaxed = None  # a new negotiation ends any tightened transient
        self.predicted = dict(result.overshoot_pct)
        self.method = result.method
        energy = self.energy(network, read.paths)
        return Negotiation(decision, network, result, energy, links)

    def on_malformed_proposal(self, network: str, raw: Any, problems: Sequence[str]) -> Negotiation:
        """A ``net/proposal`` body that is no :class:`~bus_schemas.Proposal`: refused naming every
        field that is wrong (``problems``, :attr:`bus_schemas.errors.SchemaError.problems`), with
        its id where the body has a valid one."""
        raw_id = raw.get("id") if isinstance(raw, Mapping) else None
        valid = isinstance(raw_id, int) and not isinstance(raw_id, bool) and raw_id >= 0
        pid = raw_id if valid else None
        if not self._is_gateway(network):
            return self._refused(network, pid, f"{network!r} is no gateway")
        return self._refused(network, pid, "; ".join(problems))

    def _is_gateway(self, network: str) -> bool:
        return network in self.carried and self.spec.is_wireless(network)

    def _read_proposal(self, network: str, proposal: Proposal) -> _Read:
        """The proposal's loops' and links' paths, and the delays of the loops other networks
        carry; refused (:class:`_Ended`) if ``network`` is no gateway."""
        if not self._is_gateway(network):
            raise _Ended(self._refused(network, proposal.id, f"{network!r} is no gateway"))
        others = {n: d for n, d in self.delays.items() if n not in self.carried[network]}
        missing = [n for n in self.loops if n not in self.carried[network] and n not in others]
        for n in missing:  # a loop of another gateway with no accepted configuration yet
            others[n] = 0.0
        link_paths = {  # links' paths ("<link>.link") are judged apart
            p: e for p, e in proposal.paths.items() if p.rpartition(".")[0] in self.spec.links
        }
        paths = {p: e for p, e in proposal.paths.items() if p not in link_paths}
        return _Read(proposal.id, paths, link_paths, proposal.paths, proposal.tsch, others)

    def _judge_control(self, network: str, read: _Read) -> tuple[Decision, Assignment | None]:
        """III.E step 2 on the control paths: by the bounds (the paper's and the fast method),
        or by the risk (the chance method, which finds the periods too); refused
        (:class:`_Ended`) if a path is malformed."""
        if self.config.method == "chance" and self.carried[network]:
            try:
                decision, risk = self._judge_by_risk(network, read.pid, read.paths, read.others)
            except ProposalError as err:
                raise _Ended(self._refused(network, read.pid, str(err))) from err
        else:
            decision = decide(
                read.pid,
                read.paths,
                self.bounds,
                self.config.estimate,
                wired=read.others,
                quantile=self.config.confidence,
            )
            risk = None
        if decision.verdict == "refuse":
            raise _Ended(Negotiation(decision, network))
        return decision, risk

    def _judge_proposed_links(
        self, network: str, read: _Read, decision: Decision
    ) -> tuple[Decision, list[LinkVerdict], dict[str, float]]:
        """The link groups under the proposal's link delays, joined to the decision on the
        loops; a rejection of either ends the negotiation (:class:`_Ended`)."""
        try:
            link_delays = self._link_delays(network, read.link_paths)
        except ProposalError as err:
            raise _Ended(self._refused(network, read.pid, str(err))) from err
        links = self._judge_links(network, link_delays)
        rejected = [v for v in links if v.verdict == "reject"]
        decision = _with_links(decision, links)
        if decision.verdict == "reject" or rejected:
            raise _Ended(Negotiation(decision, network, links=links))
        return decision, links, link_delays

    def _manager(self, read: _Read) -> Manager | None:
        """The TSCH manager the proposal describes (``None``: not a TSCH gateway)."""
        return None if read.capacity is None else Manager(read.capacity, read.all_paths)

    def _periods(
        self,
        network: str,
        read: _Read,
        decision: Decision,
        links: list[LinkVerdict],
        delays: Mapping[str, float],
        risk: Assignment | None,
        manager: Manager | None,
    ) -> Assignment | None:
        """III.E step 3: the control periods under the accepted delays (the chance method's
        from its judgement), which a TSCH manager must be able to schedule, else the proposal
        is rejected (:class:`_Ended`); ``None`` for a network carrying links only."""
        if not self.carried[network]:
            return None
        weights = _weights(read.paths, self.loops)
        result = risk if risk is not None else assign(self.model, delays, weights)
        if manager is not None and result.feasible:
            link_periods = {**self.link_periods}
            for v in links:
                link_periods.update(v.periods)
            schedule = manager.schedule(result.periods, link_periods)
            if not schedule.feasible:  # the manager cannot: like a violated limit
                rejected = replace(
                    decision,
                    verdict="reject",
                    reasons=(*decision.reasons, describe(result.periods, schedule)),
                    offending=manager.offending(schedule),
                )
                raise _Ended(Negotiation(rejected, network, links=links))
        return result

    def _judge_by_risk(
        self,
        network: str,
        pid: int,
        paths: Mapping[str, PathConfig],
        others: Mapping[str, float],
    ) -> tuple[Decision, Assignment | None]:
        """III.E steps 2-3 on the risk (the chance method): the proposal is accepted when
        periods exist that keep every loop's ``P(overshoot <= limit) >= confidence`` under its
        delay distribution (found by the paper's search on the risk, checked on the non-linear
        model: :func:`agents.wncsca.guarantee.chance_periods`) and every loop's delay variation
        at those periods is within its jitter margin (:mod:`agents.wncsca.jitter`), else
        rejected naming the loops.

        Raises
        ------
        ProposalError
            A malformed proposal (the caller refuses it).
        """
        carried = tuple(self.carried[network])
        delays, used = control_path_delays(paths, carried, self.config.estimate)
        laws = path_laws(paths, carried)
        down = [n for n, d in delays.items() if d is None]
        known = {**others, **{n: float(d) for n, d in delays.items() if d is not None}}
        if down:
            reasons = tuple(f"{n}: control path down (no route)" for n in down)
            return Decision(pid, "reject", reasons, known, {}, used, tuple(down)), None
        decision, result = judge_by_risk(
            self.model, laws, known, pid, used, seed=self.spec.seed, carried=carried
        )
        if decision.verdict == "accept":
            self.laws.update(laws)
        return decision, result

    def _link_delays(self, network: str, link_paths: Mapping[str, PathConfig]) -> dict[str, float]:
        """Delay of every link of ``network`` from its path in a proposal (``inf``: no route)."""
        out: dict[str, float] = {}
        for name, lk in sorted(self.spec.links.items()):
            if lk.network != network or not self.config.links:
                continue
            entry = link_paths.get(f"{name}.link")
            if entry is None:
                raise ProposalError(f"paths.{name}.link: missing (link {name} is on {network})")
            delay, _ = path_delay(
                f"{name}.link", entry, self.config.estimate, self.config.confidence
            )
            out[name] = math.inf if delay is None else delay
        return out

    def _judge_links(self, network: str, delays: Mapping[str, float]) -> list[LinkVerdict]:
        """Judge the groups with a link over ``network`` under the proposal's link ``delays``."""
        out = []
        for group in self.link_groups:
            if not any(self.spec.links[n].network == network for n in group.links):
                continue
            trial = {**self.link_delays, **delays}
            out.append(judge_links(group, trial, self._links_config()))
        return out

    def on_no_alternative(self, network: str, proposal: int | None) -> Decision:
        """The gateway has no alternative to a rejected proposal, so the network runs it: the
        periods in force are kept (those of the last accepted configuration, whose routes may
        no longer exist, or the benchmark's), and the loops the rejection named are at risk
        until a configuration of ``network`` is accepted: their set-point steps are refused
        (:meth:`on_setpoint`), and the decision says so."""
        last = self.accepted.get(network)
        rejected = self._rejected.get(network)
        named = rejected.offending if rejected is not None and rejected.proposal == proposal else ()
        loops = tuple(named) or tuple(self.carried.get(network, ()))
        self.at_risk[network] = (proposal, loops)
        kept = (
            f"the periods of the last accepted configuration (#{last}) stay in force, though "
            "the network no longer runs it"
            if last is not None
            else "the benchmark periods stay in force (no configuration accepted yet)"
        )
        reasons = [
            f"{network}: no alternative to rejected proposal #{proposal}: the network runs it; "
            f"{kept}",
            f"loops at risk: {', '.join(loops)} (judged unsafe on the configuration that runs); "
            "their set-point steps are refused until a configuration is accepted",
        ]
        if rejected is not None and rejected.proposal == proposal:
            reasons += [f"rejected because: {r}" for r in rejected.reasons[:2]]
        return Decision(proposal, "keep", tuple(reasons))

    def _refused(self, network: str, pid: int | None, reason: str) -> Negotiation:
        return Negotiation(Decision(pid, "refuse", (f"proposal refused: {reason}",)), network)

    # -- modes and set points --------------------------------------------------------------
    def on_malformed_mode(self, problems: Sequence[str]) -> Decision:
        """An ``ops/mode`` body that is no :class:`~bus_schemas.ModeRequest`: refused, naming
        every field that is wrong."""
        return Decision(None, "refuse", (f"mode refused: {'; '.join(problems)}",))

    def on_malformed_setpoint(self, loop: str, problems: Sequence[str]) -> Decision:
        """An ``ops/setpoint/<loop>`` body that is no :class:`~bus_schemas.Setpoint`: refused,
        naming every field that is wrong as ``<loop>.<field>``."""
        named = [f"{loop}:{p[5:]}" if p.startswith("body:") else f"{loop}.{p}" for p in problems]
        return Decision(None, "refuse", (f"set point refused: {'; '.join(named)}",))

    def on_mode(self, request: ModeRequest) -> Decision:
        """Change the operating mode; refused if unknown."""
        mode = request.mode
        if mode not in MODES:
            return Decision(
                None, "refuse", (f"mode refused: unknown mode {mode!r} (modes: {MODES})",)
            )
        previous, self.mode = self.mode, mode
        lacking = self.uncarried()
        if lacking:
            self.mode = previous
            return Decision(None, "refuse", (f"mode {mode} refused: {lacking}",))
        aborted = self.abort_identification()
        self.watching = None  # the loops' rates change: the window is not the step's any more
        return Decision(
            None, "accept", (f"mode {previous} -> {mode}", *(aborted.reasons if aborted else ()))
        )

    def uncarried(self) -> str | None:
        """Why a TSCH gateway's manager cannot carry the current mode's rates (``None``: every
        one can)."""
        periods = self.rates()["periods"]
        for network, manager in sorted(self.managers.items()):
            mine = {n: p for n, p in periods.items() if n in self.carried[network]}
            schedule = manager.schedule(mine, self.link_periods)
            if not schedule.feasible:
                return f"{network}: {describe(mine, schedule)}"
        return None

    def on_setpoint(
        self, loop: str, request: Setpoint, now: int
    ) -> tuple[Decision, float | None, int]:
        """A set-point request for ``loop`` at ``now`` (ticks): returns the verdict, the value to
        pass on (``None`` if refused) and when (ticks). Accepting it puts the loops back under
        control (mode ``setpoint_change``) before the change applies. A refused step whose
        request asks for its safe alternative (``safe_ramp``) is ramped instead: the first move
        is returned, the others are :attr:`ramp`."""
        value, t_apply = request.value, request.t_apply
        when = now if t_apply is None else max(t_apply, now)
        self.ramp = ()
        if self.experiment is not None and to_ticks(self.experiment.end) > now:
            return (
                Decision(
                    None,
                    "refuse",
                    (
                        f"step {loop} -> {value:g} refused: the identification experiment moves "
                        f"the set points until t={self.experiment.end:g} (ask again after it, or "
                        "end it by requesting a mode)",
                    ),
                ),
                None,
                now,
            )
        for network, (pid, loops) in sorted(self.at_risk.items()):
            if loop in loops:
                return (
                    Decision(
                        None,
                        "refuse",
                        (
                            f"step {loop} {self.setpoints.get(loop, math.nan):g} -> {value:g} "
                            f"refused: {loop} is at risk, {network} runs proposal #{pid}, which "
                            "the agent rejected; no step is applied over it until a "
                            "configuration is accepted",
                        ),
                    ),
                    None,
                    now,
                )
        judged: tuple[str, ...] = ()
        unchanged = loop in self.setpoints and float(value) == float(self.setpoints[loop])
        if unchanged:  # nothing moves: nothing to judge (an overshoot of no change is undefined)
            judged = (f"{loop} is at {value:g} already: no step to judge",)
        elif self.config.method == "chance" and loop in self.loops:
            judge = partial(
                judge_step,
                self.model,
                self.laws,
                self.delays,
                self.control_periods,
                self.setpoints,
                loop,
                float(value),
                self.spec.seed,
            )
            step = judge(0.0)
            judged = (step.reason(self.config.overshoot_limit),)
            if step.verdict == "refuse":
                alternative = safe_alternative(judge, test_length(self.model))
                offer = (
                    alternative.reason()
                    if alternative is not None
                    else "no set-point ramp up to twice the test's length is safe either"
                )
                if alternative is None or not request.safe_ramp:
                    return Decision(None, "refuse", (*judged, offer)), None, now
                step = alternative.verdict
                stairs = staircase(
                    to_units(when),
                    float(self.setpoints[loop]),
                    float(value),
                    step.periods[loop],
                    alternative.duration,
                )
                moves = tuple((to_ticks(t), v) for t, v in stairs)
                (when, value), self.ramp = moves[0], moves[1:]
                judged = (
                    *judged,
                    offer,
                    "the alternative applied, as the request asked (safe_ramp)",
                )
            if step.verdict == "tighten":
                if self._relaxed is None:
                    self._relaxed = dict(self.control_periods)
                self.control_periods = dict(step.periods)
                last = self.ramp[-1][0] if self.ramp else when
                self.relax_at = last + to_ticks(test_length(self.model))
            if self.watch is not None:  # the model watch judges what the step delivers
                for t, v in ((when, value), *self.ramp):
                    self._watch_step(loop, float(v), t)
        elif loop in self.loops:
            self.watching = None  # an unjudged change: the window is not the step's any more
        previous, self.mode = self.mode, "setpoint_change"
        note = f"{loop} -> {value:g} at t={to_units(when):g}"
        if self.ramp:
            end_t, final = self.ramp[-1]
            note = (
                f"{loop} -> {final:g} as a ramp of {len(self.ramp) + 1} moves from "
                f"t={to_units(when):g} to t={to_units(end_t):g}"
            )
        if previous != "setpoint_change":
            note += f"; control periods restored and loops closed first (was {previous})"
        return Decision(None, "accept", (note, *judged)), float(value), when

    def relax(self) -> Decision | None:
        """The transient of a tightened step is over: the negotiated periods come back
        (``None`` when nothing was tightened, or a new negotiation has replaced them)."""
        self.relax_at = None
        if self._relaxed is None:
            return None
        self.control_periods, self._relaxed = self._relaxed, None
        per = ", ".join(f"{n} {p:g}" for n, p in sorted(self.control_periods.items()))
        return Decision(None, "accept", (f"step transient over: control periods relaxed to {per}",))

    def on_sample(self, loop: str, y: float, t: int) -> Decision | None:
        """A delivered sample of ``loop`` at ``t`` (ticks) while the loops may be open: raise
        and confirm alarms (``None``: nothing to do)."""
        band = self.config.alarm.get(loop)
        if band is None or self.mode not in _OPEN_MODES:
            self._strikes[loop] = 0
            return None
        deviation = abs(y - self.setpoints[loop])
        if deviation <= band:
            self._strikes[loop] = 0
            return None
        self._strikes[loop] += 1
        what = f"{loop}: |y - r| = {deviation:.4g} > alarm {band:g} at t={to_units(t):g}"
        if self.mode == "steady_state":
            self.mode = "fault_detection"
            return Decision(None, "accept", (f"{what}: steady_state -> fault_detection",))
        if self._strikes[loop] >= self.config.confirm:
            self.mode = "regulation"
            self._strikes = {n: 0 for n in self.loops}
            return Decision(
                None,
                "accept",
                (f"{what}, confirmed: fault_detection -> regulation (loops closed)",),
            )
        return None

    def rates(self) -> dict[str, Any]:
        """Periods (time units) and closed flags for the current mode."""
        modes = self.config.modes
        periods = dict(self.control_periods)
        closed = {n: True for n in self.loops}
        if self.mode == "identification":
            periods.update(modes.identification)
        elif self.mode in _OPEN_MODES:
            periods.update(
                modes.monitoring if self.mode == "steady_state" else modes.fault_detection
            )
            closed = {n: False for n in self.loops}
        return {"mode": self.mode, "periods": periods, "closed": closed}

    # -- identification (issue 35, item 3) --------------------------------------------------
    def start_identification(self, now: int = 0) -> Decision | None:
        """Start the configured identification experiment (``identify:``; ``None`` without
        one) at ``now`` (ticks): mode ``identification`` (its periods), the set-point
        perturbation planned (:attr:`experiment`; the behaviour passes its changes on at their
        times)."""
        cfg = self.config.identify
        if cfg is None:
            return None
        previous, self.mode = self.mode, "identification"
        self.watching = None
        periods = {n: p for n, p in self.rates()["periods"].items() if n in self.loops}
        self.experiment = Experiment.plan(
            cfg,
            {n: self.setpoints[n] for n in self.loops},
            periods,
            self.spec.seed,
            previous,
            t0=to_units(now),
            index=self.experiments,
        )
        self.experiments += 1
        moves = sum(1 for c in self.experiment.changes if c[0] < self.experiment.end)
        base = self.experiment.base
        swings = ", ".join(f"{n} {base[n]:g} +- {a:g}" for n, a in sorted(cfg.amplitude.items()))
        fitted = ", ".join(f"{p}.{n}" for p, names in sorted(cfg.params.items()) for n in names)
        return Decision(
            None,
            "accept",
            (
                f"mode {previous} -> identification: experiment to t={self.experiment.end:g} "
                f"({moves} set-point moves of generalized binary noise: {swings}), then the "
                f"model's {fitted} fitted to the delivered samples and the configuration "
                "judged again",
            ),
        )

    def observe(self, loop: str, y: float, t_sampled: int, now: int) -> None:
        """A delivered sample of ``loop`` (taken at ``t_sampled``, delivered at ``now``, ticks):
        data for the experiment under way."""
        if self.experiment is not None:
            self.experiment.record(loop, y, t_sampled, now)
        if self.watch is not None:
            self._remember(loop, y, t_sampled, now)
        if self.watching is not None:
            self.watching.record(loop, y, t_sampled, now)

    def _remember(self, loop: str, y: float, t_sampled: int, now: int) -> None:
        """Keep a delivered sample for the windows to come; forget those older than
        :data:`_KEPT` test lengths (checked once a test length)."""
        if loop not in self._recent:
            return
        self._recent[loop][t_sampled] = (float(y), now - t_sampled)
        horizon = _KEPT * to_ticks(test_length(self.model))
        if now - horizon > self._kept_since + horizon // _KEPT:
            self._kept_since = now - horizon
            for kept in self._recent.values():
                for t in [t for t in kept if t < self._kept_since]:
                    del kept[t]

    def identified(self, now: int) -> Identification:
        """The experiment is over (at ``now``, ticks): fit the model's parameters to what was
        delivered (:func:`agents.wncsca.identification.identify`), take the estimate as the
        agent's model, under the chance method with the estimate's standard deviations as its
        uncertainty, restore the interrupted mode, and judge again each configuration the
        networks run (a rejection puts its loops at risk: :meth:`on_no_alternative`'s state)."""
        exp, self.experiment = self.experiment, None
        assert exp is not None, "identified() without an experiment under way"
        self.mode = exp.previous_mode
        cfg = exp.config
        settle = 0.0 if exp.t0 == 0.0 else test_length(self.model)
        if exp.t0 > 0.0 and not self.model.trials.design:  # the controllers do not drift
            spec = self.model.trials.spec
            design = {
                p: {n: float(spec.plants[p].params[n]) for n in names}
                for p, names in cfg.params.items()
            }
            self.model = LoopModel(self.model.trials.pinned(design), self.config)
        try:
            fit = identify(self.model, cfg.params, exp.seen(self.delays, settle))
        except ValueError as err:
            reason = f"identification failed ({err}): the model stays as believed"
            return Identification(None, Decision(None, "reject", (reason,)), [])
        estimate = _estimate(exp, fit, self.model.trials.spec, now)
        uncertainty: dict[str, dict[str, ParameterUncertainty]] = {}
        if self.config.method == "chance":
            uncertainty = {
                p: {n: ParameterUncertainty(rel_sd=_rel_sd(fit, p, n)) for n in names}
                for p, names in fit.params.items()
            }
        self.model = LoopModel(self.model.trials.believing(fit.params, uncertainty), self.config)
        self._bounds = None
        self.sigma = dict(fit.sigma)
        decision = Decision(None, "accept", tuple(_estimate_reasons(estimate)))
        return Identification(estimate, decision, self._judge_running())

    def _judge_running(self) -> list[Negotiation]:
        """Judge again, on the model as it now is, the configuration each network runs: the
        one the agent accepted, or the rejected one it runs for want of an alternative (a
        rejection puts its loops at risk, an acceptance ends their risk)."""
        negotiations = []
        for network in sorted(set(self._proposals) | set(self.at_risk)):
            running = self._proposals.get(network)
            if network in self.at_risk:
                pid = self.at_risk[network][0]
                judged = self._judged.get(network)
                running = judged if judged is not None and judged.id == pid else None
            if running is None:
                continue
            neg = self.on_proposal(network, running)
            if neg.decision.verdict == "reject":
                self.at_risk[network] = (running.id, tuple(neg.decision.offending))
            negotiations.append(neg)
        return negotiations

    # -- the model watch (issue 35, item 4) ------------------------------------------------
    def noise_levels(self) -> dict[str, float]:
        """Each loop's noise level for the model watch: the last identification's residual
        RMS, else the believed sensor noise."""
        spec = self.model.trials.spec
        out = {}
        for n in self.loops:
            judged = spec.loops[n]
            believed = float(spec.plants[judged.plant].noise.get(judged.sensor, 0.0))
            out[n] = self.sigma.get(n, believed)
        return out

    def pass_on(self, loop: str, value: float, now: int) -> None:
        """``loop``'s set point is ``value`` from ``now`` (ticks): the agent passed it on."""
        self.setpoints[loop] = value
        self.history.append((to_units(now), loop, value))

    def _watch_step(self, loop: str, value: float, when: int) -> None:
        """A judged step at ``when`` (ticks) opens the model watch's window for the test's
        length, or extends the open one if the loops sample as it assumes (a step that changed
        the periods starts a window of its own). Its replay starts where the plant last sat
        settled (:meth:`_settled_at`)."""
        periods = {n: self.control_periods[n] for n in self.loops}
        end = to_units(when) + test_length(self.model)
        change = (to_units(when), loop, value)
        w = self.watching
        if w is not None and dict(w.periods) == periods:
            w.changes, w.end = (*w.changes, change), max(w.end, end)
            return
        start = self._settled_at(when)
        base = dict(self.spec.setpoints)
        earlier = []
        for t, lp, v in self.history:
            if to_ticks(t) < start:
                base[lp] = v
            elif to_ticks(t) < when:
                earlier.append((t, lp, v))
        self.watching = Window(
            t0=to_units(start),
            since=to_units(when),
            kept=to_units(max(start, self._kept_since)),
            end=end,
            base={n: float(base[n]) for n in self.loops},
            changes=(*earlier, change),
            periods=periods,
        )
        for loop, kept in self._recent.items():
            for t, (y, delay) in kept.items():
                self.watching.record(loop, y, t, t + delay)

    def _settled_at(self, when: int) -> int:
        """The latest instant up to ``when`` (ticks) at which the plant had sat for the test's
        length without a set-point change (the model's own start, 0, if none): where a replay
        of what followed may start from the model settled."""
        settle = to_ticks(test_length(self.model))
        times = sorted({to_ticks(t) for t, _, _ in self.history if to_ticks(t) < when})
        start = when
        while start >= settle:
            recent = [t for t in times if start - settle < t < start]
            if not recent:
                return start
            start = min(recent)
        return 0

    def watched(self, now: int) -> Watched:
        """The window after a judged step is over (at ``now``, ticks): score it on the model
        (:func:`agents.wncsca.watch.score`), add the score to the CUSUM, and when the model no
        longer fits, identify it again (``identify:``) or widen its stated uncertainty
        (``watch.widen``) and judge the running configurations again."""
        window, self.watching = self.watching, None
        assert window is not None and self.watch is not None, "watched() without a window"
        cfg = self.watch.config
        s = score(
            self.model,
            window,
            self.delays,
            self.noise_levels(),
            0.0 if window.t0 == 0.0 else test_length(self.model),
            cfg.replays,
            self.spec.seed,
            self.watch.windows,
        )
        if s is None:
            return Watched(None, None)
        cusum_before = self.watch.cusum
        flagged = self.watch.update(s)
        total = cusum_before + s.z - cfg.allowance
        test = f"CUSUM {max(total, 0.0):.3g} (h = {cfg.threshold:g}, k = {cfg.allowance:g})"
        if not flagged:
            return Watched(s, Decision(None, "accept", (f"{s.describe()}; {test}: model fits",)))
        what = f"{s.describe()}; {test}: the model no longer fits its plant"
        if self.config.identify is not None:
            started = self.start_identification(now)
            reasons = (what, "identification started: the model is fitted again")
            return Watched(s, Decision(None, "reject", reasons), started)
        widened = self._widened(cfg.widen)
        if not widened:
            reasons = (
                what,
                "no uncertainty stated to widen and no identify: configured; the guarantee "
                "rests on a model that does not fit (state model.<plant>.uncertainty, or "
                "configure identify:)",
            )
            return Watched(s, Decision(None, "reject", reasons))
        self.model = LoopModel(self.model.trials.believing({}, widened), self.config)
        self._bounds = None
        said = ", ".join(
            f"{p}.{n} {_spread(u)}"
            for p, v in sorted(widened.items())
            for n, u in sorted(v.items())
        )
        reasons = (what, f"uncertainty widened x{cfg.widen:g}: {said}; configurations judged again")
        return Watched(s, Decision(None, "reject", reasons), None, self._judge_running())

    def _widened(self, factor: float) -> dict[str, dict[str, ParameterUncertainty]]:
        """The model's stated uncertainty, ``factor`` times wider (a standard deviation within
        what an uncertainty can state, an interval's half-width about the believed value)."""
        out: dict[str, dict[str, ParameterUncertainty]] = {}
        for name, plant in sorted(self.model.trials.spec.plants.items()):
            for param, u in sorted(plant.uncertainty.items()):
                if u.rel_sd is not None:
                    wider = ParameterUncertainty(rel_sd=min(u.rel_sd * factor, _REL_SD_MAX))
                else:
                    assert u.interval is not None
                    value = float(plant.params[param])
                    low, high = u.interval
                    wider = ParameterUncertainty(
                        interval=(value - factor * (value - low), value + factor * (high - value))
                    )
                out.setdefault(name, {})[param] = wider
        return out

    def abort_identification(self) -> Decision | None:
        """Operations changed the mode while an experiment ran: it ends unfitted, its set
        points back at their values before it (``None``: no experiment under way)."""
        exp, self.experiment = self.experiment, None
        if exp is None:
            return None
        self.setpoints.update(exp.base)
        return Decision(
            None,
            "accept",
            (
                f"identification experiment aborted (mode {self.mode} requested): set points "
                "back at their values before it; the model stays as believed",
            ),
        )

    # -- energy ----------------------------------------------------------------------------
    def energy(self, network: str, paths: Mapping[str, PathConfig]) -> dict[str, Any] | None:
        """Projected network lifetime (the first battery node to run out) under the control
        periods against the benchmark periods, over the proposal's routes."""
        cfg = self.spec.carriers[network].gateway
        if getattr(cfg, "mac", "per_hop") == "tsch":
            return self._tsch_energy(network, paths)
        topology = Topology(cfg.topology)
        routes = {}
        try:
            for path, entry in paths.items():
                if len(entry.route) >= 2:
                    routes[path] = Route(
                        tuple(topology.hop(a, b) for a, b in itertools.pairwise(entry.route))
                    )
        except ValueError:
            return None  # a route over links the scenario does not know (e.g. an added relay)

        def lifetime(periods: Mapping[str, float]) -> float:
            per = {f"{n}.sensor": periods[n] for n in self.carried[network]}
            nodes = projected_lifetime(topology, routes, per, cfg.energy)
            return min(e.lifetime_s for e in nodes.values()) / 3600.0

        return self._lifetimes(lifetime)

    def _lifetimes(self, lifetime: Any) -> dict[str, Any]:
        """The network lifetime (h) under the control periods against the benchmark periods,
        by ``lifetime(periods)``; ``None`` where infinite."""
        assigned, bench = lifetime(self.control_periods), lifetime(self.benchmark)
        finite = math.isfinite(assigned) and math.isfinite(bench) and bench > 0
        return {
            "lifetime_h_assigned": assigned if math.isfinite(assigned) else None,
            "lifetime_h_benchmark": bench if math.isfinite(bench) else None,
            "ratio": assigned / bench if finite else None,
        }

    def _tsch_energy(self, network: str, paths: Mapping[str, PathConfig]) -> dict[str, Any] | None:
        """:meth:`energy` over a TSCH network: the first battery to run out under its manager's
        schedule for the proposal's routes (:meth:`gateway.tsch.network.TschNetwork.lifetimes_h`),
        the loops' sensor and actuator paths at their periods."""
        carrier = TschCarrier(self.spec.carriers[network])
        routes = {p: (tuple(e.route) or None) for p, e in paths.items()}

        def lifetime(periods: Mapping[str, float]) -> float:
            ticks = path_ticks(routes, periods, self.link_periods)
            hours = carrier.tsch.lifetimes_h(routes, ticks)
            return min((h for h in hours.values() if h is not None), default=math.inf)

        return self._lifetimes(lifetime)


def _with_links(decision: Decision, links: list[LinkVerdict]) -> Decision:
    """``decision`` on the loops combined with the verdicts on the link groups: rejected if any
    group is, the links of a rejected group offending (so the gateway offers an alternative)."""
    if not links:
        return decision
    rejected = [v for v in links if v.verdict == "reject"]
    offending = tuple(decision.offending) + tuple(n for v in rejected for n in v.links)
    delays = {**decision.delays, **{n: v.delay for v in links for n in v.links}}
    return replace(
        decision,
        verdict="reject" if rejected or decision.verdict == "reject" else decision.verdict,
        reasons=tuple(decision.reasons) + tuple(r for v in links for r in v.reasons),
        delays=delays,
        offending=offending,
    )


def _weights(paths: Mapping[str, PathConfig], loops: tuple[str, ...]) -> dict[str, float]:
    """Energy weight of one sample of each loop: the hops of its paths (at least 1)."""
    out = {n: 1.0 for n in loops}
    for path, entry in paths.items():
        loop = path.rpartition(".")[0]
        if loop in out and entry.hops > 0:
            out[loop] = float(entry.hops) if out[loop] == 1.0 else out[loop] + entry.hops
    return out


_KEPT = 4
"""Test lengths of delivered samples the model watch keeps for the windows to come."""

_REL_SD_MAX = 0.3
"""The largest relative standard deviation a stated uncertainty takes
(:class:`~agents.wncsca.config.ParameterUncertainty`): a poorer estimate is stated so."""


def _rel_sd(fit: Identified, plant: str, name: str) -> float:
    """The estimate's relative standard deviation, within what an uncertainty can state (a fit
    that pins a parameter exactly still leaves it a trace of doubt)."""
    rel = fit.rel_sd(plant, name)
    return min(max(rel, 1e-6), _REL_SD_MAX) if math.isfinite(rel) else _REL_SD_MAX


def _estimate(exp: Experiment, fit: Identified, spec: ClosedLoopSpec, now: int) -> ModelEstimate:
    """The estimate as published on ``wncsca/model``."""
    was = {
        p: {n: float(spec.plants[p].params[n]) for n in names} for p, names in fit.params.items()
    }
    return ModelEstimate(
        t_start=to_ticks(exp.t0),
        t_end=now,
        params={p: dict(v) for p, v in fit.params.items()},
        std={p: {n: fit.std(p, n) for n in names} for p, names in fit.params.items()},
        was=was,
        fit_pct=dict(fit.fit_pct),
        sigma=dict(fit.sigma),
        cost=exp.cost(),
        samples=exp.delivered(),
        trials=fit.trials,
    )


def _spread(u: ParameterUncertainty) -> str:
    if u.rel_sd is not None:
        return f"+-{100 * u.rel_sd:.3g} % (1 sd)"
    assert u.interval is not None
    return f"in [{u.interval[0]:.5g}, {u.interval[1]:.5g}]"


def _estimate_reasons(e: ModelEstimate) -> list[str]:
    """What the agent says of its identified model, one line per parameter, then the fit."""
    out = []
    for plant, params in sorted(e.params.items()):
        for name, value in sorted(params.items()):
            sd, was = e.std[plant][name], e.was[plant][name]
            out.append(
                f"model identified: {plant}.{name} = {value:.5g} +- {1.96 * sd:.3g} (95 %), "
                f"believed {was:.5g} ({100 * (value / was - 1):+.1f} %)"
            )
    fits = ", ".join(f"{n} {v:.1f} %" for n, v in sorted(e.fit_pct.items()))
    costs = ", ".join(f"{n} {v:.3g}" for n, v in sorted(e.cost.items()))
    out.append(
        f"fit {fits} over {e.samples} delivered samples; excitation cost (RMS |y - r0|) {costs}"
    )
    return out
