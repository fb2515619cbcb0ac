"""Each node's typed spec, computed once from its scenario (the scenario layer, DESIGN section 2),
and the views of a scenario the application reads.

A behaviour takes what it needs as a frozen spec (:class:`~plants.behaviour.PlantSpec`,
:class:`~controllers.behaviour.ControllerSpec`, :class:`~gateway.behaviour.NetworkSpec`,
:class:`~agents.operator.behaviour.OperatorSpec`, :class:`~agents.monitor.behaviour.MonitorSpec`)
instead of the whole :class:`~scenario.model.Scenario`, so it neither re-derives the scenario's
view nor depends on its shape. The node kinds' builds (:data:`scenario.kinds.NODE_KINDS`) pass
a node's spec to its behaviour. A network's paths take a :class:`~gateway.carrier.CarrierSpec`.

The coordination agent takes an :class:`~agents.wncsca.spec.AgentSpec` (:func:`agent_spec`):
its judged loops as a :class:`~agents.wncsca.spec.ClosedLoopSpec`, the networks and links it
governs; its trials run through a :class:`ScenarioSimulator`, which writes each trial as a
scenario (:meth:`~scenario.schema.ScenarioSchema.agent_model`,
:meth:`~scenario.schema.ScenarioSchema.trial`) and runs it on the engine it is handed (the
direct engine's ``simulate``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from typing import Any

from agents.monitor.behaviour import MonitorSpec
from agents.monitor.columns import RunLoop, RunShape
from agents.monitor.config import MonitorNodeConfig
from agents.monitor.run_data import RunSeries
from agents.operator.behaviour import DisturbanceAt, DriftAt, ModeAt, OperatorSpec, SetpointAt
from agents.wncsca.behaviour import WncscaBehaviour
from agents.wncsca.config import WncscaConfig
from agents.wncsca.coordinator import Coordinator
from agents.wncsca.links import LinkGroup, link_groups
from agents.wncsca.model import LoopModel
from agents.wncsca.spec import (
    AgentSpec,
    ClosedLoopSpec,
    JudgedLoop,
    JudgedPlant,
    LinkSpec,
    Step,
    Trial,
)
from agents.wncsca.trials import Trials
from bus_schemas import Drift
from controllers.behaviour import ControllerSpec
from controllers.registry import uses_feedforward
from core.errors import ConfigError
from core.record import RunRecord, Simulate
from core.time import to_ticks
from gateway.behaviour import NetworkSpec
from gateway.carrier import CarrierSpec, PathCarrier, initial_hops
from plants.behaviour import PlantSpec
from scenario.schema import GatewayNodeConfig, NetworkNodeConfig, ScenarioSchema

__all__ = [
    "agent_config",
    "closed_loop_spec",
    "agent_spec",
    "ScenarioSimulator",
    "loop_model",
    "coordinator",
    "agent_behaviour",
    "carrier_spec",
    "path_hops",
    "plant_spec",
    "controller_spec",
    "network_spec",
    "run_shape",
    "monitor_spec",
    "operator_spec",
]


def plant_spec(scenario: ScenarioSchema, name: str) -> PlantSpec:
    """Plant node ``name``: its model, initial state and inputs, sensors and their generators."""
    cfg = scenario.plant(name)
    model = cfg.build()
    sensors = {
        lp.sensor: to_ticks(lp.tau_s)
        for lp in scenario.loops_of_plant(name).values()
        if lp.sensor is not None and lp.tau_s is not None  # actuator-only: nothing to sample
    }
    return PlantSpec(
        model=model,
        x0=tuple(float(cfg.x0[s]) for s in model.state_names),
        u0=tuple(float(cfg.u0[s]) for s in model.input_names),
        max_step=cfg.max_step,
        monitor=to_ticks(cfg.monitor_period),
        end=to_ticks(scenario.end_time),
        sensors=sensors,
        noise=dict(cfg.noise),
        rngs={s: scenario.sensor_rng(name, s) for s in sensors},
        input_range=tuple(cfg.input_range.get(i, (-math.inf, math.inf)) for i in model.input_names),
        kind=cfg.model,
        params=dict(cfg.params),
        offsets={
            lp.sensor: to_ticks(lp.sample_offset)
            for lp in scenario.loops_of_plant(name).values()
            if lp.sensor is not None and lp.tau_s is not None and lp.sample_offset > 0
        },
    )


def controller_spec(scenario: ScenarioSchema, name: str) -> ControllerSpec:
    """Controller node ``name``: its loops, law, plant model, set points and links."""
    cfg = scenario.controller(name)
    loops = cfg.loop_names
    first = scenario.loops[loops[0]]
    plants = sorted({scenario.loops[n].plant for n in loops})
    setpoints = {n: lp.setpoint for p in plants for n, lp in scenario.loops_of_plant(p).items()}
    common: dict[str, Any] = {
        "loops": loops,
        "multi": cfg.loops is not None,
        "law": cfg.law,
        "plant": scenario.plant(first.plant).build(),
        "setpoints": setpoints,
        "setpoint_keys": {n: scenario.setpoint_key(n) for n in setpoints},
        "governed": scenario.agent_node() is not None,
        "end": to_ticks(scenario.end_time),
    }
    if cfg.loops is None:
        if first.tau_s is None:
            raise ValueError(f"loops.{loops[0]}: a single-loop controller's loop samples")
        feedforward = scenario.feedforward(loops[0]) if uses_feedforward(cfg.law) else None
        return ControllerSpec(tau_s=first.tau_s, feedforward=feedforward, **common)
    links = sorted(scenario.links.items())
    return ControllerSpec(
        tau_s=scenario.multi_loop_tau_s(name),
        context=scenario.multi_loop_context(name),
        measured=tuple(n for n in loops if scenario.loops[n].sensor is not None),
        moved=tuple(n for n in loops if scenario.loops[n].actuator is not None),
        sends={n: to_ticks(lk.period) for n, lk in links if lk.from_ == name},
        receives=tuple(n for n, lk in links if lk.to == name),
        **common,
    )


def carrier_spec(scenario: ScenarioSchema, name: str) -> CarrierSpec:
    """What network node ``name``'s paths are made of: the loops and links it carries."""
    return CarrierSpec(
        node=name,
        seed=scenario.seed,
        loops={n: lp for n, lp in sorted(scenario.loops.items()) if lp.network == name},
        links={n: lk for n, lk in sorted(scenario.links.items()) if lk.network == name},
        gateway=scenario.node(name, GatewayNodeConfig) if scenario.is_wireless(name) else None,
        traces={}
        if scenario.is_wireless(name)
        else dict(scenario.node(name, NetworkNodeConfig).traces),
    )


