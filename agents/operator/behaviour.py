"""Operator node: publishes the scenario's schedules at their times.

Set-point changes go on ``ops/setpoint/<loop>`` (an announced change goes ``announce`` ahead of
its time, with ``t_apply``); operating-mode requests on ``ops/mode``; disturbances (inputs no loop
moves, such as a draw-off flow) go straight to the plant's actuator key
``plant/<p>/actuator/<input>``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bus_schemas import ModeRequest, Move, Setpoint, keys
from core.behaviour import Behaviour
from core.time import to_ticks

__all__ = ["OperatorBehaviour"]


class OperatorBehaviour(Behaviour):
    def __init__(self, name: str, scenario: Any) -> None:
        super().__init__(name)
        self.scenario = scenario
        for change in self.scenario.setpoints:
            t = to_ticks(change.t)
            if change.announce:
                body = Setpoint(value=change.value, t_apply=t)
                self.at(t - to_ticks(change.announce), self._publisher(change.loop, body))
            else:
                self.at(t, self._publisher(change.loop, Setpoint(value=change.value)))
        for mode in self.scenario.modes:
            self.at(to_ticks(mode.t), self._mode(mode.mode))
        for dist in self.scenario.disturbances:
            self.at(to_ticks(dist.t), self._disturber(dist.plant, dist.input, dist.value))

    def _publisher(self, loop: str, body: Setpoint) -> Callable[[], None]:
        return lambda: self.publish(keys.setpoint(loop), body)

    def _mode(self, mode: str) -> Callable[[], None]:
        return lambda: self.publish(keys.ops_mode(), ModeRequest(mode=mode))

    def _disturber(self, plant: str, input_name: str, value: float) -> Callable[[], None]:
        key = keys.actuator(plant, input_name)
        return lambda: self.publish(key, Move(value=value, t_computed=self.now))
