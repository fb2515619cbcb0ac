"""The checks across a scenario's fields (what no single field can say), one function per concern.

:func:`check_graph` runs them in a fixed order when a :class:`~scenario.model.Scenario` is
validated; each raises ``ValueError`` with the dotted path of what is wrong
(``loops.level.controller: node 'pi1' controls loop 'temperature'``), which
:func:`scenario.load.parse_scenario` turns into a :class:`~core.errors.ConfigError` naming the
file and the line. A check reads the scenario only through its fields and its derived views
(:class:`~scenario.schema.ScenarioSchema`).
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from pydantic import BaseModel

from agents.monitor.config import MonitorNodeConfig
from agents.wncsca.config import MODES, WncscaConfig
from agents.wncsca.laws import MODELLED_LAWS, modelled_law, unmodelled_law
from agents.wncsca.links import link_groups
from controllers.registry import (
    accepts_actuator_only_loops,
    accepts_measurement_only_loops,
    exchanges_estimates,
    uses_feedforward,
)
from core.time import to_ticks
from plants import registry
from scenario.schema import (
    ControllerNodeConfig,
    GatewayNodeConfig,
    LoopConfig,
    NetworkNodeConfig,
    OperatorNodeConfig,
    PlantNodeConfig,
    ScenarioSchema,
)
from scenario.views import run_shape

__all__ = ["check_graph", "GRAPH_CHECKS"]

_C = TypeVar("_C", bound=BaseModel)


def _kind_of(config: type[BaseModel]) -> str:
    """The ``kind:`` a node configuration class stands for (its ``kind`` field's literal)."""
    return str(typing.get_args(config.model_fields["kind"].annotation)[0])


def _node_of(s: ScenarioSchema, config: type[_C], name: str, where: str) -> _C:
    """Node ``name``, which ``where`` names, as a node of ``config``'s kind."""
    node = s.nodes.get(name)
    if node is None:
        raise ValueError(f"{where}: unknown node {name!r} (nodes: {sorted(s.nodes)})")
    if not isinstance(node, config):
        expected = _kind_of(config)
        raise ValueError(f"{where}: node {name!r} is a {node.kind}, expected a {expected}")
    return node


def check_multi_loop_controllers_name_loops(s: ScenarioSchema) -> None:
    """A multi-loop controller's ``loops:`` are loops of the scenario."""
    for name, node in s.nodes.items():
        if not isinstance(node, ControllerNodeConfig) or node.loops is None:
            continue
        for i, lname in enumerate(node.loops):
            if lname not in s.loops:
                raise ValueError(
                    f"nodes.{name}.loops[{i}]: unknown loop {lname!r} (loops: {sorted(s.loops)})"
                )


def check_traces_name_carried_loops(s: ScenarioSchema) -> None:
    """A wired network's delay traces are of loops it carries."""
    for name, node in s.nodes.items():
        for lname in node.traces if isinstance(node, NetworkNodeConfig) else ():
            carried = s.loops.get(lname)
            if carried is None or carried.network != name:
                raise ValueError(
                    f"nodes.{name}.traces.{lname}: no loop {lname!r} is carried by {name!r}"
                )


def _loop_signals(at: str, loop: LoopConfig, plant: Any, ctrl: ControllerNodeConfig) -> None:
    """The loop's sensor is an output of its plant and its actuator an input; an actuator-only
    or measurement-only loop only where its controller's law takes one."""
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


def _loop_controller(
    at: str, lname: str, loop: LoopConfig, ctrl: ControllerNodeConfig, controlled: dict[str, str]
) -> None:
    """The loop's controller controls it, and a single-loop controller no other loop."""
    if lname not in ctrl.loop_names:
        what = f"loop {ctrl.loop!r}" if ctrl.loops is None else f"loops {list(ctrl.loops)}"
        raise ValueError(f"{at}.controller: node {loop.controller!r} controls {what}")
    if loop.controller in controlled and ctrl.loops is None:
        raise ValueError(
            f"{at}.controller: {loop.controller!r} already controls "
            f"loop {controlled[loop.controller]!r}"
        )
    controlled[loop.controller] = lname


def _loop_network(s: ScenarioSchema, at: str, loop: LoopConfig) -> None:
    """The loop's network: a gateway whose topology has its radio nodes, or a wired network."""
    net = s.nodes.get(loop.network)
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
        _node_of(s, NetworkNodeConfig, loop.network, f"{at}.network")
        if loop.sensor_node is not None or loop.actuator_node is not None:
            raise ValueError(f"{at}.sensor_node: only loops over a gateway name WSN nodes")


def check_loops(s: ScenarioSchema) -> None:
    """Every loop: its plant and signals, its controller, its network, a period of a tick at
    least (each loop's checks in that order)."""
    controlled: dict[str, str] = {}
    for lname, loop in s.loops.items():
        at = f"loops.{lname}"
        plant = _node_of(s, PlantNodeConfig, loop.plant, f"{at}.plant").build()
        ctrl = _node_of(s, ControllerNodeConfig, loop.controller, f"{at}.controller")
        _loop_signals(at, loop, plant, ctrl)
        _loop_controller(at, lname, loop, ctrl, controlled)
        _loop_network(s, at, loop)
        if loop.tau_s is not None and to_ticks(loop.tau_s) < 1:
            raise ValueError(f"{at}.tau_s: {loop.tau_s} is shorter than one tick")


def check_controllers(s: ScenarioSchema) -> None:
    """Every controller controls a loop; a multi-loop controller's loops name it, measure and
    move something, and are governed by an agent only through its links."""
    controlled = {loop.controller for loop in s.loops.values()}
    for name, node in s.nodes.items():
        if not isinstance(node, ControllerNodeConfig):
            continue
        if node.loops is None:
            if name not in controlled:
                raise ValueError(f"nodes.{name}.loop: no loop names {name!r} as its controller")
            continue
        for i, lname in enumerate(node.loops):
            at = f"nodes.{name}.loops[{i}]"
            if s.loops[lname].controller != name:
                raise ValueError(
                    f"{at}: loop {lname!r} names {s.loops[lname].controller!r} as its controller"
                )
        if all(s.loops[lname].sensor is None for lname in node.loops):
            raise ValueError(
                f"nodes.{name}.loops: every loop is actuator-only (sensor: null); the law "
                "executes on samples and would never move"
            )
        if all(s.loops[lname].actuator is None for lname in node.loops):
            raise ValueError(
                f"nodes.{name}.loops: every loop is measurement-only (actuator: null); the "
                "controller would never move an input"
            )
        agent = s.agent_node()
        linked = any(name in (lk.from_, lk.to) for lk in s.links.values())
        if agent is not None and not (linked and s.nodes_of(WncscaConfig)[agent].links is not None):
            raise ValueError(
                f"nodes.{name}.loops: the coordination agent simulates single-loop "
                "controllers only (it opens, closes and re-tunes loops one by one); it "
                "governs a multi-loop controller only through its links' update period "
                f"(links: in nodes.{agent}, and the controller on a link)"
            )


def check_clock(s: ScenarioSchema) -> None:
    """The nodes the clock may drop exist."""
    for i, name in enumerate(s.clock.may_drop):
        if name not in s.nodes:
            raise ValueError(f"clock.may_drop[{i}]: unknown node {name!r}")


def check_operator(s: ScenarioSchema) -> None:
    """At most one operator, and one wherever a schedule needs publishing."""
    operators = list(s.nodes_of(OperatorNodeConfig))
    if len(operators) > 1:
        raise ValueError(f"nodes: at most one operator node, found {operators}")
    if s.setpoints and not operators:
        raise ValueError("setpoints: a schedule needs an operator node to publish it")
    if s.disturbances and not operators:
        raise ValueError("disturbances: a schedule needs an operator node to publish it")


def check_agent(s: ScenarioSchema) -> None:
    """At most one coordination agent; every loop it names exists; it has links to govern if
    it is told to; its test steps every loop it judges."""
    agents = s.nodes_of(WncscaConfig)
    if len(agents) > 1:
        raise ValueError(f"nodes: at most one agent node, found {list(agents)}")
    for name, cfg in agents.items():
        named = [(f"order[{i}]", n) for i, n in enumerate(cfg.order or [])]
        named += [(f"ideal_period.{n}", n) for n in cfg.ideal_period]
        named += [(f"alarm.{n}", n) for n in cfg.alarm]
        for mode in ("identification", "monitoring", "fault_detection"):
            named += [(f"modes.{mode}.{n}", n) for n in getattr(cfg.modes, mode)]
        if cfg.test is not None:
            named += [
                (f"test.setpoints[{i}].loop", step.loop)
                for i, step in enumerate(cfg.test.setpoints)
            ]
        for where, loop in named:
            if loop not in s.loops:
                raise ValueError(
                    f"nodes.{name}.{where}: unknown loop {loop!r} (loops: {sorted(s.loops)})"
                )
        if cfg.links is not None and not s.links:
            raise ValueError(f"nodes.{name}.links: the scenario has no links to govern")
        steps = cfg.test.setpoints if cfg.test is not None else s.setpoints
        unstepped = sorted(set(s.simulated_loops()) - {step.loop for step in steps})
        if unstepped:
            where = "test.setpoints" if cfg.test is not None else "test (default: setpoints)"
            raise ValueError(
                f"nodes.{name}.{where}: no set-point step for loop(s) {unstepped}; the agent "
                "judges a loop by the overshoot of its step"
            )


def check_agent_method(s: ScenarioSchema) -> None:
    """The agent's method models every loop it judges: the fast and chance methods model the PI
    and seed 002's 2-DOF laws (:data:`agents.wncsca.laws.MODELLED_LAWS`) and refuse the others
    with the reason (:data:`agents.wncsca.laws.REFUSED`); the paper's method simulates any
    single-loop law."""
    for name, cfg in s.nodes_of(WncscaConfig).items():
        if cfg.method == "paper":
            continue
        judged = s.simulated_loops()
        for loop in judged:
            law = s.controller(s.loops[loop].controller).law
            if not isinstance(law, MODELLED_LAWS):
                raise ValueError(f"nodes.{name}.method: {unmodelled_law(cfg.method, loop, law)}")
        _check_linear_forms(s, name, cfg, judged)


def _check_linear_forms(
    s: ScenarioSchema, name: str, cfg: WncscaConfig, judged: Sequence[str]
) -> None:
    """Each judged loop's law has a linear form where the fast and chance methods take one
    (:meth:`agents.wncsca.laws.PILaw.linear`): at the test's final set point (the jitter
    margin), and at every set point the test visits for a loop that shares its plant with another
    judged loop (the fast method's closure of the other loops)."""
    steps = cfg.test.setpoints if cfg.test is not None else s.setpoints
    where = "test.setpoints" if cfg.test is not None else "test (default: setpoints)"
    for loop in judged:
        lp = s.loops[loop]
        if lp.setpoint is None:
            continue
        moves = sorted((float(st.t), float(st.value)) for st in steps if st.loop == loop)
        visited = [float(lp.setpoint)] + [v for _, v in moves]
        shared = any(s.loops[n].plant == lp.plant for n in judged if n != loop)
        law = modelled_law(s.controller(lp.controller).law, s.plant(lp.plant).build(), loop)
        for value in visited if shared else visited[-1:]:
            try:
                law.linear(value, value)
            except ValueError as err:
                raise ValueError(
                    f"nodes.{name}.{where}: loop {loop!r} at {value:g}: {err}; the {cfg.method} "
                    "method needs it there (method 'paper' simulates the law)"
                ) from err


def check_agent_model(s: ScenarioSchema) -> None:
    """The agent's own model (``model:``) names plants it judges, parameters of their models,
    and uncertainty of numeric parameters with the believed value inside a stated interval."""
    for name, cfg in s.nodes_of(WncscaConfig).items():
        judged = sorted({s.loops[n].plant for n in s.simulated_loops()})
        for plant, belief in sorted(cfg.model.items()):
            at = f"nodes.{name}.model.{plant}"
            if plant not in judged:
                raise ValueError(f"{at}: not a plant of a loop the agent judges (plants: {judged})")
            for param in belief.params:
                if param not in s.plant(plant).params:
                    known = sorted(s.plant(plant).params)
                    raise ValueError(f"{at}.params.{param}: not a parameter of the plant ({known})")
        stated = sorted(p for p, belief in cfg.model.items() if belief.uncertainty)
        if stated and cfg.method != "chance":
            raise ValueError(
                f"nodes.{name}.model.{stated[0]}.uncertainty: the {cfg.method} method takes the "
                "model as exact; the chance method covers its uncertainty (method: chance)"
            )
        try:
            believed = s.believed(cfg)
        except ValueError as err:
            raise ValueError(f"nodes.{name}.{err}") from err
        for plant, belief in sorted(cfg.model.items()):
            params = believed.plant(plant).params
            for param, spread in sorted(belief.uncertainty.items()):
                at = f"nodes.{name}.model.{plant}.uncertainty.{param}"
                value = params.get(param)
                if not isinstance(value, int | float) or isinstance(value, bool):
                    raise ValueError(f"{at}: not a numeric parameter of the plant ({value!r})")
                if spread.interval is not None and not (
                    spread.interval[0] <= value <= spread.interval[1]
                ):
                    raise ValueError(
                        f"{at}.interval: the believed value {value} is outside {spread.interval}"
                    )


def check_agent_identify(s: ScenarioSchema) -> None:
    """The agent's identification experiment (``identify:``) perturbs loops it judges, fits
    numeric non-zero parameters of their plants as the agent believes them, samples every
    judged loop at an identification period, ends within the run, and has the set points and
    the mode to itself while it runs (no scheduled set-point change or mode request before its
    end)."""
    for name, cfg in s.nodes_of(WncscaConfig).items():
        exp = cfg.identify
        if exp is None:
            continue
        at = f"nodes.{name}.identify"
        judged = s.simulated_loops()
        for loop in sorted(exp.amplitude):
            if loop not in judged:
                raise ValueError(
                    f"{at}.amplitude.{loop}: not a loop the agent judges (loops: {list(judged)})"
                )
        plants = sorted({s.loops[n].plant for n in judged})
        believed = s.believed(cfg)
        for plant, params in sorted(exp.params.items()):
            if plant not in plants:
                raise ValueError(
                    f"{at}.params.{plant}: not a plant of a loop the agent judges ({plants})"
                )
            for param in params:
                value = believed.plant(plant).params.get(param)
                if isinstance(value, bool) or not isinstance(value, int | float) or value == 0:
                    raise ValueError(
                        f"{at}.params.{plant}: {param!r} is not a non-zero numeric parameter "
                        f"of the plant (believed: {value!r}; parameters: "
                        f"{sorted(believed.plant(plant).params)})"
                    )
        missing = [n for n in judged if n not in cfg.modes.identification]
        if missing:
            raise ValueError(
                f"nodes.{name}.modes.identification: no period for loop(s) {missing}; the "
                "experiment samples every loop the agent judges at its identification period"
            )
        if exp.duration >= s.end_time:
            raise ValueError(
                f"{at}.duration: {exp.duration} does not end before end_time {s.end_time}"
            )
        asked = [  # when the agent hears each request
            (f"setpoints[{i}].t", c.t, c.t - c.announce) for i, c in enumerate(s.setpoints)
        ] + [(f"modes[{i}].t", c.t, c.t) for i, c in enumerate(s.modes)]
        for where, t, heard in asked:
            if heard <= exp.duration:
                raise ValueError(
                    f"{where}: {t} is requested at t = {heard}, within the identification "
                    f"experiment (t = 0 to {exp.duration}, {at}); schedule it after"
                )


def check_monitors(s: ScenarioSchema) -> None:
    """A monitor's loop and columns exist, and its loop has samples."""
    monitors = s.nodes_of(MonitorNodeConfig)
    if not monitors:
        return
    run = run_shape(s)  # builds every plant: once for all monitors
    for name, node in monitors.items():
        node.check(run, name)
        if s.loops[node.loop].sensor is None:
            raise ValueError(f"nodes.{name}.loop: loop {node.loop!r} is actuator-only (no samples)")


def check_disturbances(s: ScenarioSchema) -> None:
    """A disturbance changes an input of its plant that no loop moves, within the run."""
    moved = {(lp.plant, lp.actuator) for lp in s.loops.values() if lp.actuator is not None}
    for i, dist in enumerate(s.disturbances):
        at = f"disturbances[{i}]"
        inputs = _node_of(s, PlantNodeConfig, dist.plant, f"{at}.plant").build().input_names
        if dist.input not in inputs:
            raise ValueError(
                f"{at}.input: plant {dist.plant!r} has no input {dist.input!r} "
                f"(inputs: {list(inputs)})"
            )
        if (dist.plant, dist.input) in moved:
            raise ValueError(f"{at}.input: {dist.input!r} is moved by a loop's controller")
        if dist.t > s.end_time:
            raise ValueError(f"{at}.t: {dist.t} is after end_time {s.end_time}")


def check_drifts(s: ScenarioSchema) -> None:
    """A drift moves a numeric parameter of its plant to a value its model accepts, within the
    run, with an operator to publish it; drifts of one parameter do not overlap."""
    if s.drifts and not s.nodes_of(OperatorNodeConfig):
        raise ValueError("drifts: a schedule needs an operator node to publish it")
    until: dict[tuple[str, str], float] = {}
    for i, d in sorted(enumerate(s.drifts), key=lambda e: e[1].t):
        at = f"drifts[{i}]"
        cfg = _node_of(s, PlantNodeConfig, d.plant, f"{at}.plant")
        value = cfg.params.get(d.param)
        if isinstance(value, bool) or not isinstance(value, int | float):
            known = sorted(k for k, v in cfg.params.items() if isinstance(v, int | float))
            raise ValueError(f"{at}.param: {d.param!r} is not a numeric parameter {known}")
        try:
            PlantNodeConfig.model_validate(
                {**cfg.model_dump(), "params": {**cfg.params, d.param: d.value}}
            )
        except ValueError as err:
            raise ValueError(f"{at}.value: the plant refuses {d.param} = {d.value}: {err}") from err
        if d.t > s.end_time:
            raise ValueError(f"{at}.t: {d.t} is after end_time {s.end_time}")
        if until.get((d.plant, d.param), -1.0) > d.t:
            raise ValueError(f"{at}.t: a drift of {d.plant}.{d.param} is still under way")
        until[(d.plant, d.param)] = d.t + d.over


def check_setpoints(s: ScenarioSchema) -> None:
    """A set-point change is of a loop with a set point, within the run, announced (to an
    agent) no earlier than the run's start."""
    for i, change in enumerate(s.setpoints):
        if change.loop not in s.loops:
            raise ValueError(
                f"setpoints[{i}].loop: unknown loop {change.loop!r} (loops: {sorted(s.loops)})"
            )
        if change.t > s.end_time:
            raise ValueError(f"setpoints[{i}].t: {change.t} is after end_time {s.end_time}")
        if s.loops[change.loop].sensor is None:
            raise ValueError(
                f"setpoints[{i}].loop: {change.loop!r} is actuator-only (sensor: null): "
                "it has no set point"
            )
        if change.announce > change.t:
            raise ValueError(
                f"setpoints[{i}].announce: {change.announce} is before the run starts "
                f"(t = {change.t})"
            )
        if change.announce and s.agent_node() is None:
            raise ValueError(f"setpoints[{i}].announce: announcing needs an agent node")
        if change.safe_ramp and s.agent_node() is None:
            raise ValueError(
                f"setpoints[{i}].safe_ramp: the safe alternative is a coordination agent's; the "
                "scenario has no agent node"
            )


def check_modes(s: ScenarioSchema) -> None:
    """Mode requests go from an operator to an agent, name known modes, within the run."""
    if s.modes and (s.agent_node() is None or not s.nodes_of(OperatorNodeConfig)):
        raise ValueError("modes: mode requests need an agent node and an operator node")
    for i, change in enumerate(s.modes):
        if change.mode not in MODES:
            raise ValueError(f"modes[{i}].mode: unknown mode {change.mode!r} (modes: {MODES})")
        if change.t > s.end_time:
            raise ValueError(f"modes[{i}].t: {change.t} is after end_time {s.end_time}")


def check_feedforward(s: ScenarioSchema) -> None:
    """A controller's ``feedforward_params`` name numeric parameters of its loops' plant, and
    every steady-state feedforward is computable at every scheduled set point."""
    for name, ctl in s.controllers().items():
        if not ctl.feedforward_params:
            continue
        for plant in sorted({lp.plant for lp in s.loops.values() if lp.controller == name}):
            cfg = s.plant(plant)
            try:
                registry.build(cfg.model, {**cfg.params, **ctl.feedforward_params})
            except (ValueError, TypeError) as err:
                first = str(err).splitlines()
                raise ValueError(
                    f"nodes.{name}.feedforward_params: not parameters of plant {plant!r} "
                    f"({cfg.model}): {' '.join(first[:3])}"
                ) from err
    current = {name: lp.setpoint for name, lp in s.loops.items() if lp.setpoint is not None}
    order = sorted(range(len(s.setpoints)), key=lambda i: s.setpoints[i].t)
    for index in [None, *order]:
        where = "loops.*.setpoint (initial set points)"
        if index is not None:
            change = s.setpoints[index]
            current[change.loop] = change.value
            where = f"setpoints[{index}]"
        for lname, loop in s.loops.items():
            if not uses_feedforward(s.controllers()[loop.controller].law):
                continue
            try:
                s.feedforward(lname).u_bar(s.plant_setpoints(loop.plant, current))
            except ValueError as err:
                raise ValueError(f"{where}: feedforward of loop {lname!r}: {err}") from err


def check_links(s: ScenarioSchema) -> None:
    """Links join two multi-loop controllers whose laws exchange data, over a network node."""
    for name, link in s.links.items():
        at = f"links.{name}"
        if name in s.loops:
            raise ValueError(f"{at}: a loop has that name; name links and loops apart")
        for field, node in (("from", link.from_), ("to", link.to)):
            cfg = s.nodes.get(node)
            if not isinstance(cfg, ControllerNodeConfig):
                known = sorted(s.nodes_of(ControllerNodeConfig))
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
        net = s.nodes.get(link.network)
        if isinstance(net, GatewayNodeConfig):
            topo_nodes = net.topology.nodes
            for end, radio in (("source_node", link.source_node), ("dest_node", link.dest_node)):
                if radio not in topo_nodes:
                    raise ValueError(
                        f"{at}.{end}: {radio!r} is not a node of the topology of "
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
                raise ValueError(f"{at}.network: {link.network!r} is not a network or gateway node")
            if link.source_node is not None or link.dest_node is not None:
                raise ValueError(f"{at}.source_node: only links over a gateway name WSN nodes")
        if to_ticks(link.period) < 1:
            raise ValueError(f"{at}.period: {link.period} is shorter than one tick")


def check_multi_loop_laws(s: ScenarioSchema) -> None:
    """Build every multi-loop law once, so that refusals that depend on the plant (a design
    the plant's linearization does not admit) name the node before anything starts."""
    for name, node in s.controllers().items():
        if node.loops is None:
            continue
        try:
            s.multi_loop_law(name)
        except ValueError as err:
            raise ValueError(f"nodes.{name}.law.{node.law.type}: {err}") from err


def check_agent_links(s: ScenarioSchema) -> None:
    """The analysis an agent with ``links:`` will run needs laws it can analyse (built now,
    so that a refusal names the agent before anything starts)."""
    agent = s.agent_node()
    cfg = s.nodes_of(WncscaConfig)[agent] if agent is not None else None
    if cfg is None or cfg.links is None:
        return
    try:
        link_groups(s.links, s.multi_loop_law, cfg.links.analysis, tau_s=s.multi_loop_tau_s)
    except ValueError as err:
        raise ValueError(f"nodes.{agent}.links: {err}") from err


def check_one_loop_per_input(s: ScenarioSchema) -> None:
    """Two loops moving one input would fight over it (after the laws' own checks, which
    name their own cases more precisely)."""
    movers: dict[tuple[str, str], str] = {}  # (plant, input) -> the loop that moves it
    for lname, loop in s.loops.items():
        if loop.actuator is None:
            continue
        first = movers.setdefault((loop.plant, loop.actuator), lname)
        if first != lname:
            raise ValueError(
                f"loops.{lname}.actuator: input {loop.actuator!r} of plant {loop.plant!r} is "
                f"already moved by loop {first!r} (one loop per input)"
            )


GRAPH_CHECKS: tuple[Callable[[ScenarioSchema], None], ...] = (
    check_multi_loop_controllers_name_loops,
    check_traces_name_carried_loops,
    check_loops,
    check_controllers,
    check_clock,
    check_operator,
    check_agent,
    check_agent_method,
    check_agent_model,
    check_agent_identify,
    check_monitors,
    check_disturbances,
    check_drifts,
    check_setpoints,
    check_modes,
    check_feedforward,
    check_links,
    check_multi_loop_laws,
    check_agent_links,
    check_one_loop_per_input,
)
"""The checks in the order they run (a scenario with several faults is refused for the first)."""


def check_graph(s: ScenarioSchema) -> None:
    """Run every check of :data:`GRAPH_CHECKS` on ``s`` (``ValueError`` at the first fault)."""
    for check in GRAPH_CHECKS:
        check(s)
