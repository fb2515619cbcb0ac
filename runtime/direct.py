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
   points of ``t`` (controller node, after its messages); moves enter the actuator path. A
   single-loop controller makes one move per sample. A multi-loop controller
   (:mod:`controllers.node`) takes its loops' samples in by round, as its node does: first those
   delivered over a delayed path (they arrive in the instant's first round), then those over a
   zero-delay path (one round later), each batch in key order, and executes once per non-empty
   batch (once every loop has delivered), making a move for every loop. Each delivered sample is
   recorded with the ``k``-th move of its loop made at its instant if it is the ``k``-th sample
   of its loop delivered then (``None`` if there is none), which is how
   :func:`runtime.history.load_record` pairs them from a bus run's history;
5. commands arriving at ``t`` are applied from ``t`` on (zero-order hold).

Actuator-only loops (``sensor: null``) are never sampled; their moves are recorded one per
execution (``t``, ``y = None``, ``u``). **Links** (``links:``): in step 2, before the samples,
every link due at ``t`` gets its sender's ``law.transmit(t)`` (the node's timer, in the first
round at ``t``) and the vector enters the link's path (:class:`~gateway.carrier.PathCarrier`,
direction ``link``). In step 4 a multi-loop controller's batches hold link receipts as well as
samples (delayed ones with the first batch, zero-delay ones with the second, as their messages
arrive in the node's rounds): each batch hands its receipts to ``law.receive`` in key order, then
takes its samples in and executes (the node dispatches ``link/<k>/rx`` as it arrives and executes
after dispatch).

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

from bus_schemas import keys
from controllers.registry import build_law, build_multi_loop_law, uses_feedforward
from gateway.carrier import ACTUATOR, LINK, SENSOR, PathCarrier, path_hops
from plants.integrate import integrator_of
from runtime.record import LinkRecord, LoopRecord, PlantRecord, RunRecord
from runtime.scenario import Scenario
from runtime.time import to_ticks, to_units

__all__ = ["simulate", "Execution", "multi_loop_executions"]


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
    y_index: int | None  # None: an actuator-only loop (never sampled)
    u_index: int | None  # None: a measurement-only loop (never moved)
    tau_s: int
    carrier: Any  # gateway.carrier.PathCarrier of the loop's network node
    law: Any
    feedforward: Any  # SteadyStateFeedforward or None
    next_sample: int | None
    deliveries: list  # heap of (t_deliver, order, y, t_sampled)
    commands: list  # heap of (t_arrive, order, u)
    record: LoopRecord
    noise: float
    rng: Any
    multi: Any = None  # the _MultiController it belongs to, or None (single-loop controller)


@dataclass
class _MultiController:
    name: str
    loops: list[_Loop]  # in the order of the node's loops:
    law: Any
    held: dict[str, tuple[int, float]]  # loop -> (t_sampled, value), as the node holds them
    measured: list[_Loop]  # the loops with a sensor
    links_in: list[_Link]  # links it receives, by name


@dataclass
class _Link:
    name: str
    sender: _MultiController
    carrier: Any  # gateway.carrier.PathCarrier of the link's network node
    period: int
    next_send: int
    deliveries: list  # heap of (t_deliver, order, values, t_sent)
    record: LinkRecord


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
        ctrl_cfg = scenario.nodes[lp.controller]
        law_cfg = ctrl_cfg.law
        ff = scenario.feedforward(name) if uses_feedforward(law_cfg) else None
        u_bar = ff.u_bar(scenario.plant_setpoints(lp.plant, setpoints)) if ff else 0.0
        sensed = lp.sensor is not None
        loops[name] = _Loop(
            name=name,
            plant=plant,
            y_index=plant.model.output_names.index(lp.sensor) if sensed else None,
            u_index=(
                plant.model.input_names.index(lp.actuator) if lp.actuator is not None else None
            ),
            tau_s=to_ticks(lp.tau_s) if lp.tau_s is not None else 0,
            carrier=carriers[lp.network],
            law=(
                build_law(law_cfg, u_bar=u_bar, plant=plant.model, tau_s=lp.tau_s)
                if ctrl_cfg.loops is None
                else None  # a multi-loop controller's law is built once, below
            ),
            feedforward=ff,
            next_sample=0 if sensed else None,
            deliveries=[],
            commands=[],
            record=LoopRecord(
                plant=lp.plant,
                sensor=lp.sensor,
                setpoints=[(0, lp.setpoint)],
                settling_band=lp.settling_band,
            ),
            noise=scenario.nodes[lp.plant].noise.get(lp.sensor, 0.0) if sensed else 0.0,
            rng=scenario.sensor_rng(lp.plant, lp.sensor) if sensed else None,
        )
    multis: dict[str, _MultiController] = {}
    for cname, cfg in sorted(scenario.nodes.items()):
        if cfg.kind != "controller" or cfg.loops is None:
            continue
        members = [loops[n] for n in cfg.loops]
        law = build_multi_loop_law(
            cfg.law,
            loops=cfg.loops,
            plant=members[0].plant.model,
            tau_s=scenario.multi_loop_tau_s(cname),
            context=scenario.multi_loop_context(cname),
        )
        mc = _MultiController(
            name=cname,
            loops=members,
            law=law,
            held={},
            measured=[m for m in members if m.y_index is not None],
            links_in=[],
        )
        for member in members:
            member.multi = mc
        multis[cname] = mc
    links: dict[str, _Link] = {}
    for lname, lk in sorted(scenario.links.items()):
        links[lname] = _Link(
            name=lname,
            sender=multis[lk.from_],
            carrier=carriers[lk.network],
            period=to_ticks(lk.period),
            next_send=0,
            deliveries=[],
            record=LinkRecord(),
        )
        multis[lk.to].links_in.append(links[lname])
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
        for lk in links.values():
            if lk.next_send <= end:
                cands.append(lk.next_send)
            if lk.deliveries:
                cands.append(lk.deliveries[0][0])
        for lp in loops.values():
            if lp.next_sample is not None:
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
        # 2. link transmissions (the controllers' timers), monitoring record and sensor samples
        for lk in links.values():
            if lk.next_send == t:
                values = [float(v) for v in lk.sender.law.transmit(tu)]
                lk.record.sent += 1
                t_deliver = lk.carrier.deliver(lk.name, LINK, t)
                if t_deliver is None:
                    lk.record.lost += 1
                else:
                    heapq.heappush(lk.deliveries, (t_deliver, next(order), values, t))
                lk.next_send += lk.period
        for p in plants.values():
            if p.next_monitor == t:
                p.record.t.append(t)
                p.record.x.append(p.x.tolist())
                p.next_monitor += p.monitor
        for lp in loops.values():
            if lp.next_sample == t and lp.y_index is not None:
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
            if lp.multi is not None:
                continue
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
        for mc in multis.values():
            _execute_multi(mc, t, setpoints, order)
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
        links={n: lk.record for n, lk in links.items()},
        plants={n: p.record for n, p in plants.items()},
        disturbances=scenario.disturbance_times(),
        hops=path_hops(scenario),
        configurations=configurations,
        net_nodes=net_nodes,
    )
    rec.wall_s = time.perf_counter() - wall0
    rec.phases = {"run": rec.wall_s}
    return rec


