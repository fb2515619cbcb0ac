"""The agent's analysis without the bus (``wncs analyze``): judge a scenario's control-path delays
against the loops' bounds (seed 000, III.E step 2) and negotiate the periods (step 3), writing the
same ``wncsca`` section a run's ``summary.json`` has, and the Fig. 10-style plot of the search.

Delays come from ``--delays loop=value,...`` or, by default, from the scenario itself: wired loops
their ``tau_d + tau_a``, loops over a gateway the estimate the agent is configured to use from the
gateway's initial configuration, with its delay distributions (the chance method judges by
them; every method's assignment gets each loop's jitter margin, :mod:`agents.wncsca.jitter`).
The decision's ``subject`` says what was judged ("the scenario's initial configuration" or "the
given delays": there is no gateway proposal to number), and with a WSN ``energy`` holds the
projected network lifetime of the assignment against the benchmark periods over the network's
initial routes, as the agent computes it after a negotiation
(:meth:`agents.wncsca.coordinator.Coordinator.energy`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agents.wncsca.bounds import delay_bounds
from agents.wncsca.config import ESTIMATES, WncscaConfig
from agents.wncsca.coordinator import Coordinator, assign
from agents.wncsca.decision import control_path_delays, decide
from agents.wncsca.guarantee import judge_by_risk, path_laws
from agents.wncsca.jitter import loop_margins
from agents.wncsca.plots import fig10
from bus_schemas.bodies import PathConfig
from gateway.carrier import PathCarrier
from runtime.direct import loop_model
from scenario.views import agent_spec, carrier_spec

__all__ = ["analyze", "parse_delays"]


def parse_delays(text: str, loops: Any) -> dict[str, float]:
    """``"level=0.17,temperature=0.1"`` -> ``{"level": 0.17, "temperature": 0.1}``.

    Raises
    ------
    ValueError
        Naming the item that is malformed, names an unknown loop, or is negative.
    """
    out: dict[str, float] = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--delays: {item!r} is not loop=value")
        if name not in loops:
            raise ValueError(f"--delays: unknown loop {name!r} (loops: {sorted(loops)})")
        try:
            delay = float(value)
        except ValueError:
            raise ValueError(f"--delays: {name}: not a number: {value!r}") from None
        if not delay >= 0:
            raise ValueError(f"--delays: {name}: a delay must be >= 0, got {value}")
        out[name] = delay
    return out


def _network_paths(scenario: Any, name: str) -> dict[str, PathConfig]:
    """The paths as network ``name`` would first propose them."""
    if scenario.is_wireless(name):
        configuration = PathCarrier.from_spec(carrier_spec(scenario, name)).configuration(0)
        return {p: PathConfig.model_validate(e) for p, e in configuration.items()}
    paths: dict[str, PathConfig] = {}
    for loop, lp in scenario.loops.items():
        if lp.network == name:
            d = lp.tau_d + lp.tau_a
            est = {"timestamps": d, "ping": d, "hops": d}
            paths[f"{loop}.sensor"] = PathConfig(hops=0, estimates=est)
    return paths


def _scenario_paths(scenario: Any) -> dict[str, PathConfig]:
    """The paths as the scenario's networks would first propose them."""
    paths: dict[str, PathConfig] = {}
    for name in scenario.carriers():
        paths.update(_network_paths(scenario, name))
    return paths


def _energy(
    scenario: Any, model: Any, config: WncscaConfig, periods: Mapping[str, float]
) -> list[dict[str, Any]]:
    """Per WSN carrying loops, the projected network lifetime under ``periods`` against the
    benchmark periods over the network's initial routes (:meth:`Coordinator.energy`, as the
    agent computes it after a negotiation); the entries of ``summary.json``'s ``wncsca.energy``."""
    core = Coordinator(agent_spec(scenario, config=config), model)
    core.control_periods = dict(periods)
    out = []
    for name in scenario.carriers():
        if scenario.is_wireless(name) and core.carried.get(name):
            energy = core.energy(name, _network_paths(scenario, name))
            if energy is not None:
                out.append({"t": 0.0, "network": name, **energy})
    return out


