"""Each node's typed spec, computed once from its scenario (the scenario layer, DESIGN section 2).

A behaviour takes what it needs as a frozen spec (:class:`~plants.behaviour.PlantSpec`,
:class:`~controllers.behaviour.ControllerSpec`, :class:`~gateway.behaviour.NetworkSpec`,
:class:`~agents.operator.behaviour.OperatorSpec`, :class:`~agents.monitor.behaviour.MonitorSpec`)
instead of the whole :class:`~runtime.scenario.Scenario`, so it neither re-derives the scenario's
view nor depends on its shape. The node kinds' builds (:data:`runtime.scenario.NODE_KINDS`) pass
a node's spec to its behaviour. Not cut yet: two cores still read the scenario they are given
(duck-typed, never imported) when they are built into a node's spec: the monitor's
``agents.monitor.run_data.RunSeries`` and the agent's ``agents.wncsca.coordinator.Coordinator``
(built by the agent kind's own build). A network's paths take a
:class:`~gateway.carrier.CarrierSpec`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from agents.monitor.behaviour import MonitorSpec
from agents.monitor.run_data import RunSeries
from agents.operator.behaviour import DisturbanceAt, ModeAt, OperatorSpec, SetpointAt
from controllers.behaviour import ControllerSpec
from controllers.registry import uses_feedforward
from core.errors import ConfigError
from core.time import to_ticks
from gateway.behaviour import NetworkSpec
from gateway.carrier import CarrierSpec, PathCarrier
from plants.behaviour import PlantSpec

if TYPE_CHECKING:
    from runtime.scenario import Scenario

__all__ = [
    "carrier_spec",
    "path_hops",
    "plant_spec",
    "controller_spec",
    "network_spec",
    "monitor_spec",
    "operator_spec",
]


def plant_spec(scenario: Scenario, name: str) -> PlantSpec:
    """Plant node ``name``: its model, initial state and inputs, sensors and their generators."""
    cfg = scenario.nodes[name]
    model = cfg.build()
    sensors = {
        lp.sensor: to_ticks(lp.tau_s)
        for lp in scenario.loops_of_plant(name).values()
        if lp.sensor is not None  # an actuator-only loop: nothing to sample
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
    )


def controller_spec(scenario: Scenario, name: str) -> ControllerSpec:
    """Controller node ``name``: its loops, law, plant model, set points and links."""
    cfg = scenario.nodes[name]
    loops = cfg.loop_names
    first = scenario.loops[loops[0]]
    plants = sorted({scenario.loops[n].plant for n in loops})
    setpoints = {n: lp.setpoint for p in plants for n, lp in scenario.loops_of_plant(p).items()}
    common: dict[str, Any] = {
        "loops": loops,
        "multi": cfg.loops is not None,
        "law": cfg.law,
        "plant": scenario.nodes[first.plant].build(),
        "setpoints": setpoints,
        "setpoint_keys": {n: scenario.setpoint_key(n) for n in setpoints},
        "governed": scenario.agent_node() is not None,
        "end": to_ticks(scenario.end_time),
    }
    if cfg.loops is None:
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


def carrier_spec(scenario: Scenario, name: str) -> CarrierSpec:
    """What network node ``name``'s paths are made of: the loops and links it carries."""
    return CarrierSpec(
        node=name,
        seed=scenario.seed,
        loops={n: lp for n, lp in sorted(scenario.loops.items()) if lp.network == name},
        links={n: lk for n, lk in sorted(scenario.links.items()) if lk.network == name},
        gateway=scenario.nodes[name] if scenario.is_wireless(name) else None,
        traces={} if scenario.is_wireless(name) else dict(scenario.nodes[name].traces),
    )


def path_hops(scenario: Scenario) -> dict[str, int]:
    """Loop -> hops of its sensor path (0 wired, -1 down), for every loop of the scenario."""
    out: dict[str, int] = {}
    for name in scenario.carriers():
        carrier = PathCarrier(carrier_spec(scenario, name))
        out.update({loop: carrier.hops(loop) for loop in carrier.loops})
    return out


def network_spec(scenario: Scenario, name: str) -> NetworkSpec:
    """Network or gateway node ``name``: the paths it carries, and its timing."""
    stats_period = getattr(scenario.nodes[name], "stats_period", None)  # a gateway's
    return NetworkSpec(
        carrier=PathCarrier(carrier_spec(scenario, name)),
        governed=scenario.agent_node() is not None,
        end=to_ticks(scenario.end_time),
        stats_period=None if stats_period is None else to_ticks(stats_period),
    )


def monitor_spec(scenario: Scenario, name: str) -> MonitorSpec:
    """Monitor node ``name``: its configuration and the window of the columns it assesses."""
    cfg = scenario.nodes[name]
    try:
        cfg.check(scenario, name)
    except ValueError as err:
        raise ConfigError(str(err)) from err
    series = RunSeries(
        scenario, cfg.loop, cfg.columns(), start=to_ticks(cfg.start), window=cfg.window
    )
    return MonitorSpec(cfg, series, end=to_ticks(scenario.end_time), time_unit=scenario.time_unit)


def operator_spec(scenario: Scenario, name: str) -> OperatorSpec:
    """The operator: the scenario's set-point, mode and disturbance schedules, in ticks."""
    return OperatorSpec(
        setpoints=tuple(
            SetpointAt(to_ticks(c.t), c.loop, c.value, to_ticks(c.announce) if c.announce else 0)
            for c in scenario.setpoints
        ),
        modes=tuple(ModeAt(to_ticks(m.t), m.mode) for m in scenario.modes),
        disturbances=tuple(
            DisturbanceAt(to_ticks(d.t), d.plant, d.input, d.value) for d in scenario.disturbances
        ),
    )
