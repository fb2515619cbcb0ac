"""The scenario layer: scenario files (the process graph, loops, set-point schedule and timing
of one run), their checks, and the typed spec of every node computed from them.

A scenario is YAML validated into :class:`Scenario` before anything starts; every problem
becomes a :class:`~core.errors.ConfigError` naming the file and the dotted field
(``scenarios/x.yaml: line 14: loops.level.tau_s: Input should be greater than 0``; the line
where the file has the field, ``scenario/yaml_positions.py``; ``--set`` overrides,
``scenario/overrides.py``, are applied before validation).

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

The package, lowest first (no module imports one after it):

* :mod:`scenario.schema`: every node kind's configuration, the static :data:`NodeConfig` union,
  loops, links, schedules, and :class:`ScenarioSchema`, a scenario's fields with the views
  derived from them;
* :mod:`scenario.views`: each node's typed spec (plant, controller, network, operator, monitor,
  the agent's :class:`~agents.wncsca.spec.AgentSpec` and its trials' simulator), computed once;
* :mod:`scenario.checks`: the checks across fields, one function per concern;
* :mod:`scenario.model`: :class:`Scenario`, the schema validated whole;
* :mod:`scenario.kinds`: :data:`NODE_KINDS`, each kind's configuration and build;
* :mod:`scenario.load`: reading a file (:mod:`scenario.yaml_positions` for the lines,
  :mod:`scenario.overrides` for ``--set``) into a :class:`Scenario`.

Import from the package (``from scenario import Scenario, load_scenario``); its modules import
from each other, never from the package.
"""

from scenario.kinds import NODE_KINDS, BehaviourBuild
from scenario.load import load_scenario, parse_scenario
from scenario.model import Scenario
from scenario.schema import (
    AGENT_NETWORK,
    AGENT_OPERATOR,
    HISTORIAN,
    MAX_END_TIME,
    RESERVED_NODES,
    SETPOINT_LIMIT,
    ClockConfig,
    ControllerNodeConfig,
    Disturbance,
    GatewayNodeConfig,
    LinkConfig,
    LoopConfig,
    ModeChange,
    NetworkNodeConfig,
    NodeConfig,
    OperatorNodeConfig,
    PlantNodeConfig,
    ScenarioSchema,
    ScheduledEvent,
    SetpointChange,
)

__all__ = [
    "NODE_KINDS",
    "BehaviourBuild",
    "load_scenario",
    "parse_scenario",
    "Scenario",
    "AGENT_NETWORK",
    "AGENT_OPERATOR",
    "HISTORIAN",
    "MAX_END_TIME",
    "RESERVED_NODES",
    "SETPOINT_LIMIT",
    "ClockConfig",
    "ControllerNodeConfig",
    "Disturbance",
    "GatewayNodeConfig",
    "LinkConfig",
    "LoopConfig",
    "ModeChange",
    "NetworkNodeConfig",
    "NodeConfig",
    "OperatorNodeConfig",
    "PlantNodeConfig",
    "ScenarioSchema",
    "ScheduledEvent",
    "SetpointChange",
]
