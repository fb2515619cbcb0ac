"""Scenario files: the process graph, loops, set-point schedule and timing of one run.

A scenario is YAML validated into :class:`Scenario` before anything starts; every problem
becomes a :class:`~core.errors.ConfigError` naming the file and the dotted field
(``scenarios/x.yaml: line 14: loops.level.tau_s: Input should be greater than 0``; the line
where the file has the field, ``runtime/yaml_positions.py``; ``--set`` overrides,
``runtime/overrides.py``, are applied before validation).

Shape (see ``scenarios/jcstr_benchmark.yaml``)::

    name, time_unit, end_time, seed, clock: {...}
    nodes:    name -> {kind: plant | controller | network | gateway | operator | agent, ...}
    loops:    name -> {plant, sensor, actuator, controller, network, tau_s, tau_d, tau_a, setpoint}
    links:    name -> {from, to, network, period, delay, source_node, dest_node}
    setpoints: [{t, loop, value}, ...]

A loop with ``sensor: null`` is an **actuator-only** loop: one input of a multi-loop controller
whose law moves inputs it does not measure (seed 001's units measure a temperature and move a heat
input and a feed concentration); it has no sampling, no sensor path and no step figures. A loop
with ``actuator: null`` is **measurement-only**: a measurement a multi-loop controller takes in
without moving an input for it (the secondary of seed 004's PI-P cascade); it is sampled and
delivered like any loop, but no move is published for it and it has no actuator path. A **link**
carries what one multi-loop controller's law transmits (``transmit(t)``, every ``period``) to
another (``receive(t, link, values)``) over a network node, like a sensor path.

Two node names are reserved and always present: ``clock`` and ``historian``; the names of the
bus identities that are not nodes are reserved too (:data:`RESERVED_NODES`).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from agents.monitor.behaviour import MonitorBehaviour
from agents.monitor.config import MonitorNodeConfig
from agents.operator.behaviour import OperatorBehaviour
from agents.wncsca.config import MODES, WncscaConfig
from agents.wncsca.links import link_groups
from agents.wncsca.spec import ClosedLoopSpec, Trial
from bus_schemas import Setpoint, keys
from controllers.behaviour import ControllerBehaviour
from controllers.feedforward import SteadyStateFeedforward
from controllers.registry import (
    LawConfig,
    MultiLoopContext,
    accepts_actuator_only_loops,
    accepts_measurement_only_loops,
    build_multi_loop_law,
    check_loops,
    exchanges_estimates,
    is_multi_loop,
    uses_feedforward,
)
from core.behaviour import Behaviour
from core.errors import ConfigError
from core.record import Simulate
from core.registry import Kind, Registry
from core.time import to_ticks
from gateway.behaviour import NetworkBehaviour
from gateway.energy import EnergyConfig
from gateway.topology import Interference, Topology, TopologyConfig, TopologyEvent
from gateway.tsch.config import TschConfig
from gateway.tsch.network import effective_links, link_quality_of, slot_ticks_of
from gateway.tsch.schedule import check_cells
from plants import registry
from plants.behaviour import PlantBehaviour
from runtime.overrides import Override, apply_overrides, parse_override
from runtime.specs import (
    agent_behaviour,
    controller_spec,
    monitor_spec,
    network_spec,
    operator_spec,
    plant_spec,
    run_shape,
)
from runtime.yaml_positions import field_line, message_path, read_yaml

__all__ = [
    "HISTORIAN",
    "RESERVED_NODES",
    "NODE_KINDS",
    "BehaviourBuild",
    "ClockConfig",
    "PlantNodeConfig",
    "ControllerNodeConfig",
    "NetworkNodeConfig",
    "GatewayNodeConfig",
    "OperatorNodeConfig",
    "LoopConfig",
    "LinkConfig",
    "SetpointChange",
    "ModeChange",
    "Disturbance",
    "Scenario",
    "load_scenario",
    "parse_scenario",
]

HISTORIAN = "historian"
"""The historian's name: a participant of every run, not one of the scenario's nodes."""

RESERVED_NODES = ("clock", HISTORIAN, "inject", "dashboard", "launcher", "threads", "router")
"""Names no node may take: the clock and the historian, and the bus identities that are not
nodes (:mod:`runtime.security`: ``wncs inject``, the dashboard, ``wncs run``'s own session, the
threads engine's session, routers joining each other), whose credentials and grants a node of
that name would take over."""

_C = TypeVar("_C", bound=BaseModel)

AGENT_NETWORK = "wncsca_model_network"
AGENT_OPERATOR = "wncsca_model_operator"
"""The wired network and the operator of the agent's closed-loop model
(:meth:`Scenario.agent_model`)."""


_STRICT = ConfigDict(frozen=True, extra="forbid")


SETPOINT_LIMIT = Setpoint.LIMIT
"""Largest set-point magnitude accepted anywhere (the bus schema's bound)."""

MAX_END_TIME = 1e9
"""Longest run, time units (1e15 ticks: well inside 64-bit integers)."""


class ClockConfig(BaseModel):
    """Wall-clock limits of the round protocol (DESIGN section 3)."""

    model_config = _STRICT

    round_timeout_s: float = Field(
        default=10.0,
        gt=0,
        description="a participant silent this long in a round (no answer, no progress "
        "heartbeat) is a fault; round 0, where nodes do their one-off work, has "
        "startup_timeout_s",
    )
    startup_timeout_s: float = Field(
        default=120.0,
        gt=0,
        description="time for every participant to come alive, and then to answer round 0",
    )
    work_timeout_s: float = Field(
        default=3600.0,
        gt=0,
        description="the longest a participant may work on one round: a node busy with a long "
        "computation (the agent deciding) sends a progress heartbeat, so round_timeout_s judges "
        "only silence, and this ends a node that computes forever",
    )
    max_microsteps: int = Field(
        default=10_000, gt=0, description="rounds allowed at one instant before it is an error"
    )
    max_rounds: int = Field(
        default=100_000_000,
        gt=0,
        description="rounds a run may take before it is stopped as an error (a long end_time "
        "with a fast timer runs this many at most)",
    )
    may_drop: tuple[str, ...] = Field(
        default=(),
        description="nodes whose loss the run survives: the clock drops them and carries on "
        "(a plant then holds its last inputs); losing any other node stops the run",
    )


class PlantNodeConfig(BaseModel):
    """A plant simulator: integrates its model, samples its sensors, holds its inputs."""

    model_config = _STRICT

    kind: Literal["plant"]
    model: str = Field(description="plant model name, one of plants.registry.MODELS")
    params: dict[str, Any] = Field(description="the model's physical parameters by symbol")
    x0: dict[str, float] = Field(description="initial state by state name")
    u0: dict[str, float] = Field(description="inputs held until the first command arrives")
    monitor_period: float = Field(
        default=0.01, gt=0, description="period of the true-state record (plant/<p>/state)"
    )
    max_step: float = Field(default=0.005, gt=0, description="largest RK4 integration step")
    noise: dict[str, float] = Field(
        default_factory=dict,
        description="sensor signal -> standard deviation of additive Gaussian measurement noise; "
        "each signal draws from its own generator seeded from the scenario seed and its name",
    )
    input_range: dict[str, tuple[float, float]] = Field(
        default_factory=dict,
        description="input -> [low, high], the actuator's physical range (a valve cannot pass "
        "a negative flow: [0, .inf]); a command beyond it is held at the limit it passes, as "
        "the actuator saturates. Inputs not named have no limit.",
    )

    @model_validator(mode="after")
    def _check_model(self) -> PlantNodeConfig:
        if self.model not in registry.MODELS:
            raise ValueError(
                f"model: unknown plant model {self.model!r} (known: {sorted(registry.MODELS)})"
            )
        try:
            plant = registry.build(self.model, self.params)
        except ValidationError as err:
            e = err.errors()[0]
            loc = ".".join(str(p) for p in e["loc"])
            raise ValueError(f"params.{loc}: {e['msg']}") from err
        for signal, sigma in self.noise.items():
            if signal not in plant.output_names:
                raise ValueError(
                    f"noise.{signal}: not an output of {self.model!r} "
                    f"(outputs: {list(plant.output_names)})"
                )
            if not sigma >= 0:
                raise ValueError(f"noise.{signal}: standard deviation must be >= 0, got {sigma}")
        for field, names, given in (
            ("x0", plant.state_names, self.x0),
            ("u0", plant.input_names, self.u0),
        ):
            if set(given) != set(names):
                raise ValueError(f"{field}: expected exactly {list(names)}, got {sorted(given)}")
        for name, (low, high) in self.input_range.items():
            if name not in plant.input_names:
                raise ValueError(
                    f"input_range.{name}: not an input of {self.model!r} "
                    f"(inputs: {list(plant.input_names)})"
                )
            if not low < high:
                raise ValueError(f"input_range.{name}: low ({low}) must be below high ({high})")
            if not low <= self.u0[name] <= high:
                raise ValueError(
                    f"u0.{name}: {self.u0[name]} is outside input_range.{name} [{low}, {high}]"
                )
        return self

    def build(self) -> Any:
        """The plant object."""
        return registry.build(self.model, self.params)


class ControllerNodeConfig(BaseModel):
    """A controller of one loop (``loop: name``), or of several at once (``loops: [a, b]``, for a
    multi-loop law such as the MRAC: see :mod:`controllers.node` for how it executes)."""

    model_config = _STRICT

    kind: Literal["controller"]
    loop: str | None = Field(default=None, description="the one loop of a single-loop law")
    loops: tuple[str, ...] | None = Field(
        default=None, description="the loops of a multi-loop law, in the order of its x and u"
    )
    law: LawConfig

    @model_validator(mode="after")
    def _one_or_several(self) -> ControllerNodeConfig:
        multi = is_multi_loop(self.law)
        if self.loop is not None and self.loops is not None:
            raise ValueError("loops: give either loop: (one loop) or loops: (several), not both")
        if self.loops is None:
            if self.loop is None:
                raise ValueError(
                    "loops: a controller names its loop (loop: name) or loops (loops: [a, b])"
                )
            if multi:
                raise ValueError(
                    f"loop: law {self.law.type!r} controls several loops at once; name them "
                    "with loops: [...]"
                )
            return self
        if not multi:
            raise ValueError(
                f"loops: law {self.law.type!r} controls one loop; name it with loop: (a loop per "
                "controller node)"
            )
        if len(set(self.loops)) != len(self.loops):
            raise ValueError(f"loops: a loop is named twice in {list(self.loops)}")
        try:
            check_loops(self.law, self.loops)
        except ValueError as err:
            raise ValueError(f"loops: {err}") from err
        return self

    @property
    def loop_names(self) -> tuple[str, ...]:
        """The loops it controls, in order (one for a single-loop law)."""
        return self.loops if self.loops is not None else (str(self.loop),)


class NetworkNodeConfig(BaseModel):
    """A network that carries the loops naming it, with each loop's constant path delays.

    The wireless gateway emulator (multi-hop delays, loss, energy) replaces this node kind; a
    ``network`` node is a wired fieldbus with fixed latency ``tau_d`` (sensor path) and
    ``tau_a`` (actuator path) per loop.
    """

    model_config = _STRICT

    kind: Literal["network"]
    traces: dict[str, list[Annotated[float, Field(ge=0, allow_inf_nan=False)] | None]] = Field(
        default_factory=dict,
        description="loop -> sensor-path delay of its 1st, 2nd, ... sample, time units (null: "
        "the sample is lost); after the last, the loop's tau_d. A recorded or drawn delay "
        "sequence replayed on a wired path (the coordination agent's realizations)",
    )


class ScheduledEvent(BaseModel):
    """A reconfiguration of the WSN at a set time (node down/up, link degraded, ...)."""

    model_config = _STRICT

    t: float = Field(ge=0)
    event: TopologyEvent


class GatewayNodeConfig(BaseModel):
    """A WSN gateway: the loops naming it have their sensor (and optionally actuator) paths
    routed over its topology, with per-hop delays, retries and loss (``gateway/``), or carried
    by a TSCH network (``mac: tsch``: slotframes, cells, a central scheduler, channel hopping,
    queues; ``gateway/tsch/``)."""

    model_config = _STRICT

    kind: Literal["gateway"]
    mac: Literal["per_hop", "tsch"] = Field(
        default="per_hop",
        description="per_hop: each hop's delay drawn from its link's model; tsch: a TSCH "
        "network run slot by slot (tsch:)",
    )
    tsch: TschConfig = Field(default_factory=TschConfig, description="the TSCH network (mac: tsch)")
    topology: TopologyConfig
    events: list[ScheduledEvent] = Field(
        default_factory=list, description="reconfigurations applied at their times"
    )
    energy: EnergyConfig = Field(
        default_factory=EnergyConfig,
        description="radio charges and batteries; seconds_per_unit maps scenario time to s",
    )
    ping_probes: int = Field(default=10, ge=1, description="probes per ping estimate")
    stats_period: float | None = Field(
        default=None, gt=0, description="period of net/stats (always sent at the end)"
    )

    @model_validator(mode="after")
    def _one_gateway(self) -> GatewayNodeConfig:
        self.gateway_node()
        topology = Topology(self.topology)  # every event must apply, in time order
        for i in sorted(range(len(self.events)), key=lambda k: self.events[k].t):
            event = self.events[i].event
            if isinstance(event, Interference) and self.mac != "tsch":
                raise ValueError(
                    f"events[{i}].event: interference needs a TSCH network (mac: tsch); the "
                    "per-hop models have no channels"
                )
            try:
                topology.apply(event)
            except ValueError as err:
                raise ValueError(f"events[{i}].event: {err}") from err
        if self.mac == "tsch":
            self._check_tsch()
        return self

    def _check_tsch(self) -> None:
        """The TSCH network must run: slot duration in whole ticks, positions for ``pathloss``,
        a trace that reads, a written schedule without conflicts between known nodes."""
        cfg = self.tsch
        try:
            slot_ticks_of(cfg, self.energy.seconds_per_unit)
            quality = link_quality_of(cfg, self.topology, np.random.default_rng(0))
            effective_links(cfg, self.topology, quality)
        except ValueError as err:
            raise ValueError(str(err)) from err
        field = "tsch.schedule" if cfg.schedule != "auto" else "tsch.shared_cells"
        cells = cfg.cells()
        for i, cell in enumerate(cells):
            for end in ("tx", "rx"):
                if getattr(cell, end) not in self.topology.nodes:
                    raise ValueError(
                        f"{field}[{i}].{end}: unknown node {getattr(cell, end)!r} "
                        f"(nodes: {sorted(self.topology.nodes)})"
                    )
        check_cells(cells, cfg.length, cfg.offsets, where=field)

    def gateway_node(self) -> str:
        """The topology's node of kind ``gateway``."""
        names = [n for n, spec in self.topology.nodes.items() if spec.kind == "gateway"]
        if len(names) != 1:
            raise ValueError(f"topology.nodes: exactly one node of kind gateway, found {names}")
        return names[0]


class OperatorNodeConfig(BaseModel):
    """Publishes the scenario's set-point schedule on ``ops/setpoint/<loop>``."""

    model_config = _STRICT

    kind: Literal["operator"]


def _kind_of(config: type[BaseModel]) -> str:
    """The ``kind:`` a node configuration class stands for (the node-kind registry's name)."""
    return next(k.name for k in NODE_KINDS.kinds.values() if k.config is config)


@dataclass(frozen=True)
class BehaviourBuild:
    """A node kind's build: ``behaviour(name, spec(scenario, name))``, the node's typed spec
    computed once (:mod:`runtime.specs`)."""

    behaviour: Callable[[str, Any], Behaviour]
    spec: Callable[[Scenario, str], Any]

    def __call__(self, name: str, scenario: Scenario, simulate: Simulate) -> Behaviour:
        return self.behaviour(name, self.spec(scenario, name))


NODE_KINDS: Registry[Behaviour] = Registry(
    "node kind",
    tag="kind",
    kinds=[
        Kind("plant", PlantNodeConfig, BehaviourBuild(PlantBehaviour, plant_spec)),
        Kind(
            "controller",
            ControllerNodeConfig,
            BehaviourBuild(ControllerBehaviour, controller_spec),
        ),
        Kind("network", NetworkNodeConfig, BehaviourBuild(NetworkBehaviour, network_spec)),
        Kind("gateway", GatewayNodeConfig, BehaviourBuild(NetworkBehaviour, network_spec)),
        Kind("operator", OperatorNodeConfig, BehaviourBuild(OperatorBehaviour, operator_spec)),
        Kind("agent", WncscaConfig, agent_behaviour, "the coordination agent"),
        Kind("monitor", MonitorNodeConfig, BehaviourBuild(MonitorBehaviour, monitor_spec)),
    ],
)
"""Every node kind: its ``kind:``, its configuration, and ``build(name, scenario, simulate)``:
the behaviour every engine runs (``simulate`` runs a scenario on the direct engine, for nodes
that simulate, as the coordination agent does)."""

NodeConfig = NODE_KINDS.union()
"""A node's configuration, chosen by its ``kind`` field."""


class LoopConfig(BaseModel):
    """One control loop: which plant signal it measures, which input it moves, and its timing."""

    model_config = _STRICT

    plant: str
    sensor: str | None = Field(
        description="plant output measured by the loop's sensor; null: an actuator-only loop "
        "(an input of a multi-loop controller that it does not measure)"
    )
    actuator: str | None = Field(
        description="plant input moved by the loop's controller; null: a measurement-only loop "
        "(a measurement of a multi-loop controller that moves no input for it)"
    )
    controller: str = Field(description="name of the controller node")
    network: str = Field(description="network node carrying the loop's sensor and actuator paths")
    tau_s: float | None = Field(
        default=None, gt=0, description="sampling period of the loop's sensor (none without one)"
    )
    tau_d: float = Field(default=0.0, ge=0, description="sensor-to-controller path delay")
    tau_a: float = Field(default=0.0, ge=0, description="controller-to-actuator path delay")
    sensor_node: str | None = Field(
        default=None, description="gateway networks: the topology node hosting the sensor"
    )
    actuator_node: str | None = Field(
        default=None,
        description="gateway networks: the topology node hosting the actuator; None = wired",
    )
    setpoint: float | None = Field(
        default=None, description="set point at t = 0 (an actuator-only loop may have none)"
    )
    settling_band: float = Field(
        default=0.02, gt=0, lt=1, description="settling band as a fraction of the step size"
    )

    @model_validator(mode="after")
    def _sensor_or_not(self) -> LoopConfig:
        if self.actuator is None:
            if self.sensor is None:
                raise ValueError(
                    "actuator: a loop without a sensor must move an input (sensor and actuator "
                    "both null)"
                )
            self._unset(
                {"tau_a": 0.0, "actuator_node": None},
                "a measurement-only loop (actuator: null) moves nothing",
            )
        if self.sensor is not None:
            for field in ("tau_s", "setpoint"):
                if getattr(self, field) is None:
                    raise ValueError(f"{field}: Field required (the loop has a sensor)")
            return self
        self._unset(
            {"tau_s": None, "tau_d": 0.0, "sensor_node": None},
            "an actuator-only loop (sensor: null) samples nothing",
        )
        return self

    def _unset(self, defaults: dict[str, Any], why: str) -> None:
        """Refuse a field given a value the loop's kind has no use for (``why``)."""
        for field, default in defaults.items():
            if getattr(self, field) != default:
                raise ValueError(f"{field}: {why}; leave {field} out")

    @property
    def has_sensor(self) -> bool:
        """Whether the loop measures something (``False``: an actuator-only loop)."""
        return self.sensor is not None

    @property
    def has_actuator(self) -> bool:
        """Whether the loop moves an input (``False``: a measurement-only loop)."""
        return self.actuator is not None


class LinkConfig(BaseModel):
    """Data one controller's law sends to another's every ``period`` over a network node
    (seed 001: a unit's state estimate, the update of its neighbours' models)."""

    model_config = ConfigDict(
        frozen=True, extra="forbid", validate_by_name=True, serialize_by_alias=True
    )

    from_: str = Field(alias="from", description="the sending controller node")
    to: str = Field(description="the receiving controller node")
    network: str = Field(description="network or gateway node that carries it")
    period: float = Field(gt=0, description="update period h: one transmission every period")
    delay: float = Field(
        default=0.0, ge=0, description="constant delay over a wired network (kind: network)"
    )
    source_node: str | None = Field(
        default=None, description="gateway networks: the topology node of the sender"
    )
    dest_node: str | None = Field(
        default=None, description="gateway networks: the topology node of the receiver"
    )


class Disturbance(BaseModel):
    """A scheduled change of a plant input that no loop moves (e.g. a disturbance outflow)."""

    model_config = _STRICT

    t: float = Field(ge=0)
    plant: str
    input: str
    value: float


class SetpointChange(BaseModel):
    """A scheduled set-point change, optionally announced ahead (to a coordination agent)."""

    model_config = _STRICT

    t: float = Field(ge=0)
    loop: str
    value: float = Field(
        ge=-SETPOINT_LIMIT,
        le=SETPOINT_LIMIT,
        description=f"the new set point (a physical value: |value| <= {SETPOINT_LIMIT:g})",
    )
    announce: float = Field(
        default=0.0,
        ge=0,
        description="the operator requests the change this long before t (needs an agent)",
    )


class ModeChange(BaseModel):
    """A scheduled operating-mode request to the coordination agent (``ops/mode``)."""

    model_config = _STRICT

    t: float = Field(ge=0)
    mode: str = Field(description="startup, setpoint_change, identification, steady_state, ...")


class Scenario(BaseModel):
    """A whole run: process graph, loops, schedule and end time."""

    model_config = _STRICT

    name: str
    time_unit: str = "pu"
    end_time: float = Field(
        gt=0,
        le=MAX_END_TIME,
        description=f"end of the run, time units (at most {MAX_END_TIME:g}: ticks stay 64-bit)",
    )
    seed: int = Field(default=0, ge=0)
    clock: ClockConfig = ClockConfig()
    nodes: dict[str, NodeConfig]
    loops: dict[str, LoopConfig]
    links: dict[str, LinkConfig] = Field(
        default_factory=dict, description="data exchanged between controllers, by link name"
    )
    setpoints: list[SetpointChange] = []
    disturbances: list[Disturbance] = []
    modes: list[ModeChange] = Field(
        default_factory=list, description="operating modes requested of the agent, in time"
    )

    @field_validator("nodes")
    @classmethod
    def _node_names(cls, nodes: dict[str, Any]) -> dict[str, Any]:
        for name in nodes:
            keys.check_name(name, "node name")
            if name in RESERVED_NODES:
                raise ValueError(f"{name!r} is a reserved node name ({RESERVED_NODES})")
        return nodes

    @field_validator("loops")
    @classmethod
    def _loop_names(cls, loops: dict[str, Any]) -> dict[str, Any]:
        for name in loops:
            keys.check_name(name, "loop name")
        return loops

    @field_validator("links")
    @classmethod
    def _link_names(cls, links: dict[str, Any]) -> dict[str, Any]:
        for name in links:
            keys.check_name(name, "link name")
        return links

    @model_validator(mode="after")
    def _check_graph(self) -> Scenario:
        def node_of(config: type[BaseModel], name: str, where: str) -> Any:
            node = self.nodes.get(name)
            if node is None:
                raise ValueError(f"{where}: unknown node {name!r} (nodes: {sorted(self.nodes)})")
            if not isinstance(node, config):
                expected = _kind_of(config)
                raise ValueError(f"{where}: node {name!r} is a {node.kind}, expected a {expected}")
            return node

        for name, node in self.nodes.items():
            if not isinstance(node, ControllerNodeConfig) or node.loops is None:
                continue
            for i, lname in enumerate(node.loops):
                if lname not in self.loops:
                    raise ValueError(
                        f"nodes.{name}.loops[{i}]: unknown loop {lname!r} "
                        f"(loops: {sorted(self.loops)})"
                    )
        for name, node in self.nodes.items():
            for lname in getattr(node, "traces", {}) if isinstance(node, NetworkNodeConfig) else ():
                carried = self.loops.get(lname)
                if carried is None or carried.network != name:
                    raise ValueError(
                        f"nodes.{name}.traces.{lname}: no loop {lname!r} is carried by {name!r}"
                    )
        controlled: dict[str, str] = {}
        for lname, loop in self.loops.items():
            at = f"loops.{lname}"
            plant_cfg = node_of(PlantNodeConfig, loop.plant, f"{at}.plant")
            plant = plant_cfg.build()
            ctrl = node_of(ControllerNodeConfig, loop.controller, f"{at}.controller")
            if loop.sensor is None:
                if ctrl.loops is None or not accepts_actuator_only_loops(ctrl.law):
                    raise ValueError(
                        f"{at}.sensor: null (an actuator-only loop) is allowed only for a loop of "
                        "a multi-loop controller whose law moves inputs it does not measure; "
                        f"node {loop.controller!r} (law {ctrl.law.type!r}) needs a sensor"
                    )
            elif loop.sensor not in plant.output_names:
                raise ValueError(
                    f"{at}.sensor: plant {loop.plant!r} has no output {loop.sensor!r} "
                    f"(outputs: {list(plant.output_names)})"
                )
            if loop.actuator is None:
                if ctrl.loops is None or not accepts_measurement_only_loops(ctrl.law):
                    raise ValueError(
                        f"{at}.actuator: null (a measurement-only loop) is allowed only for a "
                        "loop of a multi-loop controller whose law takes measurements it moves "
                        f"no input for; node {loop.controller!r} (law {ctrl.law.type!r}) needs "
                        "an actuator"
                    )
            elif loop.actuator not in plant.input_names:
                raise ValueError(
                    f"{at}.actuator: plant {loop.plant!r} has no input {loop.actuator!r} "
                    f"(inputs: {list(plant.input_names)})"
                )

            if lname not in ctrl.loop_names:
                what = f"loop {ctrl.loop!r}" if ctrl.loops is None else f"loops {list(ctrl.loops)}"
                raise ValueError(f"{at}.controller: node {loop.controller!r} controls {what}")
            if loop.controller in controlled and ctrl.loops is None:
                raise ValueError(
                    f"{at}.controller: {loop.controller!r} already controls "
                    f"loop {controlled[loop.controller]!r}"
                )
            controlled[loop.controller] = lname
            net = self.nodes.get(loop.network)
            if isinstance(net, GatewayNodeConfig):
                topo_nodes = net.topology.nodes
                if loop.sensor is not None and loop.sensor_node not in topo_nodes:
                    raise ValueError(
                        f"{at}.sensor_node: {loop.sensor_node!r} is not a node of the topology of "
                        f"{loop.network!r} (nodes: {sorted(topo_nodes)})"
                    )
                if loop.actuator_node is not None and loop.actuator_node not in topo_nodes:
                    raise ValueError(
                        f"{at}.actuator_node: {loop.actuator_node!r} is not a node "
                        f"of the topology of {loop.network!r}"
                    )
                if loop.tau_d:
                    raise ValueError(
                        f"{at}.tau_d: a gateway's paths take their delays from its "
                        "topology; leave tau_d at 0"
                    )
            else:
                node_of(NetworkNodeConfig, loop.network, f"{at}.network")
                if loop.sensor_node is not None or loop.actuator_node is not None:
                    raise ValueError(f"{at}.sensor_node: only loops over a gateway name WSN nodes")
            if loop.tau_s is not None and to_ticks(loop.tau_s) < 1:
                raise ValueError(f"{at}.tau_s: {loop.tau_s} is shorter than one tick")
        for name, node in self.nodes.items():
            if not isinstance(node, ControllerNodeConfig):
                continue
            if node.loops is None:
                if name not in controlled:
                    raise ValueError(f"nodes.{name}.loop: no loop names {name!r} as its controller")
                continue
            for i, lname in enumerate(node.loops):
                at = f"nodes.{name}.loops[{i}]"
                if self.loops[lname].controller != name:
                    raise ValueError(
                        f"{at}: loop {lname!r} names {self.loops[lname].controller!r} as its "
                        "controller"
                    )
            if all(self.loops[lname].sensor is None for lname in node.loops):
                raise ValueError(
                    f"nodes.{name}.loops: every loop is actuator-only (sensor: null); the law "
                    "executes on samples and would never move"
                )
            if all(self.loops[lname].actuator is None for lname in node.loops):
                raise ValueError(
                    f"nodes.{name}.loops: every loop is measurement-only (actuator: null); the "
                    "controller would never move an input"
                )
            agent = self.agent_node()
            linked = any(name in (lk.from_, lk.to) for lk in self.links.values())
            if agent is not None and not (linked and self.nodes[agent].links is not None):
                raise ValueError(
                    f"nodes.{name}.loops: the coordination agent simulates single-loop "
                    "controllers only (it opens, closes and re-tunes loops one by one); it "
                    "governs a multi-loop controller only through its links' update period "
                    f"(links: in nodes.{agent}, and the controller on a link)"
                )
        for i, name in enumerate(self.clock.may_drop):
            if name not in self.nodes:
                raise ValueError(f"clock.may_drop[{i}]: unknown node {name!r}")
        operators = list(self.nodes_of(OperatorNodeConfig))
        if len(operators) > 1:
            raise ValueError(f"nodes: at most one operator node, found {operators}")
        if self.setpoints and not operators:
            raise ValueError("setpoints: a schedule needs an operator node to publish it")
        if self.disturbances and not operators:
            raise ValueError("disturbances: a schedule needs an operator node to publish it")
        self._check_agent()
        for name, node in self.nodes.items():
            if isinstance(node, MonitorNodeConfig):
                node.check(run_shape(self), name)  # the loop and columns it assesses exist
                if self.loops[node.loop].sensor is None:
                    raise ValueError(
                        f"nodes.{name}.loop: loop {node.loop!r} is actuator-only (no samples)"
                    )
        moved = {(lp.plant, lp.actuator) for lp in self.loops.values() if lp.actuator is not None}
        for i, dist in enumerate(self.disturbances):
            at = f"disturbances[{i}]"
            plant_cfg = node_of(PlantNodeConfig, dist.plant, f"{at}.plant")
            inputs = plant_cfg.build().input_names
            if dist.input not in inputs:
                raise ValueError(
                    f"{at}.input: plant {dist.plant!r} has no input {dist.input!r} "
                    f"(inputs: {list(inputs)})"
                )
            if (dist.plant, dist.input) in moved:
                raise ValueError(f"{at}.input: {dist.input!r} is moved by a loop's controller")
            if dist.t > self.end_time:
                raise ValueError(f"{at}.t: {dist.t} is after end_time {self.end_time}")
        for i, change in enumerate(self.setpoints):
            if change.loop not in self.loops:
                raise ValueError(
                    f"setpoints[{i}].loop: unknown loop {change.loop!r} "
                    f"(loops: {sorted(self.loops)})"
                )
            if change.t > self.end_time:
                raise ValueError(f"setpoints[{i}].t: {change.t} is after end_time {self.end_time}")
            if self.loops[change.loop].sensor is None:
                raise ValueError(
                    f"setpoints[{i}].loop: {change.loop!r} is actuator-only (sensor: null): "
                    "it has no set point"
                )
            if change.announce > change.t:
                raise ValueError(
                    f"setpoints[{i}].announce: {change.announce} is before the run starts "
                    f"(t = {change.t})"
                )
            if change.announce and self.agent_node() is None:
                raise ValueError(f"setpoints[{i}].announce: announcing needs an agent node")
        if self.modes and (self.agent_node() is None or not operators):
            raise ValueError("modes: mode requests need an agent node and an operator node")
        for i, change in enumerate(self.modes):
            if change.mode not in MODES:
                raise ValueError(f"modes[{i}].mode: unknown mode {change.mode!r} (modes: {MODES})")
            if change.t > self.end_time:
                raise ValueError(f"modes[{i}].t: {change.t} is after end_time {self.end_time}")
        self._check_feedforward()
        self._check_links()
        self._check_multi_loop_laws()
        self._check_agent_links()
        self._check_one_loop_per_input()
        return self

    def _check_one_loop_per_input(self) -> None:
        """Two loops moving one input would fight over it (after the laws' own checks, which
        name their own cases more precisely)."""
        movers: dict[tuple[str, str], str] = {}  # (plant, input) -> the loop that moves it
        for lname, loop in self.loops.items():
            if loop.actuator is None:
                continue
            first = movers.setdefault((loop.plant, loop.actuator), lname)
            if first != lname:
                raise ValueError(
                    f"loops.{lname}.actuator: input {loop.actuator!r} of plant {loop.plant!r} is "
                    f"already moved by loop {first!r} (one loop per input)"
                )

    def _check_agent_links(self) -> None:
        """The analysis an agent with ``links:`` will run needs laws it can analyse (built now,
        so that a refusal names the agent before anything starts)."""
        agent = self.agent_node()
        cfg = self.nodes[agent] if agent is not None else None
        if cfg is None or cfg.links is None:
            return
        try:
            link_groups(
                self.links, self.multi_loop_law, cfg.links.analysis, tau_s=self.multi_loop_tau_s
            )
        except ValueError as err:
            raise ValueError(f"nodes.{agent}.links: {err}") from err

    def _check_links(self) -> None:
        """Links join two multi-loop controllers whose laws exchange data, over a network node."""
        for name, link in self.links.items():
            at = f"links.{name}"
            if name in self.loops:
                raise ValueError(f"{at}: a loop has that name; name links and loops apart")
            for field, node in (("from", link.from_), ("to", link.to)):
                cfg = self.nodes.get(node)
                if not isinstance(cfg, ControllerNodeConfig):
                    known = sorted(self.nodes_of(ControllerNodeConfig))
                    raise ValueError(
                        f"{at}.{field}: {node!r} is not a controller node (controllers: {known})"
                    )
                if cfg.loops is None:
                    raise ValueError(
                        f"{at}.{field}: node {node!r} controls one loop; links join multi-loop "
                        "controllers (loops: [...])"
                    )
                if not exchanges_estimates(cfg.law):
                    raise ValueError(
                        f"{at}.{field}: the law of node {node!r} ({cfg.law.type!r}) does not "
                        "transmit or receive on links"
                    )
            if link.from_ == link.to:
                raise ValueError(f"{at}.to: a link joins two different controllers")
            net = self.nodes.get(link.network)
            if isinstance(net, GatewayNodeConfig):
                topo_nodes = net.topology.nodes
                for field, node in (
                    ("source_node", link.source_node),
                    ("dest_node", link.dest_node),
                ):
                    if node not in topo_nodes:
                        raise ValueError(
                            f"{at}.{field}: {node!r} is not a node of the topology of "
                            f"{link.network!r} (nodes: {sorted(topo_nodes)})"
                        )
                if link.source_node == link.dest_node:
                    raise ValueError(f"{at}.dest_node: the link's two ends are the same node")
                if link.delay:
                    raise ValueError(
                        f"{at}.delay: a gateway's paths take their delays from its topology; "
                        "leave delay at 0"
                    )
            else:
                if not isinstance(net, NetworkNodeConfig):
                    raise ValueError(
                        f"{at}.network: {link.network!r} is not a network or gateway node"
                    )
                if link.source_node is not None or link.dest_node is not None:
                    raise ValueError(f"{at}.source_node: only links over a gateway name WSN nodes")
            if to_ticks(link.period) < 1:
                raise ValueError(f"{at}.period: {link.period} is shorter than one tick")

    def _check_multi_loop_laws(self) -> None:
        """Build every multi-loop law once, so that refusals that depend on the plant (a design
        the plant's linearization does not admit) name the node before anything starts."""
        for name, node in self.nodes.items():
            if not isinstance(node, ControllerNodeConfig) or node.loops is None:
                continue
            try:
                self.multi_loop_law(name)
            except ValueError as err:
                raise ValueError(f"nodes.{name}.law.{node.law.type}: {err}") from err

    def multi_loop_law(self, controller: str) -> Any:
        """A fresh instance of multi-loop controller ``controller``'s law, as its node builds it."""
        node = self.nodes[controller]
        return build_multi_loop_law(
            node.law,
            loops=node.loops,
            plant=self.nodes[self.loops[node.loops[0]].plant].build(),
            tau_s=self.multi_loop_tau_s(controller),
            context=self.multi_loop_context(controller),
        )

    def simulated_loops(self) -> tuple[str, ...]:
        """The loops a coordination agent judges by simulating them: those of single-loop
        controllers (multi-loop controllers on links are governed by their update period)."""
        return tuple(
            n for n, lp in sorted(self.loops.items()) if self.nodes[lp.controller].loops is None
        )

    def multi_loop_context(self, controller: str) -> MultiLoopContext:
        """The loops' signals and the links of multi-loop controller ``controller``."""
        cfg = self.nodes[controller]
        return MultiLoopContext(
            signals={n: (self.loops[n].sensor, self.loops[n].actuator) for n in cfg.loop_names},
            sends=tuple(n for n, lk in sorted(self.links.items()) if lk.from_ == controller),
            receives=tuple(n for n, lk in sorted(self.links.items()) if lk.to == controller),
        )

    def multi_loop_tau_s(self, controller: str) -> float:
        """The shortest sampling period of a multi-loop controller's loops with a sensor."""
        cfg = self.nodes[controller]
        return min(
            float(self.loops[n].tau_s)  # type: ignore[arg-type]
            for n in cfg.loop_names
            if self.loops[n].tau_s is not None
        )

    def _check_agent(self) -> None:
        """At most one coordination agent; every loop it names must exist."""
        agents = list(self.nodes_of(WncscaConfig))
        if len(agents) > 1:
            raise ValueError(f"nodes: at most one agent node, found {agents}")
        for name in agents:
            cfg = self.nodes[name]
            named = [(f"order[{i}]", n) for i, n in enumerate(cfg.order or [])]
            named += [(f"ideal_period.{n}", n) for n in cfg.ideal_period]
            named += [(f"alarm.{n}", n) for n in cfg.alarm]
            for mode in ("identification", "monitoring", "fault_detection"):
                named += [(f"modes.{mode}.{n}", n) for n in getattr(cfg.modes, mode)]
            if cfg.test is not None:
                named += [
                    (f"test.setpoints[{i}].loop", s.loop) for i, s in enumerate(cfg.test.setpoints)
                ]
            for where, loop in named:
                if loop not in self.loops:
                    raise ValueError(
                        f"nodes.{name}.{where}: unknown loop {loop!r} (loops: {sorted(self.loops)})"
                    )
            if cfg.links is not None and not self.links:
                raise ValueError(f"nodes.{name}.links: the scenario has no links to govern")
            steps = cfg.test.setpoints if cfg.test is not None else self.setpoints
            unstepped = sorted(set(self.simulated_loops()) - {s.loop for s in steps})
            if unstepped:
                where = "test.setpoints" if cfg.test is not None else "test (default: setpoints)"
                raise ValueError(
                    f"nodes.{name}.{where}: no set-point step for loop(s) {unstepped}; the agent "
                    "judges a loop by the overshoot of its step"
                )

    def _check_feedforward(self) -> None:
        """Every steady-state feedforward must be computable at every scheduled set point."""
        current = {name: loop.setpoint for name, loop in self.loops.items()}
        order = sorted(range(len(self.setpoints)), key=lambda i: self.setpoints[i].t)
        for index in [None, *order]:
            where = "loops.*.setpoint (initial set points)"
            if index is not None:
                change = self.setpoints[index]
                current[change.loop] = change.value
                where = f"setpoints[{index}]"
            for lname, loop in self.loops.items():
                if not uses_feedforward(self.nodes[loop.controller].law):
                    continue
                try:
                    self.feedforward(lname).u_bar(self.plant_setpoints(loop.plant, current))
                except ValueError as err:
                    raise ValueError(f"{where}: feedforward of loop {lname!r}: {err}") from err

    # -- derived views used by nodes and engines --------------------------------------------------
    def nodes_of(self, config: type[_C]) -> dict[str, _C]:
        """The nodes configured by ``config`` (a node kind's configuration class), by name."""
        return {n: c for n, c in self.nodes.items() if isinstance(c, config)}

    def plants(self) -> dict[str, PlantNodeConfig]:
        """The plant nodes by name."""
        return self.nodes_of(PlantNodeConfig)

    def controllers(self) -> dict[str, ControllerNodeConfig]:
        """The controller nodes by name."""
        return self.nodes_of(ControllerNodeConfig)

    def carriers(self) -> list[str]:
        """The nodes that carry loops: wired networks and WSN gateways, sorted."""
        return sorted(self.nodes_of(NetworkNodeConfig) | self.nodes_of(GatewayNodeConfig))

    def gateways(self) -> list[str]:
        """The WSN gateways, sorted."""
        return sorted(self.nodes_of(GatewayNodeConfig))

    def is_wireless(self, network: str) -> bool:
        """Whether ``network`` routes its loops over a WSN topology (a gateway), rather than a
        wired network of constant delays."""
        return isinstance(self.nodes.get(network), GatewayNodeConfig)

    def agent_node(self) -> str | None:
        """The coordination agent's node name, or ``None``."""
        return next(iter(sorted(self.nodes_of(WncscaConfig))), None)

    def setpoint_key(self, loop: str) -> str:
        """Where controllers read loop ``loop``'s set points: from operations
        (``ops/setpoint/<loop>``), or from the coordination agent (``loop/<loop>/sp``) that
        governs the loops, restoring control rates before it passes a change on."""
        if self.agent_node() is None:
            return keys.setpoint(loop)
        return keys.loop_setpoint(loop)

    def loops_of_plant(self, plant: str) -> dict[str, LoopConfig]:
        """The loops measuring or moving plant ``plant``, by name (sorted)."""
        return {n: lp for n, lp in sorted(self.loops.items()) if lp.plant == plant}

    def plant_setpoints(self, plant: str, setpoints: Mapping[str, float]) -> dict[str, float]:
        """The subset of loop set points that belong to ``plant``'s loops."""
        return {n: setpoints[n] for n in self.loops_of_plant(plant)}

    def feedforward(self, loop: str) -> Any:
        """The steady-state feedforward object of ``loop`` (seed 000, eq. (5)-(7))."""
        lp = self.loops[loop]
        plant = self.nodes[lp.plant].build()
        outputs = {
            n: other.sensor
            for n, other in self.loops_of_plant(lp.plant).items()
            if other.sensor is not None
        }
        return SteadyStateFeedforward(plant, outputs, lp.actuator)

    def disturbance_times(self) -> dict[str, list[int]]:
        """Plant -> sorted ticks of its scheduled disturbances."""
        out: dict[str, list[int]] = {}
        for d in self.disturbances:
            out.setdefault(d.plant, []).append(to_ticks(d.t))
        return {p: sorted(v) for p, v in out.items()}

    def sensor_rng(self, plant: str, signal: str) -> Any:
        """The seeded generator of one sensor's measurement noise (the plant node owns it)."""
        return np.random.default_rng(
            [self.seed, zlib.crc32(plant.encode()), zlib.crc32(signal.encode())]
        )

    def participants(self) -> list[str]:
        """Every node that takes part in clock rounds: the scenario's nodes and the historian."""
        return sorted([*self.nodes, HISTORIAN])

    def agent_model(self, spec: ClosedLoopSpec) -> Scenario:
        """The coordination agent's closed-loop model (:func:`runtime.specs.closed_loop_spec`)
        as a scenario of its own: this scenario's plants and controllers of the judged loops,
        each loop on one wired network of no delay (no radio nodes), an operator for the
        spec's steps, at the benchmark periods; validated here, once."""
        loops = {
            n: self.loops[n].model_copy(
                update={
                    "network": AGENT_NETWORK,
                    "sensor_node": None,
                    "actuator_node": None,
                    "tau_d": 0.0,
                    "tau_a": 0.0,
                }
            )
            for n in spec.names
        }
        nodes: dict[str, Any] = {
            n: cfg
            for n, cfg in self.nodes.items()
            if n in spec.plants or n in {lp.controller for lp in spec.loops.values()}
        }
        nodes[AGENT_NETWORK] = NetworkNodeConfig(kind="network")
        nodes[AGENT_OPERATOR] = OperatorNodeConfig(kind="operator")
        return Scenario(
            name=spec.name,
            time_unit=spec.time_unit,
            end_time=spec.end_time,
            seed=spec.seed,
            nodes=nodes,
            loops=loops,
            setpoints=[
                SetpointChange(t=s.t, loop=s.loop, value=s.value, announce=s.announce)
                for s in spec.steps
            ],
            disturbances=[],
        )

    def trial(self, trial: Trial) -> Scenario:
        """This agent model (:meth:`agent_model`) with one trial's periods, delays, steps, end
        and delay traces (only those fields replaced: the trial's values are checked by the
        agent, :meth:`agents.wncsca.model.LoopModel.evaluate`)."""
        loops = {
            name: lp.model_copy(update={"tau_s": trial.periods[name], "tau_d": trial.delays[name]})
            for name, lp in self.loops.items()
        }
        template = self.setpoints[0]
        update: dict[str, Any] = {
            "loops": loops,
            "setpoints": [
                template.model_copy(
                    update={"t": s.t, "loop": s.loop, "value": s.value, "announce": s.announce}
                )
                for s in trial.steps
            ],
            "end_time": trial.end_time,
        }
        if trial.traces is not None:
            network = NetworkNodeConfig.model_validate(
                {"kind": "network", "traces": dict(trial.traces)}
            )
            update["nodes"] = {**self.nodes, AGENT_NETWORK: network}
        return self.model_copy(update=update)

    def with_loops(
        self,
        *,
        tau_s: Mapping[str, float] | None = None,
        tau_d: Mapping[str, float] | None = None,
    ) -> Scenario:
        """A copy with some loops' ``tau_s`` / ``tau_d`` replaced (validated again)."""
        data = self.model_dump()
        for field, values in (("tau_s", tau_s), ("tau_d", tau_d)):
            for name, value in (values or {}).items():
                if name not in data["loops"]:
                    raise ValueError(f"with_loops: unknown loop {name!r}")
                data["loops"][name][field] = value
        return Scenario.model_validate(data)


def _format_error(source: str, err: ValidationError, text: str | None = None) -> str:
    """One line per error: ``source: field: message``; ``source: line N: field: ...`` with text."""
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        line = None if text is None else field_line(text, message_path(e["loc"], msg))
        where = source if line is None else f"{source}: line {line}"
        lines.append(f"{where}: {loc + ': ' if loc else ''}{msg}")
    return "\n".join(lines)


_INFINITE_OK = frozenset({"u_min", "u_max"})
"""Fields where an infinite value means "no limit" (actuator limits; and the bounds of a plant
node's ``input_range``)."""


def _infinite_ok(path: tuple[Any, ...]) -> bool:
    return bool(path) and (
        path[-1] in _INFINITE_OK or (len(path) >= 3 and path[-3] == "input_range")
    )


def _non_finite(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], float]]:
    """Every NaN, and every infinity outside :data:`_INFINITE_OK`, in a scenario's mapping."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _non_finite(value, (*path, key))
    elif isinstance(data, list | tuple):
        for i, value in enumerate(data):
            yield from _non_finite(value, (*path, i))
    elif isinstance(data, float) and not math.isfinite(data):
        if math.isnan(data) or not _infinite_ok(path):
            yield path, data


def parse_scenario(
    data: Any,
    *,
    source: str = "<scenario>",
    text: str | None = None,
    base_dir: str | Path | None = None,
) -> Scenario:
    """Validate an already-parsed mapping; errors name ``source`` and the field.

    With ``text`` (the YAML ``data`` was read from), each error also names the field's line.
    Relative file names in the scenario (a TSCH link trace) are taken from ``base_dir`` (the
    scenario file's folder) and kept absolute.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: a scenario must be a mapping, got {type(data).__name__}")
    for path, value in _non_finite(data):
        line = None if text is None else field_line(text, path)
        where = source if line is None else f"{source}: line {line}"
        raise ConfigError(f"{where}: {'.'.join(map(str, path))}: {value} is not a finite number")
    context = {"base_dir": str(base_dir)} if base_dir is not None else None
    try:
        return Scenario.model_validate(data, context=context)
    except ValidationError as err:
        raise ConfigError(_format_error(source, err, text)) from err


def load_scenario(path: str | Path, *, overrides: Sequence[str | Override] = ()) -> Scenario:
    """Read and validate a scenario file, after applying ``--set`` style ``overrides``.

    The overrides (``"loops.level.tau_s=0.2"``, see :mod:`runtime.overrides`) change the mapping
    read from the file before validation, so a bad value is refused as it would be in the file.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not YAML (the message names line and column), an override
        names a path the file does not have, or the scenario does not validate; the message names
        the file, the dotted field and, where the file has it, the field's line
        (``scenarios/x.yaml: line 14: loops.level.tau_s: Input should be greater than 0``).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"{path}: cannot read scenario: {err.strerror or err}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(
            f"{path}: not a text scenario: byte {err.object[err.start]:#04x} at offset "
            f"{err.start} is not UTF-8"
        ) from err
    if "\x00" in text:
        raise ConfigError(f"{path}: not a text scenario: NUL byte at offset {text.index(chr(0))}")
    data = read_yaml(text, source=str(path))
    parsed = [o if isinstance(o, Override) else parse_override(o) for o in overrides]
    data = apply_overrides(data, parsed)
    return parse_scenario(data, source=str(path), text=text, base_dir=path.parent)
