"""The plant node: runs any plant model on the bus.

It samples each sensor at its loop's ``tau_s`` (``plant/<p>/sensor/<s>``), applies the commands it
receives (``plant/<p>/actuator/<i>``) from their time on (zero-order hold), and records its true
state on a monitoring grid (``plant/<p>/state``, sent in batches when it samples and at the end).

The true plant's physical parameters may drift (``plant/<p>/drift``, from the operator's
``drifts:`` schedule or ``wncs inject``): a :class:`~bus_schemas.Drift` moves one parameter from
its value now to a new one, at once or in equal steps over a ramp (fouling, wear); the plant
integrates to each step and goes on with its model rebuilt on the new value. A new drift of a
parameter replaces a ramp of it under way; a drift the model refuses (an unknown or non-numeric
parameter, a value out of its bounds) is dropped with its reason. Nothing else is told: a
coordination agent judges on its own model.

A sensor's period can be changed while the run goes on (``plant/<p>/sampling/<s>``, from the
network that carries its loop, as the coordination agent assigns it): the next sample is then one
new period after the last one taken, or at once if that instant has passed.

It integrates lazily, only up to instants where it samples or receives a command, cutting every
segment at the monitoring grid: its trajectory does not depend on other nodes' timers, and the
``direct`` engine integrates over exactly the same segments.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from math import inf
from typing import Any

import numpy as np

from bus_schemas import Drift, Move, PlantState, Sample, SamplingPeriod, keys
from bus_schemas.envelope import RawEnvelope
from core.behaviour import Behaviour, Timer
from core.time import to_units
from plants import registry
from plants.integrate import integrator_of

__all__ = ["PlantBehaviour", "PlantSpec"]


@dataclass(frozen=True)
class _Applied:
    """A command applied since the plant last published: what undoing it restores."""

    key: str
    index: int
    value: float
    before: float
    t_state: int
    x: np.ndarray
    next_record: int
    n_records: int


class _Diverged(Exception):
    """The state left the finite numbers after a command not yet published on."""


@dataclass(frozen=True)
class PlantSpec:
    """What a plant node needs of its scenario, computed once (:func:`scenario.views.plant_spec`).

    Attributes
    ----------
    model : object
        The plant model (:mod:`plants.registry`).
    x0, u0 : tuple of float
        Initial state and held inputs, in the model's ``state_names`` / ``input_names`` order.
    max_step : float
        Largest RK4 step, time units.
    monitor, end : int
        Period of the true-state record and end of the run, ticks.
    sensors : mapping
        Sampled output -> its loop's initial sampling period, ticks (in the loops' name order).
    offsets : mapping
        Sampled output -> its first sampling instant, ticks (none named: 0).
    noise : mapping
        Output -> standard deviation of its additive measurement noise.
    rngs : mapping
        Sampled output -> its seeded generator (the node owns it; drawn from only with noise).
    input_range : tuple of (float, float)
        Each input's actuator range, in ``input_names`` order: a command beyond it is held at
        the limit (saturation); ``(-inf, inf)`` for no limit.
    """

    model: Any
    x0: tuple[float, ...]
    u0: tuple[float, ...]
    max_step: float
    monitor: int
    end: int
    sensors: Mapping[str, int]
    noise: Mapping[str, float]
    rngs: Mapping[str, np.random.Generator]
    input_range: tuple[tuple[float, float], ...] = ()
    kind: str = ""
    """The model's name in :data:`plants.registry.MODELS` (to rebuild it when it drifts)."""
    params: Mapping[str, Any] = field(default_factory=dict)
    """The model's parameters at the start."""
    offsets: Mapping[str, int] = field(default_factory=dict)


