"""The scenario's schema: what a scenario file may say, node by node (DESIGN section 2).

The configuration of every node kind (:class:`PlantNodeConfig`, :class:`ControllerNodeConfig`,
:class:`NetworkNodeConfig`, :class:`GatewayNodeConfig`, :class:`OperatorNodeConfig`, the agent's
:class:`~agents.wncsca.config.WncscaConfig`, the monitor's
:class:`~agents.monitor.config.MonitorNodeConfig`), the static :data:`NodeConfig` union of them
(discriminated by ``kind``; ``tests/unit/test_scenario_package.py`` checks it is the node-kind
registry's union, :data:`scenario.kinds.NODE_KINDS`), loops, links and schedules, and
:class:`ScenarioSchema`: a whole scenario's fields, each checked alone, with the derived views
the node specs and engines read (:meth:`ScenarioSchema.carriers`, ...). The checks across fields
(:mod:`scenario.checks`) make it a :class:`scenario.model.Scenario`.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Self, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from agents.monitor.config import MonitorNodeConfig
from agents.wncsca.config import WncscaConfig
from agents.wncsca.spec import ClosedLoopSpec, Trial
from bus_schemas import Setpoint, keys
from controllers.feedforward import SteadyStateFeedforward
from controllers.registry import (
    LawConfig,
    MultiLoopContext,
    build_multi_loop_law,
    check_loops,
    is_multi_loop,
)
from core.time import to_ticks
from gateway.energy import EnergyConfig
from gateway.topology import Interference, Topology, TopologyConfig, TopologyEvent
from gateway.tsch.config import TschConfig
from gateway.tsch.network import effective_links, link_quality_of, slot_ticks_of
from gateway.tsch.schedule import check_cells
from plants import registry

__all__ = [
    "HISTORIAN",
    "RESERVED_NODES",
    "AGENT_NETWORK",
    "AGENT_OPERATOR",
    "SETPOINT_LIMIT",
    "MAX_END_TIME",
    "ClockConfig",
    "PlantNodeConfig",
    "ControllerNodeConfig",
    "NetworkNodeConfig",
    "ScheduledEvent",
    "GatewayNodeConfig",
    "OperatorNodeConfig",
    "NodeConfig",
    "LoopConfig",
    "LinkConfig",
    "Disturbance",
    "DriftChange",
    "SetpointChange",
    "ModeChange",
    "ScenarioSchema",
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
    feedforward_params: dict[str, float] = Field(
        default_factory=dict,
        description="plant parameters its steady-state feedforward is designed on, where they "
        "differ from the plant node's (a controller designed on another model of its plant; "
        "the agent's trials pin them when the plant drifts from its design)",
    )

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


NodeConfig = Annotated[
    PlantNodeConfig
    | ControllerNodeConfig
    | NetworkNodeConfig
    | GatewayNodeConfig
    | OperatorNodeConfig
    | WncscaConfig
    | MonitorNodeConfig,
    Field(discriminator="kind"),
]
"""A node's configuration, chosen by its ``kind`` field: written out here, so that a type
checker sees it; the node-kind registry (:data:`scenario.kinds.NODE_KINDS`) has the same kinds
with their builds (a test checks the two agree)."""


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
    sample_offset: float = Field(
        default=0.0,
        ge=0,
        description="when the sensor first samples (time units); then every tau_s (a sensor "
        "whose clock is not the run's: staggered sensors, or the agent's replay of a run)",
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


class DriftChange(BaseModel):
    """A scheduled drift of one of a true plant's physical parameters (fouling, wear): from its
    value at ``t`` to ``value``, at once (``over: 0``) or in ``steps`` equal steps over ``over``
    time units. The plant node changes; a coordination agent's model does not."""

    model_config = _STRICT

    t: float = Field(ge=0, description="when the drift starts, time units")
    plant: str
    param: str = Field(description="the parameter, by the plant model's symbol")
    value: float = Field(description="where it ends, in the parameter's unit")
    over: float = Field(default=0.0, ge=0, description="ramp duration, time units (0: a step)")
    steps: int = Field(default=20, ge=1, le=10_000, description="ramp steps (piecewise constant)")


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
    safe_ramp: bool = Field(
        default=False,
        description="if the agent refuses the step, it applies its safe alternative instead (the "
        "fastest set-point ramp to the value that it judges safe; needs an agent)",
    )


