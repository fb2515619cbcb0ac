"""The plant node: runs any plant model on the bus.

It samples each sensor at its loop's ``tau_s`` (``plant/<p>/sensor/<s>``), applies the commands it
receives (``plant/<p>/actuator/<i>``) from their time on (zero-order hold), and records its true
state on a monitoring grid (``plant/<p>/state``, sent in batches when it samples and at the end).

A sensor's period can be changed while the run goes on (``plant/<p>/sampling/<s>``, from the
network that carries its loop, as the coordination agent assigns it): the next sample is then one
new period after the last one taken, or at once if that instant has passed.

It integrates lazily, only up to instants where it samples or receives a command, cutting every
segment at the monitoring grid: its trajectory does not depend on other nodes' timers, and the
``direct`` engine integrates over exactly the same segments.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bus_schemas import Move, PlantState, Sample, SamplingPeriod, keys
from bus_schemas.envelope import RawEnvelope
from core.behaviour import Behaviour
from core.time import to_ticks, to_units
from plants.integrate import integrator_of

__all__ = ["PlantBehaviour"]


class PlantBehaviour(Behaviour):
    def __init__(self, name: str, scenario: Any) -> None:
        super().__init__(name)
        self.scenario = scenario
        cfg = self.scenario.nodes[self.name]
        self.model = cfg.build()
        self.x = np.array([cfg.x0[s] for s in self.model.state_names], dtype=float)
        self.u = np.array([cfg.u0[s] for s in self.model.input_names], dtype=float)
        self.t_state = 0
        self.max_step = cfg.max_step
        self._step = integrator_of(self.model)
        self.monitor = to_ticks(cfg.monitor_period)
        self.end = to_ticks(self.scenario.end_time)
        self._next_record = 0
        self._records_t: list[int] = []
        self._records_x: list[list[float]] = []
        self.noise = dict(cfg.noise)
        self._rngs: dict[str, Any] = {}
        self.periods: dict[str, int] = {}
        self._last_sample: dict[str, int] = {}
        self._generation: dict[str, int] = {}
        for loop in self.scenario.loops_of_plant(self.name).values():
            if loop.sensor is None:
                continue  # an actuator-only loop: nothing to sample
            self.periods[loop.sensor] = to_ticks(loop.tau_s)
            self._generation[loop.sensor] = 0
            self.at(0, self._sampler(loop.sensor, 0))
            self.subscribe(
                keys.sampling(self.name, loop.sensor), SamplingPeriod, self._on_period(loop.sensor)
            )
        for input_name in self.model.input_names:  # loop actuators and scheduled disturbances
            self.subscribe(keys.actuator(self.name, input_name), Move, self._actuator(input_name))
        self.at(self.end, self._final)

    def _integrate_to(self, t: int) -> None:
        """Integrate to ``t``, stopping at (and recording) every monitoring instant on the way."""
        while self._next_record <= t:
            self._step_to(self._next_record)
            self._records_t.append(self._next_record)
            self._records_x.append(self.x.tolist())
            self._next_record += self.monitor
        self._step_to(t)

    def _step_to(self, t: int) -> None:
        if t > self.t_state:
            self.x = self._step(
                to_units(self.t_state), self.x, to_units(t), self.u, max_step=self.max_step
            )
            self.t_state = t

    def _send_records(self) -> None:
        if not self._records_t:
            return
        columns = zip(*self._records_x, strict=True)
        values = {n: tuple(c) for n, c in zip(self.model.state_names, columns, strict=True)}
        self.publish(
            keys.plant_state(self.name), PlantState(t=tuple(self._records_t), values=values)
        )
        self._records_t, self._records_x = [], []

    def _final(self) -> None:
        self._integrate_to(self.now)
        self._send_records()

    def _sampler(self, signal: str, generation: int) -> Any:
        """A sample of ``signal`` now, and the next one a period later (unless a new period has
        rescheduled the sensor since: then this timer is stale and does nothing)."""
        index = self.model.output_names.index(signal)
        sigma = self.noise.get(signal, 0.0)
        if signal not in self._rngs:
            self._rngs[signal] = self.scenario.sensor_rng(self.name, signal)
        rng = self._rngs[signal]

        def sample() -> None:
            if generation != self._generation[signal]:
                return
            self._integrate_to(self.now)
            y = float(self.model.outputs(self.x)[index])
            if sigma > 0.0:
                y += sigma * float(rng.standard_normal())
            self.publish(keys.sensor(self.name, signal), Sample(value=y, t_sampled=self.now))
            self._send_records()
            self._last_sample[signal] = self.now
            nxt = self.now + self.periods[signal]
            if nxt <= self.end:
                self.at(nxt, self._sampler(signal, generation))

        return sample

    def _on_period(self, signal: str) -> Any:
        def apply(env: RawEnvelope, msg: SamplingPeriod) -> None:
            if msg.period == self.periods[signal]:
                return
            self.log.info(
                "sensor %s: period %s -> %s ticks", signal, self.periods[signal], msg.period
            )
            self.periods[signal] = msg.period
            self._generation[signal] += 1
            last = self._last_sample.get(signal)
            nxt = self.now if last is None else max(last + msg.period, self.now)
            if last == self.now:
                nxt = self.now + msg.period  # sampled in this instant already
            if nxt <= self.end:
                self.at(nxt, self._sampler(signal, self._generation[signal]))

        return apply

    def _actuator(self, input_name: str) -> Any:
        index = self.model.input_names.index(input_name)

        def apply(env: RawEnvelope, move: Move) -> None:
            self._integrate_to(self.now)
            self.u[index] = move.value

        return apply