def path_hops(scenario: ScenarioSchema) -> dict[str, int]:
    """Loop -> hops of its sensor path (0 wired, -1 down), for every loop of the scenario: from
    each network's routes alone (:func:`gateway.carrier.initial_hops`), not its whole carrier."""
    out: dict[str, int] = {}
    for name in scenario.carriers():
        out.update(initial_hops(carrier_spec(scenario, name)))
    return out


def network_spec(scenario: ScenarioSchema, name: str) -> NetworkSpec:
    """Network or gateway node ``name``: the paths it carries, and its timing."""
    gateway = scenario.nodes_of(GatewayNodeConfig).get(name)
    stats_period = gateway.stats_period if gateway is not None else None
    return NetworkSpec(
        carrier=PathCarrier.from_spec(carrier_spec(scenario, name)),
        governed=scenario.agent_node() is not None,
        end=to_ticks(scenario.end_time),
        stats_period=None if stats_period is None else to_ticks(stats_period),
    )


def run_shape(scenario: ScenarioSchema) -> RunShape:
    """What the monitor reads of a run of ``scenario``: its loops (sampling period, set point
    and where the controller reads it), its plants' states and its end."""
    return RunShape(
        loops={
            n: RunLoop(tau_s=lp.tau_s, setpoint=lp.setpoint, setpoint_key=scenario.setpoint_key(n))
            for n, lp in scenario.loops.items()
        },
        plant_states={
            n: tuple(cfg.build().state_names) for n, cfg in sorted(scenario.plants().items())
        },
        end_time=scenario.end_time,
    )


def monitor_spec(scenario: ScenarioSchema, name: str) -> MonitorSpec:
    """Monitor node ``name``: its configuration and the window of the columns it assesses."""
    cfg = scenario.node(name, MonitorNodeConfig)
    run = run_shape(scenario)
    try:
        cfg.check(run, name)
    except ValueError as err:
        raise ConfigError(str(err)) from err
    series = RunSeries(run, cfg.loop, cfg.columns(), start=to_ticks(cfg.start), window=cfg.window)
    return MonitorSpec(cfg, series, end=to_ticks(scenario.end_time), time_unit=scenario.time_unit)


