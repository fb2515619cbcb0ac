"""The ``direct`` engine: the scenario's sampled-data loops simulated without a bus.

It calls the same cores (plant model, RK4 integrator, PI law, feedforward) in the same order as
the bus nodes do in their rounds (DESIGN section 3), so it produces the same traces as the
``processes`` and ``threads`` engines, bit for bit, while being fast enough for the coordination
agent to call it thousands of times. At each instant ``t`` (integer ticks):

1. each plant with something due at ``t`` (a sensor sample, a monitoring instant, an arriving
   command) integrates from its last stop to ``t`` (plant node: timers / actuator handler);
   network reconfigurations and end-of-run statistics due at ``t`` are applied (the gateway's
   timers fire in the first round at ``t``, before any packet of that instant);
2. monitoring record and sensor samples at ``t``; samples enter their loop's sensor path, whose
   delivery time (or loss) comes from the same :class:`~gateway.carrier.PathCarrier` the
   network node uses (constant ``tau_d``, or drawn over a WSN);
3. set-point changes due at ``t`` update set points and feedforwards (operator -> controllers);
4. samples delivered at ``t`` are handed to their controllers, which compute moves with the set
   points of ``t`` (controller node, after its messages); moves enter the actuator path;
5. commands arriving at ``t`` are applied from ``t`` on (zero-order hold).

A plant integrates only to instants it has something to do at, so its trajectory does not depend
on other nodes' timers.
"""

from __future__ import annotations

import heapq
import itertools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.registry import build_law, uses_feedforward
from gateway.carrier import ACTUATOR, SENSOR, PathCarrier, path_hops
from plants.integrate import integrator_of
from runtime.record import LoopRecord, PlantRecord, RunRecord
from runtime.scenario import Scenario
from runtime.time import to_ticks, to_units

__all__ = ["simulate"]


@dataclass
class _Plant:
    name: str
    model: Any
    x: np.ndarray
    u: np.ndarray
    t: int
    monitor: int
    next_monitor: int
    max_step: float
    record: PlantRecord
    step: Any

    def integrate_to(self, t: int) -> None:
        if t > self.t:
            self.x = self.step(
                to_units(self.t), self.x, to_units(t), self.u, max_step=self.max_step
            )
            self.t = t


@dataclass
class _Loop:
    name: str
    plant: _Plant
    y_index: int
    u_index: int
    tau_s: int
    carrier: Any  # gateway.carrier.PathCarrier of the loop's network node
    law: Any
    feedforward: Any  # SteadyStateFeedforward or None
    next_sample: int
    deliveries: list  # heap of (t_deliver, order, y, t_sampled)
    commands: list  # heap of (t_arrive, order, u)
    record: LoopRecord
    noise: float
    rng: Any


