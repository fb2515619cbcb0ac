"""One pydantic model per message body.

Bodies are frozen and forbid extra fields; time is integer ticks, never float.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictStr, model_validator

__all__ = [
    "Sample",
    "Move",
    "Estimate",
    "Setpoint",
    "PlantState",
    "Loss",
    "NetApplied",
    "CellBody",
    "TschCapacity",
    "ScheduleSummary",
    "DelayDistribution",
    "PathConfig",
    "NodeStats",
    "NetStats",
    "PathStats",
    "Proposal",
    "Decision",
    "Rates",
    "SamplingPeriod",
    "Timing",
    "ModelEstimate",
    "ModeRequest",
    "InjectRequest",
    "NetworkEvent",
    "Tick",
    "TickLog",
    "Done",
    "Working",
    "Stop",
    "MonitorHarris",
    "MonitorCandidate",
    "MonitorAssessment",
]

_FROZEN = ConfigDict(frozen=True, extra="forbid")


Finite = Annotated[float, Field(allow_inf_nan=False)]
"""A float that is neither NaN nor infinite (checked by pydantic's core, not in Python)."""


class Sample(BaseModel):
    """A measurement, at the sensor (``plant/<p>/sensor/<s>``) or delivered (``loop/<l>/meas``)."""

    model_config = _FROZEN

    value: Finite = Field(description="measured value, in the signal's engineering unit")
    t_sampled: int = Field(ge=0, strict=True, description="time the sample was taken, ticks")


class Move(BaseModel):
    """A control move: computed (``loop/<l>/u``) or delivered (``plant/<p>/actuator/<i>``)."""

    model_config = _FROZEN

    value: Finite = Field(description="actuator command, in the input's engineering unit")
    t_computed: int = Field(ge=0, strict=True, description="time the move was computed, ticks")


class Estimate(BaseModel):
    """What a controller's law transmits on a link (``link/<k>/tx``) and the network delivers
    (``link/<k>/rx``): seed 001's state estimate of a unit, in the law's own units."""

    model_config = _FROZEN

    values: tuple[Finite, ...] = Field(min_length=1, description="the transmitted vector")
    t_sent: int = Field(ge=0, strict=True, description="time it was transmitted, ticks")


class Setpoint(BaseModel):
    """A new set point of one loop: requested by operations (``ops/setpoint/<loop>``) or, when a
    coordination agent governs the loops, passed on by it to the controllers (``loop/<l>/sp``)."""

    model_config = _FROZEN

    LIMIT: ClassVar[float] = 1e9
    """Largest set-point magnitude: a set point is a physical value; beyond this a law's
    arithmetic could overflow to infinity."""

    value: Finite = Field(ge=-LIMIT, le=LIMIT, strict=True)
    t_apply: int | None = Field(
        default=None,
        ge=0,
        strict=True,
        description="announced change: when it is to be applied, ticks (None: at once)",
    )
    safe_ramp: bool = Field(
        default=False,
        strict=True,
        description="to a coordination agent: if it refuses the step, apply its safe "
        "alternative instead (the fastest set-point ramp to the same value that it judges safe)",
    )


class PlantState(BaseModel):
    """A plant's true state at the instants of its monitoring grid (``plant/<p>/state``).

    Not measurements: reports compute overshoot from them. The plant sends the grid points it
    has passed since its last message, in a batch, whenever it samples (and at the end of the run),
    so the record costs no clock rounds of its own.
    """

    model_config = _FROZEN

    t: tuple[int, ...] = Field(description="grid instants, ticks")
    values: dict[str, tuple[Finite, ...]] = Field(description="state variable -> one value per t")

    @model_validator(mode="after")
    def _same_lengths(self) -> PlantState:
        for name, column in self.values.items():
            if len(column) != len(self.t):
                raise ValueError(f"values.{name}: {len(column)} values for {len(self.t)} times")
        return self


class Loss(BaseModel):
    """A packet the network could not deliver (``net/lost``): retries exhausted or no route."""

    model_config = _FROZEN

    loop: str = Field(description="the loop, or the link for direction 'link'")
    direction: Literal["sensor", "actuator", "link"]
    t_ready: int = Field(ge=0, strict=True, description="time the packet entered the path, ticks")
    reason: str | None = Field(
        default=None,
        description="a TSCH network: queue_full, retries_exhausted, no_route or node_down",
    )


class DelayDistribution(BaseModel):
    """A path's delay distribution for the coordination agent (issue 14): the delays of delivered
    packets at increasing probabilities (the quantile function, piecewise linear between the
    points), a compact histogram, and the probability that a packet is lost.

    ``source`` says where it comes from: ``model`` (the gateway's per-hop models, retries and
    loss composed by seeded Monte Carlo, :func:`gateway.distribution.predict`) or ``measured``
    (time stamps of the packets the path carried).
    """

    model_config = _FROZEN

    source: Literal["model", "measured"]
    probabilities: tuple[Finite, ...] = Field(
        min_length=2, description="increasing, from 0 to 1: where the quantiles are taken"
    )
    delays: tuple[Finite, ...] = Field(
        min_length=2, description="delay of a delivered packet at each probability, time units"
    )
    loss: Finite = Field(ge=0, le=1, description="probability that a packet is lost")
    count: int = Field(ge=0, description="packets the distribution rests on (sent)")
    edges: tuple[Finite, ...] = Field(default=(), description="histogram bin edges, time units")
    counts: tuple[int, ...] = Field(default=(), description="delivered packets per bin")

    @model_validator(mode="after")
    def _consistent(self) -> DelayDistribution:
        p, d = self.probabilities, self.delays
        if len(p) != len(d):
            raise ValueError(f"delays: {len(d)} values for {len(p)} probabilities")
        if p[0] != 0.0 or p[-1] != 1.0 or any(b <= a for a, b in zip(p, p[1:], strict=False)):
            raise ValueError("probabilities: must increase strictly from 0 to 1")
        for k, v in enumerate(d):
            if v < 0:
                raise ValueError(f"delays.{k}: a delay must be >= 0, got {v}")
        if any(b < a for a, b in zip(d, d[1:], strict=False)):
            raise ValueError("delays: must not decrease (a quantile function)")
        if len(self.edges) != (len(self.counts) + 1 if self.counts else 0):
            raise ValueError(f"edges: {len(self.edges)} edges for {len(self.counts)} bins")
        if any(c < 0 for c in self.counts):
            raise ValueError("counts: must be >= 0")
        return self


EstimateName = Literal["timestamps", "ping", "hops"]
"""The paper's three path-delay estimates (seed 000, III.E step 1)."""

Delay = Annotated[float, Field(strict=True, ge=0, allow_inf_nan=False)]
"""A delay in time units: a finite number >= 0 (an int is taken as a float, a bool or a string
is not a number)."""


class PathConfig(BaseModel):
    """One routed path of a network configuration, with the paper's three delay estimates."""

    model_config = _FROZEN

    hops: int = Field(strict=True, ge=-1, description="-1: no route, the path is down")
    route: list[str] = Field(default_factory=list, description="the nodes, sensor to sink")
    estimates: dict[EstimateName, Delay | None] = Field(
        description="timestamps / ping / hops -> estimated path delay, time units (None: not "
        "measured)"
    )
    distribution: DelayDistribution | None = Field(
        default=None, description="the model's delay distribution of the route (None: down)"
    )


class CellBody(BaseModel):
    """One TSCH cell: ``tx`` sends to ``rx`` in slot offset ``slot`` on channel offset
    ``channel`` of the slotframes ``n`` with ``n % every == phase``."""

    model_config = _FROZEN

    slot: int = Field(ge=0, strict=True)
    channel: int = Field(ge=0, strict=True)
    tx: str
    rx: str
    shared: bool = False
    every: int = Field(default=1, ge=1, strict=True)
    phase: int = Field(default=0, ge=0, strict=True)


class TschCapacity(BaseModel):
    """What a TSCH gateway's manager schedules with (``Proposal.tsch``): the coordination agent
    asks the same scheduler whether its periods can be carried on the proposed routes."""

    model_config = _FROZEN

    slot_ticks: int = Field(ge=1, strict=True, description="slot duration, ticks")
    length: int = Field(ge=1, strict=True, description="slots per slotframe")
    channel_offsets: int = Field(ge=1, strict=True)
    retry_cells: int = Field(ge=0, strict=True, description="extra cells per hop of a chain")
    static: bool = Field(description="the schedule is written in the scenario, not computed")
    cells: list[CellBody] = Field(
        default_factory=list, description="written cells (the static schedule, or shared ones)"
    )


class ScheduleSummary(BaseModel):
    """A TSCH manager's schedule as applied (``NetApplied.schedule``)."""

    model_config = _FROZEN

    cells: dict[str, float] = Field(
        description="link 'a->b' -> cells per slotframe (a cell every e slotframes counts 1/e)"
    )
    lacking: dict[str, int] = Field(
        default_factory=dict, description="link 'a->b' -> cells the manager could not place"
    )
    lifetime_h: dict[str, float | None] = Field(
        default_factory=dict, description="node -> projected lifetime under it, hours"
    )


class NetApplied(BaseModel):
    """The network's configuration now in force (``net/applied``): at start and after each event."""

    model_config = _FROZEN

    event: str = Field(
        description="'initial', the type of the event that caused it, 'rates' (sampling periods "
        "applied) or 'no_alternative' (a rejected proposal has no alternative left)"
    )
    source: Literal["initial", "scenario", "injected", "alternative", "agent", "battery"]
    paths: dict[str, PathConfig] = Field(description="path '<loop>.<direction>' -> its route")
    proposal: int | None = Field(default=None, description="the accepted proposal's id")
    periods: dict[str, int] = Field(
        default_factory=dict, description="loop -> sampling period now applied, ticks"
    )
    schedule: ScheduleSummary | None = Field(
        default=None, description="a TSCH gateway: its manager's schedule now in force"
    )
    reason: str | None = Field(
        default=None,
        description="event 'rates_refused': why the manager cannot carry them; event "
        "'no_alternative': what was rejected and that the network runs it",
    )


class NodeStats(BaseModel):
    """Energy of one WSN node."""

    model_config = _FROZEN

    energy_mAh: float
    battery_pct: float
    lifetime_h: float | None = Field(description="projected at the current rates; None: mains")


class PathStats(BaseModel):
    """What one routed path delivered so far."""

    model_config = _FROZEN

    hops: int
    delay_mean: float | None
    delay_p95: float | None
    delay_max: float | None
    sent: int = Field(ge=0)
    lost: int = Field(ge=0)
    distribution: DelayDistribution | None = Field(
        default=None, description="measured from the time stamps (None: nothing carried yet)"
    )


class NetStats(BaseModel):
    """A gateway's WSN (``net/stats``), periodically and at the end: per path what it delivered,
    per node its energy."""

    model_config = _FROZEN

    paths: dict[str, PathStats]
    nodes: dict[str, NodeStats]


class Proposal(BaseModel):
    """A network configuration proposed to the coordination agent (``net/proposal``)."""

    model_config = _FROZEN

    id: int = Field(ge=0, strict=True, description="increasing per gateway")
    event: str
    source: Literal["initial", "scenario", "injected", "alternative", "battery"]
    paths: dict[StrictStr, PathConfig]
    tsch: TschCapacity | None = Field(
        default=None, description="a TSCH gateway: what its manager schedules with"
    )


class Decision(BaseModel):
    """The coordination agent's verdict (``wncsca/decision``) on a proposal, a mode change or a
    set-point request: ``accept``, ``reject`` (a proposal whose delays exceed a loop's bound),
    ``refuse`` (malformed: nothing changes) or ``keep`` (no alternative left: the last accepted
    configuration stays in force)."""

    model_config = _FROZEN

    subject: Literal["proposal", "mode", "setpoint", "links", "rates", "model"]
    network: str | None = Field(default=None, description="the proposing network node")
    proposal: int | None = Field(default=None, description="the proposal's id, if any")
    verdict: Literal["accept", "reject", "refuse", "keep"]
    reasons: tuple[str, ...]
    delays: dict[str, float] = Field(
        default_factory=dict, description="loop -> control-path delay judged, time units"
    )
    bounds: dict[str, float] = Field(
        default_factory=dict, description="loop -> largest tolerable delay, time units"
    )
    offending: tuple[str, ...] = Field(default=(), description="loops over their bound")
    paths: tuple[str, ...] = Field(
        default=(), description="paths of the offending loops, for the gateway's alternative"
    )
    links: tuple[dict[str, Any], ...] = Field(
        default=(),
        description="per group of linked controllers: delay, stabilizing update periods "
        "(h_min, h_max), the assigned h and rho(M) there (agents.wncsca.links.LinkVerdict)",
    )


class Rates(BaseModel):
    """Sampling periods and loop states the agent assigns (``wncsca/rates``)."""

    model_config = _FROZEN

    mode: str
    periods: dict[str, int] = Field(description="loop -> sampling period, ticks")
    closed: dict[str, bool] = Field(description="loop -> closed (False: output held)")
    control_periods: dict[str, int] = Field(
        description="loop -> negotiated control period, ticks (restored for set-point changes)"
    )
    proposal: int | None = Field(description="the accepted configuration the periods are for")
    method: str | None = Field(default=None, description="how the control periods were found")
    overshoot_pct: dict[str, float | None] = Field(
        default_factory=dict, description="predicted worst-case overshoot at the control periods"
    )
    assignment: dict[str, Any] | None = Field(
        default=None, description="a new negotiation: delays, periods, search trace (time units)"
    )
    energy: dict[str, Any] | None = Field(
        default=None, description="projected network lifetime, assigned vs benchmark periods"
    )
    link_periods: dict[str, int] = Field(
        default_factory=dict,
        description="link -> update period h, ticks (the sending controller applies it)",
    )

    @model_validator(mode="after")
    def _positive(self) -> Rates:
        for loop, period in {**self.periods, **self.control_periods}.items():
            if period <= 0:
                raise ValueError(f"periods.{loop}: must be > 0 ticks, got {period}")
        for link, period in self.link_periods.items():
            if period <= 0:
                raise ValueError(f"link_periods.{link}: must be > 0 ticks, got {period}")
        return self


class Timing(BaseModel):
    """Wall-clock time the agent took to decide on a proposal (``wncsca/timing``): a measurement,
    so it is left out of the history digest."""

    model_config = _FROZEN

    proposal: int | None
    decision_s: float = Field(ge=0)


class ModelEstimate(BaseModel):
    """The agent's model as identified on the plant (``wncsca/model``; issue 35, item 3): the
    estimated parameters with their standard deviations (the fit's Gauss-Newton covariance), the
    values believed before, how well the fit explains each loop's delivered samples, and what
    the experiment cost in set-point error."""

    model_config = _FROZEN

    t_start: int = Field(ge=0, strict=True, description="the experiment's start, ticks")
    t_end: int = Field(ge=0, strict=True, description="its end (the estimate's time), ticks")
    params: dict[str, dict[str, Finite]] = Field(
        description="plant -> parameter -> estimated value"
    )
    std: dict[str, dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]]] = Field(
        description="plant -> parameter -> the estimate's standard deviation"
    )
    was: dict[str, dict[str, Finite]] = Field(
        description="plant -> parameter -> the value the agent believed before"
    )
    fit_pct: dict[str, Finite] = Field(
        description="loop -> 100 (1 - |residuals| / |y - mean(y)|) over its delivered samples"
    )
    sigma: dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]] = Field(
        description="loop -> the residuals' RMS, in the signal's unit"
    )
    cost: dict[str, Annotated[float, Field(ge=0, allow_inf_nan=False)]] = Field(
        description="loop -> RMS deviation of its delivered samples from its set point before "
        "the experiment (what the excitation cost), in the signal's unit"
    )
    samples: int = Field(ge=0, strict=True, description="delivered samples fitted, all loops")
    trials: int = Field(ge=0, strict=True, description="simulations the fit took")