def operator_spec(scenario: ScenarioSchema, name: str) -> OperatorSpec:
    """The operator: the scenario's set-point, mode and disturbance schedules, in ticks."""
    return OperatorSpec(
        setpoints=tuple(
            SetpointAt(
                to_ticks(c.t),
                c.loop,
                c.value,
                to_ticks(c.announce) if c.announce else 0,
                c.safe_ramp,
            )
            for c in scenario.setpoints
        ),
        modes=tuple(ModeAt(to_ticks(m.t), m.mode) for m in scenario.modes),
        disturbances=tuple(
            DisturbanceAt(to_ticks(d.t), d.plant, d.input, d.value) for d in scenario.disturbances
        ),
        drifts=tuple(
            DriftAt(
                to_ticks(d.t),
                d.plant,
                Drift(param=d.param, value=d.value, over=to_ticks(d.over), steps=d.steps),
            )
            for d in scenario.drifts
        ),
    )


def agent_config(scenario: ScenarioSchema, name: str | None = None) -> WncscaConfig:
    """The configuration of agent node ``name`` (default: the scenario's agent), or the
    defaults if the scenario has none (what ``wncs analyze`` judges a scenario without an agent
    with)."""
    name = name or scenario.agent_node()
    return scenario.nodes_of(WncscaConfig)[name] if name else WncscaConfig()


def _test(
    scenario: ScenarioSchema, config: WncscaConfig, names: tuple[str, ...]
) -> tuple[tuple[Step, ...], float]:
    """The steps and the end of the agent's set-point test of its judged loops ``names``
    (``ValueError`` for a step of an unknown loop or after the end, or a loop without one)."""
    if config.test is not None:
        steps = tuple(Step(s.t, s.loop, s.value) for s in config.test.setpoints)
        end_time = config.test.end_time
    else:
        steps = tuple(Step(s.t, s.loop, s.value, s.announce) for s in scenario.setpoints)
        end_time = scenario.end_time
    for i, step in enumerate(steps):
        if step.loop not in names:
            raise ValueError(
                f"test.setpoints[{i}].loop: unknown loop {step.loop!r} (loops: {list(names)})"
            )
        if step.t > end_time:
            raise ValueError(f"test.setpoints[{i}].t: {step.t} is after end_time {end_time}")
    missing = [n for n in names if n not in {s.loop for s in steps}]
    if missing:
        raise ValueError(
            f"test.setpoints: no set-point step for loop(s) {missing}; the agent judges a "
            "loop by the overshoot of its step"
        )
    return steps, end_time


def closed_loop_spec(scenario: ScenarioSchema, config: WncscaConfig) -> ClosedLoopSpec:
    """The agent's closed-loop model of ``scenario`` under ``config``'s test (default: the
    scenario's set-point schedule and end): its judged loops
    (:meth:`~scenario.schema.ScenarioSchema.simulated_loops`), their plants and laws.

    Raises
    ------
    ValueError
        A test step names an unknown loop or falls after the test's end, or a judged loop has
        no step (the agent judges a loop by the overshoot of its step).
    """
    scenario = scenario.believed(config)  # the agent's own model of the plants
    names = scenario.simulated_loops()
    steps, end_time = _test(scenario, config, names)
    loops: dict[str, JudgedLoop] = {}
    for n in names:
        lp = scenario.loops[n]
        law = scenario.controllers()[lp.controller].law
        if lp.sensor is None or lp.actuator is None or lp.tau_s is None or lp.setpoint is None:
            raise ValueError(f"loops.{n}: a judged loop measures and moves its plant")
        loops[n] = JudgedLoop(
            name=n,
            plant=lp.plant,
            sensor=lp.sensor,
            actuator=lp.actuator,
            controller=lp.controller,
            law=law,
            setpoint=float(lp.setpoint),
            tau_s=float(lp.tau_s),
            feedforward=scenario.feedforward(n) if uses_feedforward(law) else None,
        )
    controllers = {lp.controller for lp in loops.values()}
    plants = {}
    for p in sorted({lp.plant for lp in loops.values()}):
        cfg = scenario.plants()[p]
        plants[p] = JudgedPlant(
            name=p,
            model=cfg.build(),
            x0=dict(cfg.x0),
            u0=dict(cfg.u0),
            max_step=cfg.max_step,
            monitor_period=cfg.monitor_period,
            noise=dict(cfg.noise),
            params=dict(cfg.params),
            kind=cfg.model,
            uncertainty=dict(config.model[p].uncertainty) if p in config.model else {},
        )
    what = {  # everything a trial's outcome depends on but its periods and delays
        "plants": {p: scenario.plant(p).model_dump() for p in plants},
        "controllers": {c: scenario.controller(c).model_dump() for c in sorted(controllers)},
        "loops": {n: scenario.loops[n].model_dump() for n in names},
        "steps": [dataclasses.asdict(s) for s in steps],
        "end_time": end_time,
        "seed": scenario.seed,
    }
    if config.model:  # the believed parameters are in "plants"; their uncertainty here
        what["model"] = {p: config.model[p].model_dump() for p in sorted(config.model)}
    return ClosedLoopSpec(
        name=f"{scenario.name}.wncsca_model",
        time_unit=scenario.time_unit,
        seed=scenario.seed,
        end_time=end_time,
        plants=plants,
        loops=loops,
        steps=steps,
        fingerprint=hashlib.sha256(
            json.dumps(what, sort_keys=True, default=str).encode()
        ).hexdigest()[:16],
    )


