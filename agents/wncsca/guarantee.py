"""The chance method end to end (issue 14): a proposal's delay distributions read and checked,
each loop's risk bound, the paper's period search on the risk, the non-linear check, and the
probability reported with its interval.

:func:`path_laws` turns a proposal's paths into each loop's :class:`~agents.wncsca.chance.LoopLaw`
(the sensor path's distribution, and the actuator path's when it is on the WSN too: the shapes
are combined by sampling their sum, the losses as independent); :func:`risk_bounds` is III.E
step 2 on the risk (the largest *mean* control-path delay with the proposal's shape that keeps
``P(overshoot <= limit) >= confidence`` at the benchmark periods); :func:`chance_periods` is step
3 on the risk, then checked: the realizations replayed on the non-linear model correct the
linear prediction where the choice lies, and the search is repeated with the correction until the
checked choice holds with every loop in the paper's band ``[limit - eps_OS, limit]`` or the
choice no longer changes (at most :data:`ROUNDS` repeats; the last choice that held its own check
is kept).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import ValidationError

from agents.wncsca.assignment import Assignment
from agents.wncsca.bounds import DelayBound, largest_delay
from agents.wncsca.chance import ChanceModel, LoopLaw
from agents.wncsca.decision import ProposalError
from agents.wncsca.paper import successive_approximation
from bus_schemas import DelayDistribution

__all__ = ["ROUNDS", "path_laws", "risk_bounds", "chance_periods"]

ROUNDS = 3
"""Searches on corrected predictions after the first, at most."""

_SHAPE_DRAWS = 20000


def path_laws(paths: Any, loops: tuple[str, ...]) -> dict[str, LoopLaw]:
    """Each loop's delay law from the ``distribution`` of its paths (a loop whose paths carry
    none gets a constant delay without loss: the gateway predicts none for a down path).

    Raises
    ------
    ProposalError
        A malformed distribution, naming the path and the field.
    """
    if not isinstance(paths, Mapping):
        raise ProposalError("paths: missing or not a mapping")
    out: dict[str, LoopLaw] = {}
    for loop in loops:
        dists = []
        for direction in ("sensor", "actuator"):
            entry = paths.get(f"{loop}.{direction}")
            raw = entry.get("distribution") if isinstance(entry, Mapping) else None
            if raw is None:
                continue
            try:
                dists.append(DelayDistribution.model_validate(raw))
            except ValidationError as err:
                first = err.errors()[0]
                where = ".".join(str(p) for p in first["loc"])
                where = f".{where}" if where else ""
                raise ProposalError(
                    f"paths.{loop}.{direction}.distribution{where}: {first['msg']}"
                ) from None
        if not dists:
            out[loop] = LoopLaw()
        elif len(dists) == 1:
            d = dists[0]
            out[loop] = LoopLaw(d.probabilities, d.delays, d.loss)
        else:  # sensor and actuator paths in series: the law of the sum, losses independent
            rng = np.random.default_rng(0)
            total = sum(
                np.interp(rng.random(_SHAPE_DRAWS), d.probabilities, d.delays) for d in dists
            )
            probs = dists[0].probabilities
            keep = 1.0
            for d in dists:
                keep *= 1.0 - d.loss
            out[loop] = LoopLaw(
                tuple(probs),
                tuple(float(v) for v in np.maximum.accumulate(np.quantile(total, probs))),
                1.0 - keep,
            )
    return out


def risk_bounds(model: ChanceModel) -> dict[str, DelayBound]:
    """Every loop's largest mean control-path delay within the risk, at the benchmark periods
    (the other loops at zero delay, as the paper's bounds)."""
    return {loop: largest_delay(model, loop) for loop in model.loops}


def chance_periods(model: ChanceModel, delays: Mapping[str, float]) -> Assignment:
    """The paper's search on the risk, checked on the non-linear model and repeated on the
    corrected prediction (module docstring); the assignment's ``extra`` holds the guarantee."""
    t0 = time.perf_counter()
    sims0 = model.simulations
    cfg = model.config
    limit = cfg.overshoot_limit
    checks: list[dict[str, Any]] = []
    band = limit - cfg.os_tolerance
    result = successive_approximation(model, delays)  # type: ignore[arg-type]
    held_result: Assignment | None = None
    for _ in range(1 + ROUNDS):
        checks.append(model.check(result.periods, delays))
        corrected = model.evaluate(result.periods, delays)
        if corrected.ok(limit):
            held_result = result
            if all(v >= band for v in corrected.overshoot_pct.values()):
                break  # every loop in the paper's band [limit - eps_OS, limit]: done
        again = successive_approximation(model, delays)  # type: ignore[arg-type]
        if again.periods == result.periods:
            break
        result = again
    if held_result is not None and not model.evaluate(result.periods, delays).ok(limit):
        result = held_result  # the last choice that held on its own check
    final = model.evaluate(result.periods, delays)
    held = final.ok(limit)
    result.method = "chance"
    result.overshoot_pct = dict(final.overshoot_pct)
    result.feasible = result.feasible and held
    if not held:
        result.periods = dict(model.benchmark)
        result.reason = (
            f"the checked risk overshoot stays above {limit:g} % after {ROUNDS} corrections; "
            "benchmark periods"
        )
    result.simulations = model.simulations - sims0
    result.decision_time_s = time.perf_counter() - t0
    result.extra["guarantee"] = {
        "confidence": cfg.confidence,
        "realizations": model.linear.R,
        "exceedances_allowed": model.k_max,
        "probability": model.probability(result.periods, delays),
        "offsets": dict(model.offsets),
        "checks": checks,
        "laws": {
            n: {
                "mean": law.mean,
                "loss": law.loss,
                "p95": float(np.interp(0.95, law.probabilities, law.delays)),
            }
            for n, law in sorted(model.laws.items())
        },
    }
    return result