class SamplingPeriod(BaseModel):
    """When a sensor samples from now on (``plant/<p>/sampling/<signal>``), from its network."""

    model_config = _FROZEN

    period: int = Field(gt=0, strict=True, description="sampling period, ticks")


class Drift(BaseModel):
    """A change of one of a plant's physical parameters (``plant/<p>/drift``): from the
    operator's schedule (``drifts:``) or ``wncs inject``. The true plant moves ``param`` from its
    value now to ``value``, in ``steps`` equal steps over ``over`` ticks (0: at once), as fouling
    or wear would; the agent's model is not told."""

    model_config = _FROZEN

    param: str = Field(min_length=1, max_length=64)
    value: Finite = Field(strict=True)
    over: int = Field(default=0, ge=0, strict=True, description="ramp duration, ticks")
    steps: int = Field(default=1, ge=1, le=10_000, strict=True, description="ramp steps")


class ModeRequest(BaseModel):
    """An operating-mode change for the coordination agent (``ops/mode``)."""

    model_config = _FROZEN

    mode: str


class InjectRequest(BaseModel):
    """An external input for the clock to stamp into the run (``ops/inject``): exactly one of a
    network reconfiguration (``event``), an operating-mode request (``mode``) or a set-point
    request (``setpoint``) or a plant parameter drift (``drift``)."""

    model_config = _FROZEN

    network: str | None = Field(default=None, description="gateway node; None: the only one")
    event: dict[str, Any] | None = Field(
        default=None, description="a topology event: {type: node_down, node: r1}, ..."
    )
    mode: str | None = Field(default=None, description="an operating mode, for the agent")
    setpoint: dict[str, Any] | None = Field(
        default=None, description="{loop: name, value: number}, on ops/setpoint/<loop>"
    )
    drift: dict[str, Any] | None = Field(
        default=None,
        description="{plant: name, param, value, over (ticks), steps}, on plant/<p>/drift",
    )

    @model_validator(mode="after")
    def _exactly_one(self) -> InjectRequest:
        given = [n for n in ("event", "mode", "setpoint", "drift") if getattr(self, n) is not None]
        if len(given) != 1:
            raise ValueError(f"exactly one of event, mode, setpoint, drift; got {given or 'none'}")
        return self