class PlantBehaviour(Behaviour):
    def __init__(self, name: str, spec: PlantSpec) -> None:
        super().__init__(name)
        self.spec = spec
        self.model = spec.model
        self.x = np.array(spec.x0, dtype=float)
        self.u = np.array(spec.u0, dtype=float)
        self.t_state = 0
        self._applied: list[_Applied] = []  # since the plant last published
        self._in_force: dict[int, _Applied] = {}  # input index -> the command that set it
        self._frozen = False
        self.max_step = spec.max_step
        self._step = integrator_of(self.model)
        self.monitor = spec.monitor
        self.end = spec.end
        self._next_record = 0
        self._records_t: list[int] = []
        self._records_x: list[list[float]] = []
        self.noise = dict(spec.noise)
        self.samplers: dict[str, Timer] = {}
        for sensor, period in spec.sensors.items():
            start = spec.offsets.get(sensor, 0)
            self.samplers[sensor] = self.every(
                period, self._sampler(sensor), start=start, end=self.end
            )
            key = keys.sampling(self.name, sensor)
            self.subscribe(key, SamplingPeriod, self._on_period(sensor))
        for input_name in self.model.input_names:  # loop actuators and scheduled disturbances
            self.subscribe(keys.actuator(self.name, input_name), Move, self._actuator(input_name))
        self.params = dict(spec.params)
        self._ramps: dict[str, int] = {}  # parameter -> generation of its ramp under way
        if spec.kind:
            self.subscribe(keys.drift(self.name), Drift, self._on_drift)
        self.at(self.end, self._final)

    def _on_drift(self, env: RawEnvelope, drift: Drift) -> None:
        """Start ``drift`` (see the module docstring): its steps are timers of this ramp's
        generation, so a later drift of the parameter makes them stale."""
        start = self.params.get(drift.param)
        if isinstance(start, bool) or not isinstance(start, int | float):
            known = sorted(k for k, v in self.params.items() if isinstance(v, int | float))
            self.reject(self.current_key, f"{drift.param!r}: not a numeric parameter {known}")
            return
        try:
            registry.build(self.spec.kind, {**self.params, drift.param: drift.value})
        except ValueError as err:  # pydantic's ValidationError is one
            self.reject(self.current_key, f"{drift.param} = {drift.value!r}: {err}")
            return
        generation = self._ramps[drift.param] = self._ramps.get(drift.param, 0) + 1
        steps = drift.steps if drift.over > 0 else 1
        self.log.info(
            "%s drifts %s -> %s over %s ticks", drift.param, start, drift.value, drift.over
        )
        for k in range(1, steps + 1):
            value = drift.value if k == steps else start + (drift.value - start) * k / steps
            self.at(
                self.now + drift.over * k // steps, self._retune(drift.param, value, generation)
            )

    def _retune(self, param: str, value: float, generation: int) -> Any:
        def apply() -> None:
            if self._ramps.get(param) != generation:
                return  # replaced by a later drift of the parameter
            self._integrate_to(self.now)
            self._applied.clear()  # what came before the change stands with the old model
            self.params[param] = value
            self.model = registry.build(self.spec.kind, self.params)
            self._step = integrator_of(self.model)

        return apply

    def _integrate_to(self, t: int) -> None:
        """Integrate to ``t``, stopping at (and recording) every monitoring instant on the way.

        A command the model cannot bear (finite, yet it drives the state to NaN or infinity:
        1e300, or a large negative outflow) is refused when that happens before the plant
        publishes again: the state goes back to the instant it was applied, the input it
        replaced is held, the command is dropped and counted on its key, and the integration
        runs again. The plant node does not die of it; the run goes on as if it never came."""
        try:
            while self._next_record <= t:
                self._step_to(self._next_record)
                self._records_t.append(self._next_record)
                self._records_x.append(self.x.tolist())
                self._next_record += self.monitor
            self._step_to(t)
        except _Diverged:
            self._undo_commands()
            self._integrate_to(t)

    def _step_to(self, t: int) -> None:
        if t > self.t_state:
            t0, t1 = to_units(self.t_state), to_units(t)
            x = self._step(t0, self.x, t1, self.u, max_step=self.max_step)
            if not np.isfinite(x).all():
                if self._applied:
                    raise _Diverged
                x = self._bear(t0, t1)
            self.x = x
            self.t_state = t

    def _bear(self, t0: float, t1: float) -> np.ndarray:
        """The state at ``t1`` when the commands in force drive it out of the finite numbers
        after the plant has published on them: refuse them, latest first, until the segment
        stays finite; if none does, the state holds (the node lives on, said once)."""
        for index, applied in sorted(self._in_force.items(), key=lambda kv: -kv[1].t_state):
            self.u[index] = applied.before
            del self._in_force[index]
            self.reject(applied.key, f"command {applied.value!r} makes the state non-finite")
            x = self._step(t0, self.x, t1, self.u, max_step=self.max_step)
            if np.isfinite(x).all():
                return np.asarray(x)
        if not self._frozen:
            self._frozen = True
            self.log.error("the state cannot be integrated past t = %s; it holds", t0)
        return self.x

    def _undo_commands(self) -> None:
        """Refuse every command applied since the plant last published (see _integrate_to)."""
        first = self._applied[0]
        for a in reversed(self._applied):
            self.u[a.index] = a.before
            if self._in_force.get(a.index) is a:
                del self._in_force[a.index]
            self.reject(a.key, f"command {a.value!r} drives the state out of the finite numbers")
        self.x, self.t_state, self._next_record = first.x, first.t_state, first.next_record
        del self._records_t[first.n_records :], self._records_x[first.n_records :]
        self._applied.clear()

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
        self._applied.clear()

    def _sampler(self, signal: str) -> Any:
        """A sample of ``signal`` now (its :class:`~core.behaviour.Timer` fires it every
        period, up to the end, retimed by the network: :meth:`_on_period`)."""
        index = self.model.output_names.index(signal)
        sigma = self.noise.get(signal, 0.0)
        rng = self.spec.rngs[signal]

        def sample() -> None:
            self._integrate_to(self.now)
            y = float(self.model.outputs(self.x)[index])
            if sigma > 0.0:
                y += sigma * float(rng.standard_normal())
            self.publish(keys.sensor(self.name, signal), Sample(value=y, t_sampled=self.now))
            self._send_records()
            self._applied.clear()  # published: what came before it stands

        return sample

    def _on_period(self, signal: str) -> Any:
        def apply(env: RawEnvelope, msg: SamplingPeriod) -> None:
            timer = self.samplers[signal]
            before = timer.period
            if timer.retime(msg.period):  # the phase of its last sample kept
                self.log.info("sensor %s: period %s -> %s ticks", signal, before, msg.period)

        return apply

    def _actuator(self, input_name: str) -> Any:
        index = self.model.input_names.index(input_name)
        low, high = self.spec.input_range[index] if self.spec.input_range else (-inf, inf)

        def apply(env: RawEnvelope, move: Move) -> None:
            value = min(max(move.value, low), high)  # the actuator saturates
            self._integrate_to(self.now)
            before = float(self.u[index])
            self._applied.append(
                _Applied(
                    self.current_key,
                    index,
                    value,
                    before,
                    self.t_state,
                    self.x.copy(),
                    self._next_record,
                    len(self._records_t),
                )
            )
            self._in_force[index] = self._applied[-1]
            self.u[index] = value

        return apply