def agent_spec(
    scenario: ScenarioSchema, name: str | None = None, config: WncscaConfig | None = None
) -> AgentSpec:
    """What agent node ``name`` of ``scenario`` knows of its run (``name`` ``None``: the
    scenario's agent, or one with the default configuration; ``config`` replaces the node's)."""
    config = config or agent_config(scenario, name)
    groups: tuple[LinkGroup, ...] = ()
    if config.links:
        groups = tuple(
            link_groups(
                scenario.links,
                scenario.multi_loop_law,
                config.links.analysis,
                tau_s=scenario.multi_loop_tau_s,
            )
        )
    return AgentSpec(
        config=config,
        closed_loop=closed_loop_spec(scenario, config),
        seed=scenario.seed,
        carriers={n: carrier_spec(scenario, n) for n in scenario.carriers()},
        loop_networks={n: lp.network for n, lp in scenario.loops.items()},
        setpoints={
            n: float(lp.setpoint) for n, lp in scenario.loops.items() if lp.setpoint is not None
        },
        links={
            n: LinkSpec(network=lk.network, period=lk.period, delay=lk.delay)
            for n, lk in scenario.links.items()
        },
        link_groups=groups,
        loop_delays={n: lp.tau_d + lp.tau_a for n, lp in scenario.loops.items()},
    )


class ScenarioSimulator:
    """The agent's :class:`~agents.wncsca.spec.Simulator` for a scenario: each trial of the
    closed-loop spec written as a scenario (validated once, then only the trial's fields
    replaced: :meth:`~scenario.schema.ScenarioSchema.trial`) and run by ``simulate``."""

    def __init__(self, scenario: ScenarioSchema, spec: ClosedLoopSpec, simulate: Simulate) -> None:
        self.model = scenario.agent_model(spec)
        self._simulate = simulate

    def __call__(self, trial: Trial) -> RunRecord:
        return self._simulate(self.model.trial(trial))


def loop_model(
    scenario: ScenarioSchema, config: WncscaConfig | None = None, *, simulate: Simulate
) -> LoopModel:
    """The agent's model of ``scenario`` (``config`` defaults to its agent's), its trials run
    by ``simulate``."""
    config = config or agent_config(scenario)
    return _loop_model(scenario, closed_loop_spec(scenario, config), config, simulate)


def _loop_model(
    scenario: ScenarioSchema, spec: ClosedLoopSpec, config: WncscaConfig, simulate: Simulate
) -> LoopModel:
    """The agent's model of ``spec``, its trials run by ``simulate`` on ``scenario``'s model."""
    return LoopModel(Trials(spec, ScenarioSimulator(scenario, spec, simulate)), config)


def coordinator(
    scenario: ScenarioSchema,
    config: WncscaConfig | None = None,
    *,
    simulate: Simulate,
    name: str | None = None,
) -> Coordinator:
    """The coordination agent of ``scenario`` (its node ``name``, default the scenario's agent),
    its model's trials run by ``simulate``."""
    spec = agent_spec(scenario, name, config)
    return Coordinator(spec, _loop_model(scenario, spec.closed_loop, spec.config, simulate))


def agent_behaviour(name: str, scenario: ScenarioSchema, simulate: Simulate) -> WncscaBehaviour:
    """The agent kind's build (:data:`scenario.kinds.NODE_KINDS`): agent node ``name`` of
    ``scenario``, its model's trials run by ``simulate``."""
    return WncscaBehaviour(name, coordinator(scenario, simulate=simulate, name=name))