class NetworkEvent(BaseModel):
    """A reconfiguration delivered to a gateway (``events/<network>``), stamped by the clock."""

    model_config = _FROZEN

    event: dict[str, Any]
    source: Literal["injected"] = "injected"


Digest = Annotated[int, Field(ge=0, lt=1 << 64, strict=True)]
"""A message's fingerprint (:func:`bus_schemas.codec.digest`)."""


def _check_digests(
    digests: dict[str, tuple[Digest, ...]], counts: dict[str, int], name: str
) -> None:
    """Digests must announce exactly the messages ``counts`` counts (keys with none left out)."""
    wanted = {k: n for k, n in counts.items() if n > 0}
    got = {k: len(v) for k, v in digests.items()}
    if got != wanted:
        raise ValueError(f"digests announce {got} messages per key, {name} {wanted}")


class Tick(BaseModel):
    """Start of clock round ``round`` at time ``t`` (DESIGN section 3, step 1)."""

    model_config = _FROZEN

    round: int = Field(ge=0, strict=True)
    t: int = Field(ge=0, strict=True, description="ticks")
    expected: dict[str, int] = Field(
        description="run-relative key -> messages published on it in the previous round"
    )
    participants: tuple[str, ...] | None = Field(
        default=None,
        description="the nodes that take part in this round (sparse rounds: a timer due at t, "
        "or a message of the previous round to collect); None: every participant",
    )
    digests: dict[str, tuple[Digest, ...]] = Field(
        default_factory=dict,
        description="run-relative key -> the digests (codec.digest) of the messages of "
        "expected, as their publishers announced them; a subscriber takes exactly these",
    )

    @model_validator(mode="after")
    def _digests_match_counts(self) -> Tick:
        if self.digests:
            _check_digests(self.digests, self.expected, "expected")
        return self


