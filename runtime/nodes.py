"""Which class runs a node of each kind (the scenario's ``kind:``, plus the reserved nodes)."""

from __future__ import annotations

from agents.monitor.node import MonitorNode
from agents.operator.node import OperatorNode
from agents.wncsca.node import WncscaNode
from controllers.node import ControllerNode
from gateway.node import NetworkNode
from plants.node import PlantNode
from runtime.historian import HistorianNode
from runtime.node import Node
from runtime.scenario import Scenario

__all__ = ["NODE_CLASSES", "node_class"]

NODE_CLASSES: dict[str, type[Node]] = {
    "plant": PlantNode,
    "controller": ControllerNode,
    "network": NetworkNode,
    "gateway": NetworkNode,
    "operator": OperatorNode,
    "agent": WncscaNode,
    "monitor": MonitorNode,
}


def node_class(scenario: Scenario, name: str) -> type[Node]:
    """The class of node ``name`` (``KeyError`` with the known names if there is none)."""
    if name == "historian":
        return HistorianNode
    cfg = scenario.nodes.get(name)
    if cfg is None:
        known = ", ".join(["clock", *scenario.participants()])
        raise KeyError(f"scenario {scenario.name!r} has no node {name!r} (nodes: {known})")
    return NODE_CLASSES[cfg.kind]
