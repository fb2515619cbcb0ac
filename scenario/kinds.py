"""The node kinds: for each ``kind:`` of a scenario's node, its configuration and its build.

:data:`NODE_KINDS` is the registry every engine builds nodes from (:func:`runtime.direct.
behaviour_of`): ``build(name, scenario, simulate)`` gives the node's behaviour, the same on every
engine (``simulate`` runs a scenario on the direct engine, for the nodes that simulate, as the
coordination agent does). Most kinds build as :class:`BehaviourBuild`: the node's typed spec
(:mod:`scenario.views`), then its behaviour from it.

Adding a node kind is one module (its configuration, a pydantic model with ``kind:
Literal["name"]``, and its :class:`~core.behaviour.Behaviour`) and one entry here; the schema's
static union (:data:`scenario.schema.NodeConfig`) names the configuration too, and
``tests/unit/test_scenario_package.py`` checks the two agree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from agents.monitor.behaviour import MonitorBehaviour
from agents.monitor.config import MonitorNodeConfig
from agents.operator.behaviour import OperatorBehaviour
from agents.wncsca.config import WncscaConfig
from controllers.behaviour import ControllerBehaviour
from core.behaviour import Behaviour
from core.record import Simulate
from core.registry import Kind, Registry
from gateway.behaviour import NetworkBehaviour
from plants.behaviour import PlantBehaviour
from scenario.schema import (
    ControllerNodeConfig,
    GatewayNodeConfig,
    NetworkNodeConfig,
    OperatorNodeConfig,
    PlantNodeConfig,
    ScenarioSchema,
)
from scenario.views import (
    agent_behaviour,
    controller_spec,
    monitor_spec,
    network_spec,
    operator_spec,
    plant_spec,
)

__all__ = ["BehaviourBuild", "NODE_KINDS"]


@dataclass(frozen=True)
class BehaviourBuild:
    """A node kind's build: ``behaviour(name, spec(scenario, name))``, the node's typed spec
    computed once (:mod:`scenario.views`)."""

    behaviour: Callable[[str, Any], Behaviour]
    spec: Callable[[ScenarioSchema, str], Any]

    def __call__(self, name: str, scenario: ScenarioSchema, simulate: Simulate) -> Behaviour:
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
the behaviour every engine runs."""