class Done(BaseModel):
    """A participant has finished round ``round`` (DESIGN section 3, step 2)."""

    model_config = _FROZEN

    round: int = Field(ge=0, strict=True)
    node: str
    published: dict[str, int] = Field(description="run-relative key -> count, this round")
    next_time: int | None = Field(
        default=None, description="earliest pending timer of the node, ticks; None if none"
    )
    dropped_invalid: dict[str, int] = Field(
        default_factory=dict, description="run-relative key -> messages dropped so far"
    )
    listens: tuple[str, ...] | None = Field(
        default=None,
        description="round 0: the key expressions the node subscribes to (run-relative), for "
        "the clock to know who takes part in a round",
    )
    digests: dict[str, tuple[Digest, ...]] = Field(
        default_factory=dict,
        description="run-relative key -> the digests (codec.digest) of the messages counted "
        "in published, for the clock to announce in the next Tick",
    )

    @model_validator(mode="after")
    def _digests_match_counts(self) -> Done:
        _check_digests(self.digests, self.published, "published")
        return self


class Working(BaseModel):
    """A participant is still working on round ``round`` (``clock/working/<node>``): its
    progress heartbeat, sent while one of its rounds lasts longer than a beat (the agent
    deciding, an identification fit), so that the clock's ``round_timeout_s`` judges silence,
    not work (DESIGN section 3). Wall-clock only: it changes nothing in virtual time, and no
    node's round waits for it."""

    model_config = _FROZEN

    round: int = Field(ge=0, strict=True)
    node: str
    busy_s: float = Field(ge=0, allow_inf_nan=False, description="wall time in the round so far")