class ModeChange(BaseModel):
    """A scheduled operating-mode request to the coordination agent (``ops/mode``)."""

    model_config = _STRICT

    t: float = Field(ge=0)
    mode: str = Field(description="startup, setpoint_change, identification, steady_state, ...")


class ScenarioSchema(BaseModel):
    """A whole run: process graph, loops, schedule and end time, each field checked alone; the
    checks across fields (:mod:`scenario.checks`) make it a :class:`scenario.model.Scenario`."""

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
    drifts: list[DriftChange] = Field(
        default_factory=list,
        description="scheduled drifts of plant parameters (published by the operator)",
    )
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

    def node(self, name: str, config: type[_C]) -> _C:
        """Node ``name`` as a node of ``config``'s kind (``TypeError`` if it is another's: the
        checks, :mod:`scenario.checks`, have made sure where the schema says so)."""
        node = self.nodes[name]
        if not isinstance(node, config):
            raise TypeError(f"node {name!r} is a {node.kind}, not a {config.__name__}")
        return node

    def controller(self, name: str) -> ControllerNodeConfig:
        """Controller node ``name``."""
        return self.node(name, ControllerNodeConfig)

    def plant(self, name: str) -> PlantNodeConfig:
        """Plant node ``name``."""
        return self.node(name, PlantNodeConfig)

    def multi_loop_law(self, controller: str) -> Any:
        """A fresh instance of multi-loop controller ``controller``'s law, as its node builds it."""
        node = self.controller(controller)
        loops = node.loop_names
        return build_multi_loop_law(
            node.law,
            loops=loops,
            plant=self.plant(self.loops[loops[0]].plant).build(),
            tau_s=self.multi_loop_tau_s(controller),
            context=self.multi_loop_context(controller),
        )

    def simulated_loops(self) -> tuple[str, ...]:
        """The loops a coordination agent judges by simulating them: those of single-loop
        controllers (multi-loop controllers on links are governed by their update period)."""
        return tuple(
            n
            for n, lp in sorted(self.loops.items())
            if self.controller(lp.controller).loops is None
        )

    def multi_loop_context(self, controller: str) -> MultiLoopContext:
        """The loops' signals and the links of multi-loop controller ``controller``."""
        cfg = self.controller(controller)
        return MultiLoopContext(
            signals={n: (self.loops[n].sensor, self.loops[n].actuator) for n in cfg.loop_names},
            sends=tuple(n for n, lk in sorted(self.links.items()) if lk.from_ == controller),
            receives=tuple(n for n, lk in sorted(self.links.items()) if lk.to == controller),
        )

    def multi_loop_tau_s(self, controller: str) -> float:
        """The shortest sampling period of a multi-loop controller's loops with a sensor."""
        cfg = self.controller(controller)
        return min(
            float(tau_s) for n in cfg.loop_names if (tau_s := self.loops[n].tau_s) is not None
        )

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
        """The subset of loop set points that belong to ``plant``'s loops (those with one: an
        actuator-only loop has none)."""
        return {n: setpoints[n] for n in self.loops_of_plant(plant) if n in setpoints}

    def feedforward(self, loop: str) -> SteadyStateFeedforward:
        """The steady-state feedforward object of ``loop`` (seed 000, eq. (5)-(7))."""
        lp = self.loops[loop]
        if lp.actuator is None:
            raise ValueError(f"loops.{loop}: a measurement-only loop moves no input")
        cfg = self.plant(lp.plant)
        design = self.controllers()[lp.controller].feedforward_params
        if design:  # the controller's own model of its plant
            cfg = cfg.model_copy(update={"params": {**cfg.params, **design}})
        plant = cfg.build()
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

    def believed(self, config: WncscaConfig) -> Self:
        """This scenario as agent ``config`` believes it: each plant of its ``model:`` with the
        believed parameters (the others the plant node's own), validated (``ValueError`` naming
        ``model.<plant>.params``: the agent's node adds its own prefix)."""
        if not config.model:
            return self
        nodes = dict(self.nodes)
        for plant, belief in sorted(config.model.items()):
            cfg = self.plant(plant)
            try:
                nodes[plant] = PlantNodeConfig.model_validate(
                    {**cfg.model_dump(), "params": {**cfg.params, **belief.params}}
                )
            except ValidationError as err:
                e = err.errors()[0]
                msg = str(e["msg"]).removeprefix("Value error, ")
                raise ValueError(f"model.{plant}: {msg}") from err
        return self.model_copy(update={"nodes": nodes})

    def agent_model(self, spec: ClosedLoopSpec) -> Self:
        """The coordination agent's closed-loop model (:func:`scenario.views.closed_loop_spec`)
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
        controllers = {lp.controller for lp in spec.loops.values()}
        nodes: dict[str, Any] = {  # the plants as the agent believes them, not the plant nodes
            n: cfg.model_copy(update={"params": dict(spec.plants[n].params)})
            if n in spec.plants
            else cfg
            for n, cfg in self.nodes.items()
            if n in spec.plants or n in controllers
        }
        nodes[AGENT_NETWORK] = NetworkNodeConfig(kind="network")
        nodes[AGENT_OPERATOR] = OperatorNodeConfig(kind="operator")
        return type(self)(
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

    def trial(self, trial: Trial) -> Self:
        """This agent model (:meth:`agent_model`) with one trial's periods, delays, steps, end,
        delay traces and plant parameters (only those fields replaced: the trial's values are
        checked by the agent, :meth:`agents.wncsca.model.LoopModel.evaluate`, and its draws of
        parameters by :mod:`agents.wncsca.uncertainty`)."""
        offsets = trial.offsets or {}
        loops = {
            name: lp.model_copy(
                update={
                    "tau_s": trial.periods[name],
                    "tau_d": trial.delays[name],
                    "sample_offset": float(offsets.get(name, 0.0)),
                }
            )
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
        nodes = dict(self.nodes)
        if trial.traces is not None:
            nodes[AGENT_NETWORK] = NetworkNodeConfig.model_validate(
                {"kind": "network", "traces": dict(trial.traces)}
            )
        for plant, params in sorted((trial.params or {}).items()):  # a draw of the model
            cfg = self.plant(plant)
            nodes[plant] = cfg.model_copy(update={"params": {**cfg.params, **params}})
        for plant, noise in sorted((trial.noise or {}).items()):  # identification's noise
            nodes[plant] = nodes[plant].model_copy(update={"noise": dict(noise)})
        for plant, design in sorted((trial.design or {}).items()):  # the controllers' design
            for lp in self.loops_of_plant(plant).values():
                ctl = self.controllers()[lp.controller]
                nodes[lp.controller] = ctl.model_copy(update={"feedforward_params": dict(design)})
        if trial.traces is not None or trial.params or trial.noise or trial.design:
            update["nodes"] = nodes
        if trial.seed is not None:
            update["seed"] = trial.seed
        return self.model_copy(update=update)

    def with_loops(
        self,
        *,
        tau_s: Mapping[str, float] | None = None,
        tau_d: Mapping[str, float] | None = None,
    ) -> Self:
        """A copy with some loops' ``tau_s`` / ``tau_d`` replaced (validated again)."""
        data = self.model_dump()
        for field, values in (("tau_s", tau_s), ("tau_d", tau_d)):
            for name, value in (values or {}).items():
                if name not in data["loops"]:
                    raise ValueError(f"with_loops: unknown loop {name!r}")
                data["loops"][name][field] = value
        return type(self).model_validate(data)