def analyze(
    scenario: Any,
    *,
    delays: Mapping[str, float] | None = None,
    method: str | None = None,
    out: Path | None = None,
) -> dict[str, Any]:
    """Decision and periods for ``scenario`` (its agent's configuration, or the defaults).

    Returns the ``summary.json`` contents (with a ``wncsca`` section) and, with ``out``, writes
    ``summary.json`` and ``search.png`` there.
    """
    name = scenario.agent_node()
    config = scenario.nodes[name] if name else WncscaConfig()
    if method is not None:
        config = config.model_copy(update={"method": method})
    t0 = time.perf_counter()
    model = loop_model(scenario, config)
    bounds = delay_bounds(model)
    t_bounds = time.perf_counter() - t0
    if delays is None:
        paths = _scenario_paths(scenario)
    else:
        missing = [n for n in model.loops if n not in delays]
        if missing:
            raise ValueError(f"--delays: no delay for loop(s) {missing}")
        # the given delays as the configured estimate (``quantile``: a constant delay, as hops)
        key = config.estimate if config.estimate in ESTIMATES else "hops"
        paths = {f"{n}.sensor": PathConfig(hops=0, estimates={key: d}) for n, d in delays.items()}
    t1 = time.perf_counter()
    laws = path_laws(paths, model.loops)
    risk = None
    if config.method == "chance":
        known, used = control_path_delays(paths, model.loops, config.estimate)
        down = [n for n, d in known.items() if d is None]
        if down:
            decision = decide(None, paths, bounds, config.estimate, quantile=config.confidence)
        else:
            decision, risk = judge_by_risk(
                model,
                laws,
                {n: float(d or 0.0) for n, d in known.items()},
                None,
                used,
                seed=scenario.seed,
                carried=model.loops,
                with_bounds=True,
            )
    else:
        decision = decide(None, paths, bounds, config.estimate, quantile=config.confidence)
    entry = {
        "t": 0.0,
        **decision.as_dict(),
        # what was judged (the timeline prints the subject): there is no gateway proposal here
        "subject": "the given delays"
        if delays is not None
        else "the scenario's initial configuration",
    }
    assignments = []
    energy: list[dict[str, Any]] = []
    margins = None
    if decision.verdict == "accept":
        result = risk or assign(model, decision.delays, _hops(paths))
        margins = result.extra.get("jitter_margin") or loop_margins(
            model, result.periods, decision.delays, laws
        )
        search = result.as_dict()
        assignments.append(
            {
                "t": 0.0,
                "mode": "startup",
                "periods": dict(result.periods),
                "control_periods": dict(result.periods),
                "closed": {n: True for n in model.loops},
                "method": result.method,
                "overshoot_pct": search["overshoot_pct"],
                "search": search,
            }
        )
        energy = _energy(scenario, model, config, result.periods)
        if out is not None:
            fig10(result, Path(out) / "search.png", limit=config.overshoot_limit)
    entry["decision_time_s"] = time.perf_counter() - t1
    summary = {
        "scenario": scenario.name,
        "analysis": True,
        "wncsca": {
            "bounds": {
                n: {"tau_d_max": b.tau_d_max, "overshoot_pct": b.overshoot_pct}
                for n, b in bounds.items()
            },
            "bounds_time_s": t_bounds,
            "decisions": [entry],
            "assignments": assignments,
            "energy": energy,
            "jitter_margin": margins,
            "simulations": model.simulations,
        },
    }
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def _hops(paths: Mapping[str, PathConfig]) -> dict[str, float]:
    out: dict[str, float] = {}
    for path, entry in paths.items():
        loop = path.rpartition(".")[0]
        out[loop] = out.get(loop, 0.0) + max(1, entry.hops)
    return out