def _execute_multi(mc: _MultiController, t: int, setpoints: dict[str, float], order: Any) -> None:
    """Step 4 for a multi-loop controller at ``t``: its node's rounds at ``t``, batch by batch."""
    delayed: list[tuple[_Loop, float, int]] = []
    immediate: list[tuple[_Loop, float, int]] = []
    for lp in mc.measured:
        while lp.deliveries and lp.deliveries[0][0] == t:
            _, _, y, t_sampled = heapq.heappop(lp.deliveries)
            (immediate if t_sampled == t else delayed).append((lp, y, t_sampled))
    rx_delayed: list[tuple[_Link, list[float]]] = []
    rx_immediate: list[tuple[_Link, list[float]]] = []
    for lk in mc.links_in:  # by link name: the node's key order
        while lk.deliveries and lk.deliveries[0][0] == t:
            _, _, values, t_sent = heapq.heappop(lk.deliveries)
            lk.record.t_sent.append(t_sent)
            lk.record.t.append(t)
            (rx_immediate if t_sent == t else rx_delayed).append((lk, values))
    if not delayed and not immediate and not rx_delayed and not rx_immediate:
        return
    first = {lp.name: len(lp.record.t) for lp in mc.measured}
    moves: dict[str, list[float]] = {lp.name: [] for lp in mc.loops}
    tu = to_units(t)
    for batch, receipts in ((delayed, rx_delayed), (immediate, rx_immediate)):
        for lk, values in receipts:
            mc.law.receive(tu, lk.name, values)
        if not batch:
            continue
        batch.sort(key=lambda s: keys.meas(s[0].name))  # the node's (key, src, seq) order
        for lp, y, t_sampled in batch:
            rec = lp.record
            rec.t.append(t)
            rec.y.append(y)
            rec.u.append(None)
            rec.t_sampled.append(t_sampled)
            held = mc.held.get(lp.name)
            if held is None or t_sampled >= held[0]:
                mc.held[lp.name] = (t_sampled, y)
        if len(mc.held) < len(mc.measured):
            continue  # some loop has not delivered yet: no move
        u = mc.law.step(
            tu,
            {lp.name: mc.held[lp.name][1] for lp in mc.measured},
            {lp.name: setpoints[lp.name] for lp in mc.loops},
        )
        for lp in mc.loops:
            if lp.u_index is None:
                continue  # a measurement-only loop: no move, its samples are recorded with none
            moves[lp.name].append(u[lp.name])
            if lp.y_index is None:  # an actuator-only loop: one record entry per move
                rec = lp.record
                rec.t.append(t)
                rec.y.append(None)
                rec.u.append(u[lp.name])
                rec.t_sampled.append(t)
            t_arrive = lp.carrier.deliver(lp.name, ACTUATOR, t)
            if t_arrive is None:
                lp.record.lost_moves += 1
            else:
                heapq.heappush(lp.commands, (t_arrive, next(order), u[lp.name]))
    for lp in mc.measured:  # the k-th sample of a loop at t goes with its k-th move at t
        made = moves[lp.name]
        for k, i in enumerate(range(first[lp.name], len(lp.record.t))):
            lp.record.u[i] = made[k] if k < len(made) else None