class Stop(BaseModel):
    """End of the run, normal (``ok``) or because of a fault named in ``reason``."""

    model_config = _FROZEN

    ok: bool
    reason: str = ""
    round: int = Field(ge=0, strict=True)
    t: int = Field(ge=0, strict=True)
    dropped_invalid: dict[str, int] = Field(default_factory=dict)
    dropped_nodes: dict[str, int] = Field(
        default_factory=dict, description="nodes dropped from the run -> round they left in"
    )
    rounds_taken: dict[str, int] = Field(
        default_factory=dict,
        description="node -> rounds it took part in (sparse rounds: the others it sat out)",
    )


class TickLog(BaseModel):
    """The clock's ticks since its last log, in order, and its ``Stop`` when the run has
    ended: what the observers (the historian) and watchers of the run's progress take
    (``clock/log``), a few times a second rather than once a round."""

    model_config = _FROZEN

    ticks: tuple[Tick, ...]
    stop: Stop | None = None


class MonitorHarris(BaseModel):
    """The Harris (minimum-variance) index of a monitored loop, or why it is not identifiable
    (seed 004; ``agents/monitor/harris.py``). Non-finite figures are sent as ``None``."""

    model_config = _FROZEN

    status: Literal["ok", "unidentifiable"]
    index: float | None = Field(default=None, description="minimum variance / variance")
    std: float | None = Field(default=None, description="standard error of the index")
    ci: tuple[float, float] | None = Field(default=None, description="interval of the index")
    confidence: float | None = Field(default=None, description="level of ci")
    sigma2_mv: float | None = Field(default=None, description="minimum variance")
    order: int | None = Field(default=None, ge=1, description="AR order used")
    reason: str | None = Field(default=None, description="reason code when unidentifiable")
    detail: str | None = None


