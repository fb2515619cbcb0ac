"""Operator node: publishes the scenario's schedules at their times.

Set-point changes go on ``ops/setpoint/<loop>``; disturbances (inputs no loop moves, such as a
draw-off flow) go straight to the plant's actuator key ``plant/<p>/actuator/<input>``.
"""

from __future__ import annotations

from collections.abc import Callable

from bus_schemas import Move, Setpoint, keys
from runtime.node import Node, NodeContext
from runtime.time import to_ticks

__all__ = ["OperatorNode"]


class OperatorNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        for change in self.scenario.setpoints:
            self.at(to_ticks(change.t), self._publisher(change.loop, change.value))
        for dist in self.scenario.disturbances:
            self.at(to_ticks(dist.t), self._disturber(dist.plant, dist.input, dist.value))

    def _publisher(self, loop: str, value: float) -> Callable[[], None]:
        return lambda: self.publish(keys.setpoint(loop), Setpoint(value=value))

    def _disturber(self, plant: str, input_name: str, value: float) -> Callable[[], None]:
        key = keys.actuator(plant, input_name)
        return lambda: self.publish(key, Move(value=value, t_computed=self.now))