@dataclass(frozen=True)
class Execution:
    """One execution of a multi-loop controller: its time (ticks), the held measurement and the
    set point of each of its loops."""

    t: int
    y: dict[str, float]
    r: dict[str, float]


def multi_loop_executions(scenario: Scenario, rec: RunRecord, controller: str) -> list[Execution]:
    """The executions of multi-loop controller ``controller`` in a run, rebuilt from its record.

    The record of any engine holds every delivered sample (delivery time, value, sampling time)
    and every set-point change; the node's rule (:mod:`controllers.node`, step 4 above) gives when
    it executed and with what. Feeding them to a fresh law reproduces the run's moves, and the
    law's internal signals with them (for the MRAC: the reference model's ``x_m``, the error
    ``e``, ``theta``), which are not on the bus.

    Raises
    ------
    ValueError
        If ``controller`` is not a multi-loop controller of ``scenario``.
    """
    cfg = scenario.nodes.get(controller)
    if cfg is None or cfg.kind != "controller" or cfg.loops is None:
        raise ValueError(f"{controller!r} is not a multi-loop controller of {scenario.name!r}")
    names = [n for n in cfg.loops if scenario.loops[n].sensor is not None]
    # (t, batch: 0 delayed / 1 zero-delay, key, position) -> sample
    arrivals = []
    for name in names:
        lr = rec.loops[name]
        for i, (t, y, ts) in enumerate(zip(lr.t, lr.y, lr.t_sampled, strict=True)):
            arrivals.append((t, int(ts == t), keys.meas(name), i, name, y, ts))
    arrivals.sort(key=lambda a: a[:4])
    changes = {n: rec.loops[n].setpoints for n in cfg.loops}
    held: dict[str, tuple[int, float]] = {}
    out: list[Execution] = []
    for (t, _), group in itertools.groupby(arrivals, key=lambda a: a[:2]):
        for *_, name, y, ts in group:
            if name not in held or ts >= held[name][0]:
                held[name] = (ts, y)
        if len(held) == len(names):
            r = {n: [v for tc, v in changes[n] if tc <= t][-1] for n in cfg.loops}
            out.append(Execution(t=t, y={n: held[n][1] for n in names}, r=r))
    return out
