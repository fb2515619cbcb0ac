"""Operator node: publishes each scheduled set-point change on ``ops/setpoint/<loop>``."""

from __future__ import annotations

from bus_schemas import Setpoint, keys
from runtime.node import Node, NodeContext
from runtime.time import to_ticks

__all__ = ["OperatorNode"]


class OperatorNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        for change in self.scenario.setpoints:
            self.at(to_ticks(change.t), self._publisher(change.loop, change.value))

    def _publisher(self, loop: str, value: float):  # noqa: ANN202
        return lambda: self.publish(keys.setpoint(loop), Setpoint(value=value))
