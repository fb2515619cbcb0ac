"""Operator node: publishes the scenario's schedules at their times.

Set-point changes go on ``ops/setpoint/<loop>`` (an announced change goes ``announce`` ahead of
its time, with ``t_apply``); operating-mode requests on ``ops/mode``; disturbances (inputs no loop
moves, such as a draw-off flow) go straight to the plant's actuator key
``plant/<p>/actuator/<input>``; drifts of a plant's parameters on ``plant/<p>/drift``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from bus_schemas import Drift, ModeRequest, Move, Setpoint, keys
from core.behaviour import Behaviour

__all__ = [
    "OperatorBehaviour",
    "OperatorSpec",
    "SetpointAt",
    "ModeAt",
    "DisturbanceAt",
    "DriftAt",
]


class SetpointAt(NamedTuple):
    t: int  # ticks: when the set point applies
    loop: str
    value: float
    announce: int  # ticks ahead of t it is announced (0: not announced)
    safe_ramp: bool = False  # the agent may ramp a step it refuses


class ModeAt(NamedTuple):
    t: int
    mode: str


class DisturbanceAt(NamedTuple):
    t: int
    plant: str
    input: str
    value: float


class DriftAt(NamedTuple):
    t: int
    plant: str
    drift: Drift


@dataclass(frozen=True)
class OperatorSpec:
    """The scenario's schedules, in ticks (:func:`scenario.views.operator_spec`)."""

    setpoints: tuple[SetpointAt, ...] = ()
    modes: tuple[ModeAt, ...] = ()
    disturbances: tuple[DisturbanceAt, ...] = ()
    drifts: tuple[DriftAt, ...] = ()


class OperatorBehaviour(Behaviour):
    def __init__(self, name: str, spec: OperatorSpec) -> None:
        super().__init__(name)
        self.spec = spec
        for change in spec.setpoints:
            if change.announce:
                body = Setpoint(value=change.value, t_apply=change.t, safe_ramp=change.safe_ramp)
                self.at(change.t - change.announce, self._publisher(change.loop, body))
            else:
                body = Setpoint(value=change.value, safe_ramp=change.safe_ramp)
                self.at(change.t, self._publisher(change.loop, body))
        for mode in spec.modes:
            self.at(mode.t, self._mode(mode.mode))
        for dist in spec.disturbances:
            self.at(dist.t, self._disturber(dist.plant, dist.input, dist.value))
        for drift in spec.drifts:
            self.at(drift.t, self._drifter(drift.plant, drift.drift))

    def _publisher(self, loop: str, body: Setpoint) -> Callable[[], None]:
        return lambda: self.publish(keys.setpoint(loop), body)

    def _mode(self, mode: str) -> Callable[[], None]:
        return lambda: self.publish(keys.ops_mode(), ModeRequest(mode=mode))

    def _drifter(self, plant: str, drift: Drift) -> Callable[[], None]:
        return lambda: self.publish(keys.drift(plant), drift)

    def _disturber(self, plant: str, input_name: str, value: float) -> Callable[[], None]:
        key = keys.actuator(plant, input_name)
        return lambda: self.publish(key, Move(value=value, t_computed=self.now))
