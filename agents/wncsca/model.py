"""The agent's closed-loop model: a scenario's plants and controllers with every loop carried by
a wired path of constant delay, under the agent's set-point test, simulated by the ``direct``
engine (seed 000, III.C-III.E: the WNCSCA judges a configuration by simulating its loops).

:meth:`LoopModel.overshoots` is the one question every search asks: "with these sampling periods
and these control-path delays, how far does each loop overshoot its set-point step?". The answer
is the worst case over the step's phase relative to the sampling instants (or the paper's fixed
phase), memoised, since the searches revisit trials.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from agents.wncsca.config import WncscaConfig
from runtime.direct import simulate
from runtime.record import loop_metrics
from runtime.time import to_ticks, to_units

__all__ = ["LoopModel", "Evaluation"]

_NET = "wncsca_model_network"
_OPERATOR = "wncsca_model_operator"


@dataclass(frozen=True)
class Evaluation:
    """Overshoots of one trial: per loop, the worst over the phases tried (%; ``inf`` when the
    simulation diverged), and per phase."""

    periods: dict[str, float]
    delays: dict[str, float]
    overshoot_pct: dict[str, float]
    by_phase: tuple[dict[str, float], ...]

    def ok(self, limit: float, loops: Any = None) -> bool:
        """Every loop (or those named) within ``limit``."""
        names = self.overshoot_pct if loops is None else loops
        return all(self.overshoot_pct[n] <= limit for n in names)


class LoopModel:
    """A scenario's loops as the agent simulates them.

    Parameters
    ----------
    scenario : Scenario
        Any validated scenario: its plants, controllers and loops are used; its networks, agent
        and schedule are replaced by wired paths and the agent's set-point test.
    config : WncscaConfig
        The agent's configuration (test, phase handling).
    """

    def __init__(self, scenario: Any, config: WncscaConfig) -> None:
        from runtime.scenario import Scenario  # the scenario module imports the agent's config

        self._scenario_type = Scenario
        self.config = config
        # loops of multi-loop controllers on links are governed by their update period instead
        self.loops: tuple[str, ...] = tuple(scenario.simulated_loops())
        self.benchmark = {n: scenario.loops[n].tau_s for n in self.loops}
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
        self._base = {
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
            json.dumps(
                {"model": self._base, "phase": config.phase, "phases": config.phases},
                sort_keys=True,
                default=str,
            ).encode()
        ).hexdigest()[:16]
        self._memo: dict[tuple, Evaluation] = {}
        self.simulations = 0

    def evaluate(self, periods: Mapping[str, float], delays: Mapping[str, float]) -> Evaluation:
        """Overshoot of every loop with these periods (default: benchmark) and control-path
        delays (default: 0), each in time units."""
        per = {n: float(periods.get(n, self.benchmark[n])) for n in self.loops}
        dly = {n: float(delays.get(n, 0.0)) for n in self.loops}
        for n, p in per.items():
            if to_ticks(p) < 1:
                raise ValueError(f"period of loop {n!r} is shorter than one tick: {p}")
            if not dly[n] >= 0:
                raise ValueError(f"delay of loop {n!r} must be >= 0, got {dly[n]}")
        key = (
            tuple(to_ticks(per[n]) for n in self.loops),
            tuple(to_ticks(dly[n]) for n in self.loops),
        )
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        n_phases = 1 if self.config.phase == "fixed" else self.config.phases
        by_phase = tuple(self._simulate(per, dly, k, n_phases) for k in range(n_phases))
        worst = {n: max(ph[n] for ph in by_phase) for n in self.loops}
        result = Evaluation(per, dly, worst, by_phase)
        self._memo[key] = result
        return result

    def scenario_at(
        self,
        periods: Mapping[str, float] | None = None,
        delays: Mapping[str, float] | None = None,
        phase: tuple[int, int] | None = None,
    ) -> Any:
        """The model as a :class:`~runtime.scenario.Scenario`: wired loops with these periods
        (default benchmark) and delays (default 0); with ``phase=(k, n)`` every test step is
        moved to ``k/n`` of its loop's period after a sampling instant."""
        periods = periods or {}
        delays = delays or {}
        data = json.loads(json.dumps(self._base))
        for name, lp in data["loops"].items():
            lp["tau_s"] = float(periods.get(name, self.benchmark[name]))
            lp["tau_d"] = float(delays.get(name, 0.0))
        if phase is not None:
            k, n = phase
            # samples at 0, P, 2P, ...: phase 0 is a step at a sampling instant
            for step in data["setpoints"]:
                p = to_ticks(data["loops"][step["loop"]]["tau_s"])
                t = to_ticks(step["t"])
                step["t"] = to_units((t // p) * p + (k * p) // n)
        return self._scenario_type.model_validate(data)

    def _simulate(
        self, periods: dict[str, float], delays: dict[str, float], k: int, n: int
    ) -> dict[str, float]:
        phase = (k, n) if self.config.phase == "worst" else None
        scenario = self.scenario_at(periods, delays, phase)
        self.simulations += 1
        rec = simulate(scenario)
        diverged = {
            name
            for name, plant in rec.plants.items()
            if not all(math.isfinite(v) for row in plant.x for v in row)
        }
        out = {}
        for name in self.loops:
            os_pct = loop_metrics(rec, name)["overshoot_pct"]
            bad = os_pct is None or not math.isfinite(os_pct)
            out[name] = math.inf if bad or rec.loops[name].plant in diverged else os_pct
        return out
