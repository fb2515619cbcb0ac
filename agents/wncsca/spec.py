"""The coordination agent's typed front door: what it knows of a run, computed once by the
scenario layer (:func:`runtime.agent_spec.agent_spec`), and how its trials are run.

The agent never sees the scenario. It is handed an :class:`AgentSpec`: its configuration, the
:class:`ClosedLoopSpec` it judges by simulation (the judged loops' plants, laws and set-point
test, seed 000 III.C-III.E), the networks that carry its loops (each a
:class:`~gateway.carrier.CarrierSpec`), the wired delays and the link groups (seed 001). Its
trials go to a :class:`Simulator` (the scenario layer's, which runs them on the direct engine):
a :class:`Trial` says what changes from the closed-loop spec (periods, delays, steps, end, delay
traces), never how a scenario is written.

A renamed scenario field then breaks the scenario layer, where the types are known (mypy, the
tests), not the agent at run time.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from agents.wncsca.config import ParameterUncertainty, WncscaConfig
from agents.wncsca.links import LinkGroup
from controllers.feedforward import SteadyStateFeedforward
from core.record import RunRecord
from gateway.carrier import CarrierSpec

__all__ = [
    "Step",
    "JudgedPlant",
    "JudgedLoop",
    "ClosedLoopSpec",
    "Trial",
    "Simulator",
    "LinkSpec",
    "AgentSpec",
]


@dataclass(frozen=True)
class Step:
    """A set-point step of a trial: loop ``loop`` to ``value`` at ``t`` (time units), requested
    ``announce`` before it (the operator's lead)."""

    t: float
    loop: str
    value: float
    announce: float = 0.0


@dataclass(frozen=True)
class JudgedPlant:
    """A plant of the judged loops, as the agent's model holds it."""

    name: str
    model: Any
    """The plant model (``plants.registry``: ``rhs``, ``outputs``, ``linearize``, ...), built
    with the parameters the agent believes (:attr:`params`), not the plant node's."""
    x0: Mapping[str, float]
    u0: Mapping[str, float]
    max_step: float
    monitor_period: float
    noise: Mapping[str, float] = field(default_factory=dict)
    params: Mapping[str, Any] = field(default_factory=dict)
    """The model's parameters as the agent believes them (its ``model:``; by default the plant
    node's own)."""
    uncertainty: Mapping[str, ParameterUncertainty] = field(default_factory=dict)
    """Parameter -> how well the agent knows it (none named: known exactly)."""
    kind: str = ""
    """The plant model's name in ``plants.registry.MODELS`` (to build it with other
    parameters)."""


@dataclass(frozen=True)
class JudgedLoop:
    """A loop the agent judges by simulating it: a single-loop controller with a sensor and an
    actuator on its plant."""

    name: str
    plant: str
    sensor: str
    actuator: str
    controller: str
    law: Any
    """The controller's law configuration (``controllers.registry.LawConfig``)."""
    setpoint: float
    tau_s: float
    """The benchmark sampling period, time units."""
    feedforward: SteadyStateFeedforward | None
    """The law's steady-state feedforward (seed 000, eq. (5)-(7)); ``None`` for laws without."""


@dataclass(frozen=True)
class ClosedLoopSpec:
    """The agent's closed-loop model: its judged loops on wired paths of constant delay, their
    plants and controllers, under the set-point test (the agent's ``test:``, default the
    scenario's schedule), at the benchmark periods and no delay."""

    name: str
    time_unit: str
    seed: int
    end_time: float
    plants: Mapping[str, JudgedPlant]
    loops: Mapping[str, JudgedLoop]
    steps: tuple[Step, ...]
    fingerprint: str
    """A digest of everything that determines a trial's outcome but its periods and delays."""

    @property
    def names(self) -> tuple[str, ...]:
        """The judged loops, in name order."""
        return tuple(sorted(self.loops))

    @property
    def benchmark(self) -> dict[str, float]:
        """Each judged loop's benchmark period (time units)."""
        return {n: self.loops[n].tau_s for n in self.names}


@dataclass(frozen=True)
class Trial:
    """One simulation of the closed-loop spec with what changes: every judged loop's period
    and control-path delay (time units), the set-point steps, the end, and each loop's sensor
    path delays replayed sample by sample (``None`` in a trace: lost) before its constant delay
    takes over."""

    periods: Mapping[str, float]
    delays: Mapping[str, float]
    steps: tuple[Step, ...]
    end_time: float
    traces: Mapping[str, list[float | None]] | None = None
    params: Mapping[str, Mapping[str, float]] | None = None
    """Plant -> parameters that replace the model's for this trial (a draw of the agent's
    model uncertainty, :mod:`agents.wncsca.uncertainty`)."""
    noise: Mapping[str, Mapping[str, float]] | None = None
    """Plant -> sensor signal -> measurement noise standard deviation, replacing the plant's
    (an empty mapping: none; ``None``: the model's own), as identification needs it."""
    seed: int | None = None
    """The trial's seed (its noise realization); ``None``: the model's."""
    design: Mapping[str, Mapping[str, float]] | None = None
    """Plant -> the parameters its controllers' steady-state feedforward is designed on
    (``None``: the trial's plant's own, as :attr:`params` set them)."""
    offsets: Mapping[str, float] | None = None
    """Loop -> its sensor's first sampling instant (time units; none named: 0), as a replay of
    the run's sampling grid needs it (:mod:`agents.wncsca.window`)."""


class Simulator(Protocol):
    """Runs a :class:`Trial` of a :class:`ClosedLoopSpec` to its record (the scenario layer's
    :class:`runtime.agent_spec.ScenarioSimulator`, on the direct engine)."""

    def __call__(self, trial: Trial) -> RunRecord:
        """The record of ``trial``."""
        ...


@dataclass(frozen=True)
class LinkSpec:
    """A link between controllers (seed 001) as the agent governs it."""

    network: str
    period: float
    """Its configured update period, time units."""
    delay: float
    """Its constant delay over a wired network, time units."""


@dataclass(frozen=True)
class AgentSpec:
    """Everything the coordination agent knows of its run (see the module docstring)."""

    config: WncscaConfig
    closed_loop: ClosedLoopSpec
    seed: int
    carriers: Mapping[str, CarrierSpec]
    """Every node that carries loops or links (wired networks and gateways), by name."""
    loop_networks: Mapping[str, str]
    """Every loop -> the network that carries it."""
    setpoints: Mapping[str, float]
    """Every loop's set point at t = 0 (loops with a sensor: an actuator-only loop has none)."""
    links: Mapping[str, LinkSpec] = field(default_factory=dict)
    link_groups: tuple[LinkGroup, ...] = ()
    """The link groups under the agent's ``links:`` analysis (empty without it)."""
    loop_delays: Mapping[str, float] = field(default_factory=dict)
    """Every loop's constant control-path delay ``tau_d + tau_a`` (what a wired network
    carries it with), time units."""

    def is_wireless(self, network: str) -> bool:
        """Whether ``network`` is a WSN gateway (its delays come with its proposals)."""
        carrier = self.carriers.get(network)
        return carrier is not None and carrier.gateway is not None
