"""The coordination agent's simulator, built once from a scenario (seed 000, III.C-III.E).

:class:`ScenarioTrials` is the scenario's plants and controllers with every judged loop carried
by a wired path of constant delay, under the agent's set-point test: validated once, then for
each trial only the periods, delays and step times change (a copy of the model with those fields
replaced, no re-validation: they are checked by :meth:`agents.wncsca.model.LoopModel.evaluate`),
and the copy runs on the engine it is handed (``simulate``: :func:`runtime.direct.simulate`,
which builds the agent with this module, so the engine is passed in rather than imported).
:func:`loop_model` and :func:`coordinator` hand it to the agent's cores; the agent's node kind
(:func:`agents.wncsca.behaviour.build`) and :func:`runtime.direct.loop_model` pass the engine.

The scenario is taken as it is given (a :class:`runtime.scenario.Scenario`; this module sits
below the scenario layer, so it does not import it): the trial scenario is validated by the
given scenario's own class.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any

from agents.wncsca.config import WncscaConfig
from agents.wncsca.coordinator import Coordinator
from agents.wncsca.model import LoopModel
from core.record import RunRecord, Simulate
from core.time import to_ticks, to_units

__all__ = ["ScenarioTrials", "Simulate", "loop_model", "coordinator", "agent_config"]

Scenario = Any
"""A validated :class:`runtime.scenario.Scenario` (not imported: it is a layer above)."""


_NET = "wncsca_model_network"
_OPERATOR = "wncsca_model_operator"


class ScenarioTrials:
    """The agent's model of ``scenario`` under ``config``'s test (see the module docstring).

    Raises
    ------
    ValueError
        A test step names an unknown loop or falls after the test's end, or a judged loop has
        no step (the agent judges a loop by the overshoot of its step).
    """

    def __init__(self, scenario: Scenario, config: WncscaConfig, *, simulate: Simulate) -> None:
        self._simulate = simulate
        self.loops: tuple[str, ...] = tuple(scenario.simulated_loops())
        self.benchmark = {n: float(scenario.loops[n].tau_s) for n in self.loops}  # type: ignore[arg-type]
        if config.test is not None:
            steps = [s.model_dump() for s in config.test.setpoints]
            end_time = config.test.end_time
        else:
            steps = [s.model_dump() for s in scenario.setpoints]
            end_time = scenario.end_time
        for i, step in enumerate(steps):
            if step["loop"] not in self.loops:
                raise ValueError(
                    f"test.setpoints[{i}].loop: unknown loop {step['loop']!r} "
                    f"(loops: {list(self.loops)})"
                )
            if step["t"] > end_time:
                raise ValueError(f"test.setpoints[{i}].t: {step['t']} is after end_time {end_time}")
        stepped = {s["loop"] for s in steps}
        missing = [n for n in self.loops if n not in stepped]
        if missing:
            raise ValueError(
                f"test.setpoints: no set-point step for loop(s) {missing}; the agent judges a "
                "loop by the overshoot of its step"
            )
        data = scenario.model_dump()
        plants = {scenario.loops[n].plant for n in self.loops}
        controllers = {scenario.loops[n].controller for n in self.loops}
        nodes = {n: cfg for n, cfg in data["nodes"].items() if n in plants | controllers}
        nodes[_NET] = {"kind": "network"}
        nodes[_OPERATOR] = {"kind": "operator"}
        loops = {}
        for n, lp in data["loops"].items():
            if n not in self.loops:
                continue
            loops[n] = {
                **lp,
                "network": _NET,
                "sensor_node": None,
                "actuator_node": None,
                "tau_d": 0.0,
                "tau_a": 0.0,
            }
        base = {
            "name": f"{scenario.name}.wncsca_model",
            "time_unit": scenario.time_unit,
            "end_time": end_time,
            "seed": scenario.seed,
            "nodes": nodes,
            "loops": loops,
            "setpoints": steps,
            "disturbances": [],
        }
        self.fingerprint = hashlib.sha256(
            json.dumps(base, sort_keys=True, default=str).encode()
        ).hexdigest()[:16]
        self.scenario = type(scenario).model_validate(base)  # validated once

    def scenario_at(
        self,
        periods: Mapping[str, float] | None = None,
        delays: Mapping[str, float] | None = None,
        phase: tuple[int, int] | None = None,
    ) -> Scenario:
        """The model with these periods (default benchmark) and delays (default 0); with
        ``phase=(k, n)`` every test step is moved to ``k/n`` of its loop's period after a
        sampling instant (samples at 0, P, 2P, ...: phase 0 is a step at a sampling instant)."""
        periods = periods or {}
        delays = delays or {}
        base = self.scenario
        loops = {
            name: lp.model_copy(
                update={
                    "tau_s": float(periods.get(name, self.benchmark[name])),
                    "tau_d": float(delays.get(name, 0.0)),
                }
            )
            for name, lp in base.loops.items()
        }
        steps = list(base.setpoints)
        if phase is not None:
            k, n = phase
            shifted = []
            for step in steps:
                p = to_ticks(loops[step.loop].tau_s)  # type: ignore[arg-type]
                t = to_ticks(step.t)
                shifted.append(step.model_copy(update={"t": to_units((t // p) * p + (k * p) // n)}))
            steps = shifted
        return base.model_copy(update={"loops": loops, "setpoints": steps})

    def run(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        phase: tuple[int, int] | None,
    ) -> RunRecord:
        """One trial on the direct engine."""
        return self._simulate(self.scenario_at(periods, delays, phase))

    def run_steps(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        steps: list[tuple[float, str, float]],
        end_time: float,
        traces: Mapping[str, list[float | None]] | None = None,
    ) -> RunRecord:
        """One trial on the direct engine with these set-point ``steps`` (``(t, loop, value)``,
        time units) instead of the test's, run to ``end_time``, with each loop's sensor-path
        delays replayed from ``traces`` (default: the constant ``delays``)."""
        trial = self.scenario_at(periods, delays, None)
        template = trial.setpoints[0]
        setpoints = [
            template.model_copy(update={"t": float(t), "loop": loop, "value": float(value)})
            for t, loop, value in steps
        ]
        update: dict[str, Any] = {"setpoints": setpoints, "end_time": float(end_time)}
        if traces is not None:
            update["nodes"] = _with_traces(trial, traces)
        return self._simulate(trial.model_copy(update=update))

    def run_replay(
        self,
        periods: Mapping[str, float],
        delays: Mapping[str, float],
        traces: Mapping[str, list[float | None]],
        phases: Mapping[tuple[int, str], int],
        denominator: int,
    ) -> RunRecord:
        """One trial on the direct engine with each loop's sensor-path delays replayed from
        ``traces`` (loop -> delay of each sample, ``None``: lost) and the step at ``(tick,
        loop)`` moved to ``phases[...] / denominator`` of its loop's period after a sampling
        instant (the realizations of :mod:`agents.wncsca.chance`)."""
        trial = self.scenario_at(periods, delays, None)
        steps = []
        for step in trial.setpoints:
            j = phases.get((to_ticks(step.t), step.loop))
            if j is not None:
                p = to_ticks(trial.loops[step.loop].tau_s)
                t = to_ticks(step.t)
                step = step.model_copy(
                    update={"t": to_units((t // p) * p + (j * p) // denominator)}
                )
            steps.append(step)
        nodes = _with_traces(trial, traces)
        return self._simulate(trial.model_copy(update={"setpoints": steps, "nodes": nodes}))


def _with_traces(trial: Scenario, traces: Mapping[str, list[float | None]]) -> dict[str, Any]:
    """The trial's nodes with its wired network replaying ``traces`` (validated: delays >= 0)."""
    net = type(trial.nodes[_NET]).model_validate({"kind": "network", "traces": dict(traces)})
    return {**trial.nodes, _NET: net}


def agent_config(scenario: Scenario) -> WncscaConfig:
    """The configuration of the scenario's agent node, or the defaults if it has none."""
    name = scenario.agent_node()
    return scenario.nodes[name] if name else WncscaConfig()  # type: ignore[return-value]


def loop_model(
    scenario: Scenario, config: WncscaConfig | None = None, *, simulate: Simulate
) -> LoopModel:
    """The agent's model of ``scenario`` (``config`` defaults to its agent's)."""
    config = config or agent_config(scenario)
    return LoopModel(ScenarioTrials(scenario, config, simulate=simulate), config)


def coordinator(
    scenario: Scenario, config: WncscaConfig | None = None, *, simulate: Simulate
) -> Coordinator:
    """The coordination agent of ``scenario``, handed its simulator."""
    config = config or agent_config(scenario)
    return Coordinator(scenario, loop_model(scenario, config, simulate=simulate), config)