def simulate(scenario: Scenario) -> RunRecord:
    """Simulate ``scenario`` directly and return its record.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario; use :meth:`Scenario.with_loops` to vary ``tau_s`` / ``tau_d``.
    """
    if scenario.agent_node() is not None:
        raise ValueError(
            f"scenario {scenario.name!r}: the direct engine has no coordination agent "
            f"(node {scenario.agent_node()!r}); run it on the bus"
        )
    wall0 = time.perf_counter()
    end = to_ticks(scenario.end_time)
    plants: dict[str, _Plant] = {}
    for name, cfg in sorted(scenario.nodes.items()):
        if cfg.kind != "plant":
            continue
        model = cfg.build()
        monitor = to_ticks(cfg.monitor_period)
        plants[name] = _Plant(
            name=name,
            model=model,
            x=np.array([cfg.x0[s] for s in model.state_names], dtype=float),
            u=np.array([cfg.u0[s] for s in model.input_names], dtype=float),
            t=0,
            monitor=monitor,
            next_monitor=0,
            max_step=cfg.max_step,
            record=PlantRecord(tuple(model.state_names)),
            step=integrator_of(model),
        )

    carriers = {
        name: PathCarrier(scenario, name)
        for name, cfg in sorted(scenario.nodes.items())
        if cfg.kind in ("network", "gateway")
    }
    order = itertools.count()  # FIFO among packets due at the same instant, as the node's timers
    configurations: list[dict[str, Any]] = []
    net_nodes: dict[str, Any] = {}
    net_events = []  # (t, network node, index, event or None for the initial announcement)
    for cname, carrier in carriers.items():
        if carrier.topology is not None:
            net_events.append((0, cname, -1, None))
            net_events += [(t_ev, cname, i, ev) for t_ev, i, ev in carrier.events]
            # the gateway's energy at the end, before the packets of the last instant (its timer)
            net_events.append((end, cname, 10**9, "stats"))
    net_events.sort(key=lambda e: (e[0], e[1], e[2]))
    setpoints = {name: lp.setpoint for name, lp in scenario.loops.items()}
    loops: dict[str, _Loop] = {}
    for name, lp in sorted(scenario.loops.items()):
        plant = plants[lp.plant]
        law_cfg = scenario.nodes[lp.controller].law
        ff = scenario.feedforward(name) if uses_feedforward(law_cfg) else None
        u_bar = ff.u_bar(scenario.plant_setpoints(lp.plant, setpoints)) if ff else 0.0
        loops[name] = _Loop(
            name=name,
            plant=plant,
            y_index=plant.model.output_names.index(lp.sensor),
            u_index=plant.model.input_names.index(lp.actuator),
            tau_s=to_ticks(lp.tau_s),
            carrier=carriers[lp.network],
            law=build_law(law_cfg, u_bar=u_bar, plant=plant.model, tau_s=lp.tau_s),
            feedforward=ff,
            next_sample=0,
            deliveries=[],
            commands=[],
            record=LoopRecord(
                plant=lp.plant,
                sensor=lp.sensor,
                setpoints=[(0, lp.setpoint)],
                settling_band=lp.settling_band,
            ),
            noise=scenario.nodes[lp.plant].noise.get(lp.sensor, 0.0),
            rng=scenario.sensor_rng(lp.plant, lp.sensor),
        )
    schedule = sorted(
        ((to_ticks(c.t), i, c.loop, c.value) for i, c in enumerate(scenario.setpoints))
    )
    heapq.heapify(schedule)
    disturbances = sorted(
        (to_ticks(d.t), i, d.plant, plants[d.plant].model.input_names.index(d.input), d.value)
        for i, d in enumerate(scenario.disturbances)
    )
    heapq.heapify(disturbances)

    def next_time() -> int | None:
        cands = [p.next_monitor for p in plants.values()]
        for lp in loops.values():
            cands.append(lp.next_sample)
            if lp.deliveries:
                cands.append(lp.deliveries[0][0])
            if lp.commands:
                cands.append(lp.commands[0][0])
        if schedule:
            cands.append(schedule[0][0])
        if disturbances:
            cands.append(disturbances[0][0])
        if net_events:
            cands.append(net_events[0][0])
        return min(cands) if cands else None

    t = next_time()
    while t is not None and t <= end:
        tu = to_units(t)
        # 1. plants integrate to t if anything is due for them at t
        for p in plants.values():
            due = p.next_monitor == t
            due = due or any(d[0] == t and d[2] == p.name for d in disturbances)
            due = due or any(
                lp.plant is p and (lp.next_sample == t or (lp.commands and lp.commands[0][0] == t))
                for lp in loops.values()
            )
            if due:
                p.integrate_to(t)
        # 1b. network reconfigurations due at t (the gateway's timers: before any packet at t)
        while net_events and net_events[0][0] == t:
            _, cname, _, event = net_events.pop(0)
            carrier = carriers[cname]
            if event == "stats":
                net_nodes.update(carrier.energy(t))
                continue
            paths = carrier.configuration(t) if event is None else carrier.apply(event, t)
            configurations.append(
                {
                    "t": t,
                    "event": "initial" if event is None else event.type,
                    "source": "initial" if event is None else "scenario",
                    "paths": paths,
                    "proposal": None,  # no agent: applied at once, as the gateway node does
                    "periods": {},
                }
            )
        # 2. monitoring record and sensor samples
        for p in plants.values():
            if p.next_monitor == t:
                p.record.t.append(t)
                p.record.x.append(p.x.tolist())
                p.next_monitor += p.monitor
        for lp in loops.values():
            if lp.next_sample == t:
                y = float(lp.plant.model.outputs(lp.plant.x)[lp.y_index])
                if lp.noise > 0.0:
                    y += lp.noise * float(lp.rng.standard_normal())
                lp.record.sent += 1
                t_deliver = lp.carrier.deliver(lp.name, SENSOR, t)
                if t_deliver is None:
                    lp.record.lost += 1
                else:
                    heapq.heappush(lp.deliveries, (t_deliver, next(order), y, t))
                lp.next_sample += lp.tau_s
        # 3. set-point changes
        changed_plants = set()
        while schedule and schedule[0][0] == t:
            _, _, loop_name, value = heapq.heappop(schedule)
            setpoints[loop_name] = value
            loops[loop_name].record.setpoints.append((t, value))
            changed_plants.add(scenario.loops[loop_name].plant)
        for lp in loops.values():
            if lp.feedforward is not None and lp.plant.name in changed_plants:
                sp = scenario.plant_setpoints(lp.plant.name, setpoints)
                lp.law.set_feedforward(lp.feedforward.u_bar(sp))
        # 4. deliveries -> control moves
        for lp in loops.values():
            while lp.deliveries and lp.deliveries[0][0] == t:
                _, _, y, t_sampled = heapq.heappop(lp.deliveries)
                u = lp.law.step(tu, y, setpoints[lp.name])
                rec = lp.record
                rec.t.append(t)
                rec.y.append(y)
                rec.u.append(u)
                rec.t_sampled.append(t_sampled)
                t_arrive = lp.carrier.deliver(lp.name, ACTUATOR, t)
                if t_arrive is None:
                    lp.record.lost_moves += 1
                else:
                    heapq.heappush(lp.commands, (t_arrive, next(order), u))
        # 5. commands and disturbances arriving at t are applied from t on
        while disturbances and disturbances[0][0] == t:
            _, _, plant_name, index, value = heapq.heappop(disturbances)
            plants[plant_name].u[index] = value
        for lp in loops.values():
            while lp.commands and lp.commands[0][0] == t:
                lp.plant.integrate_to(t)
                lp.plant.u[lp.u_index] = heapq.heappop(lp.commands)[2]
        t = next_time()

    rec = RunRecord(
        scenario=scenario.name,
        seed=scenario.seed,
        engine="direct",
        end_time=end,
        time_unit=scenario.time_unit,
        loops={n: lp.record for n, lp in loops.items()},
        plants={n: p.record for n, p in plants.items()},
        disturbances=scenario.disturbance_times(),
        hops=path_hops(scenario),
        configurations=configurations,
        net_nodes=net_nodes,
    )
    rec.wall_s = time.perf_counter() - wall0
    rec.phases = {"run": rec.wall_s}
    return rec