class MonitorCandidate(BaseModel):
    """One candidate secondary of a monitored loop: the variance components 1a, 1b, 2a, 2b and
    the predicted variance under cascade control, or why they are not identifiable (seed 004)."""

    model_config = _FROZEN

    name: str
    d1: int = Field(ge=0, description="dead time secondary -> primary, samples")
    d2: int = Field(ge=1, description="dead time move -> secondary, samples")
    status: Literal["ok", "unidentifiable"]
    components: dict[str, float] | None = Field(
        default=None, description="'1a', '1b', '2a', '2b' -> variance"
    )
    band: tuple[float, float] | None = Field(
        default=None, description="predicted variance of the primary under cascade control"
    )
    point: float | None = Field(default=None, description="working estimate 1a + 2a/2")
    minimum: float | None = Field(default=None, description="component 1a: the cascade's bound")
    reduction: float | None = Field(default=None, description="1 - point / variance now")
    order: int | None = Field(default=None, ge=1, description="VAR order used")
    reason: str | None = Field(default=None, description="reason code when unidentifiable")
    detail: str | None = None


class MonitorAssessment(BaseModel):
    """A performance monitor's assessment of one loop (``monitor/assessment/<loop>``) over a
    sliding window of its samples delivered before ``until``: ``ok`` (figures), or
    ``insufficient_data`` / ``refused`` (``text`` says why; no figures)."""

    model_config = _FROZEN

    loop: str
    status: Literal["ok", "insufficient_data", "refused"]
    final: bool = Field(description="the assessment at the end of the run")
    until: int = Field(ge=0, strict=True, description="samples delivered before this, ticks")
    n_samples: int = Field(ge=0, description="samples in the window")
    t_first: int | None = Field(default=None, description="first sample of the window, ticks")
    t_last: int | None = Field(default=None, description="last sample of the window, ticks")
    delay: int = Field(ge=1, description="dead time move -> primary, samples")
    variance: float | None = Field(default=None, description="variance of the primary")
    harris: MonitorHarris | None = None
    candidates: tuple[MonitorCandidate, ...] = ()
    ranking: tuple[str, ...] = Field(default=(), description="candidates, best first")
    cascade: bool | None = Field(default=None, description="cascade control recommended")
    secondary: str | None = Field(default=None, description="the recommended secondary")
    text: str = Field(default="", description="the recommendation, or why there is none")
