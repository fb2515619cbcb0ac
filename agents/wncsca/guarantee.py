"""The chance method end to end (issue 14): a proposal's delay distributions read and checked,
the paper's period search on the risk, the non-linear check, the jitter margins, and the
probability reported with its interval.

:func:`path_laws` turns a proposal's paths into each loop's :class:`~agents.wncsca.chance.LoopLaw`
(the sensor path's distribution, and the actuator path's when it is on the WSN too: the shapes
are combined by sampling their sum, the losses as independent). :func:`chance_periods` is III.E
step 3 on the risk, then checked: the realizations replayed on the non-linear model correct the
linear prediction where the choice lies, and the search is repeated with the correction until
the checked choice holds with every loop in the paper's band ``[limit - eps_OS, limit]`` or the
choice no longer changes (at most :data:`ROUNDS` repeats; the last choice that held its own
check is kept). :func:`judge_by_risk` is step 2 on the risk: a proposal is accepted when such
periods exist and every loop is within its jitter margin there (the paper's test at the
benchmark periods would reject a network on which a faster loop is safe). :func:`risk_bounds`
is the delay bound on the risk: the largest *mean* control-path delay, the proposal's shape
held, that keeps ``P(overshoot <= limit) >= confidence`` at the assigned periods.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.wncsca.assignment import Assignment
from agents.wncsca.bounds import largest_delay
from agents.wncsca.chance import ChanceModel, LoopLaw
from agents.wncsca.decision import Decision
from agents.wncsca.jitter import delay_variation, loop_margins
from agents.wncsca.model import LoopModel
from agents.wncsca.paper import successive_approximation
from bus_schemas.bodies import PathConfig

__all__ = [
    "ROUNDS",
    "BOUND_RESOLUTION",
    "path_laws",
    "risk_bounds",
    "chance_periods",
    "judge_by_risk",
]

ROUNDS = 3
"""Searches on corrected predictions after the first, at most."""

BOUND_RESOLUTION = 0.005
"""Coarsest grid of the risk bounds, time units."""

_SHAPE_DRAWS = 20000


def path_laws(paths: Mapping[str, PathConfig], loops: tuple[str, ...]) -> dict[str, LoopLaw]:
    """Each loop's delay law from the ``distribution`` of its paths (a loop whose paths carry
    none gets a constant delay without loss: the gateway predicts none for a down path)."""
    out: dict[str, LoopLaw] = {}
    for loop in loops:
        dists = []
        for direction in ("sensor", "actuator"):
            entry = paths.get(f"{loop}.{direction}")
            if entry is not None and entry.distribution is not None:
                dists.append(entry.distribution)
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


def risk_bounds(
    model: ChanceModel, periods: Mapping[str, float], delays: Mapping[str, float]
) -> dict[str, float]:
    """Each loop's largest mean control-path delay (the proposal's shape held, the other loops
    at their ``delays``) that keeps its risk overshoot within the limit at ``periods``: III.E
    step 2's bound on the risk, at the assigned periods (how much worse the network may get
    before they are unsafe), on a grid of at least :data:`BOUND_RESOLUTION`."""
    res = max(model.config.delay_resolution, BOUND_RESOLUTION)
    return {
        n: largest_delay(model, n, periods=periods, delays=delays, resolution=res).tau_d_max  # type: ignore[arg-type]
        for n in model.loops
    }


def period_caps(
    margins: Mapping[str, Mapping[str, Any]],
    laws: Mapping[str, LoopLaw],
    delays: Mapping[str, float],
) -> dict[str, float]:
    """Each loop's longest period whose delay variation stays within its jitter margin:
    ``(margin - spread) / (1 + bursts)`` (:func:`agents.wncsca.jitter.delay_variation` is
    ``spread + (1 + bursts) h``); 0 when the spread alone exceeds the margin."""
    out = {}
    for n, m in margins.items():
        law = laws.get(n, LoopLaw())
        _, spread = delay_variation(law, float(delays.get(n, 0.0)), 0.0)
        _, one = delay_variation(law, float(delays.get(n, 0.0)), 1.0)
        per_period = one - spread
        out[n] = max(0.0, (m["margin"] - spread) / per_period) * (1 - 1e-9)
    return out


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
        "model": model.draws.summary(),
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


def judge_by_risk(
    base: LoopModel,
    laws: Mapping[str, LoopLaw],
    known: Mapping[str, float],
    pid: int | None,
    used: Mapping[str, str],
    *,
    seed: int,
    carried: tuple[str, ...],
    with_bounds: bool = False,
) -> tuple[Decision, Assignment | None]:
    """III.E steps 2-3 on the risk: accept when periods exist that keep every loop's
    ``P(overshoot <= limit) >= confidence`` under its delay law (:func:`chance_periods`) and
    every loop's delay variation there is within its jitter margin
    (:func:`agents.wncsca.jitter.loop_margins`), else reject naming the loops; ``known`` are the
    loops' mean control-path delays, ``carried`` the loops the proposing network carries.
    ``with_bounds``: also each loop's risk bound at the assigned periods (:func:`risk_bounds`;
    ``wncs analyze`` asks for it, the live agent does not: it about doubles the decision time,
    and the periods were chosen so that the bound sits near the delay now)."""
    model = ChanceModel(base, laws, seed=seed)
    # the jitter margin does not depend on the period (continuous-time laws), the variation
    # does (one period of sample and hold, one per loss burst): a period cap for the search
    margins = loop_margins(base, model.benchmark, known, laws)
    model.period_caps = period_caps(margins, laws, known)
    model.check(model.benchmark, known)  # the linearisation corrected at the start point
    result = chance_periods(model, known)
    for n, m in margins.items():
        nominal, variation = delay_variation(
            laws.get(n, LoopLaw()), float(known.get(n, 0.0)), result.periods[n]
        )
        m.update(nominal_delay=nominal, variation=variation, ok=variation < m["margin"])
    guarantee = result.extra["guarantee"]
    limit, conf = base.config.overshoot_limit, base.config.confidence
    lines = []
    for n in base.loops:
        pr = guarantee["probability"][n]
        law = guarantee["laws"].get(n)
        what = (
            f"delay mean {law['mean']:.4g}, p95 {law['p95']:.4g}, loss {law['loss']:.2g}"
            if law is not None and n in carried
            else f"delay {known[n]:.4g}"
        )
        lines.append(
            f"{n}: P(overshoot <= {limit:g} %) = {pr['p']:.3f} "
            f"(95 % CI {pr['low']:.3f}-{pr['high']:.3f}) at period "
            f"{result.periods[n]:g} ({what})"
        )
    if not model.draws.exact:
        lines.append(model.draws.describe())
    result.extra["jitter_margin"] = margins
    unstable = [n for n in base.loops if n in margins and not margins[n]["ok"]]
    lines += [
        f"{n}: jitter margin {m['margin']:.4g} {'>' if m['ok'] else '<='} delay variation "
        f"{m['variation']:.4g} (nominal {m['nominal_delay']:.4g}, Kao-Lincoln)"
        for n, m in sorted(margins.items())
    ]
    if unstable:
        reasons = (
            f"outside the jitter margin of {unstable}: stability is not guaranteed under "
            "the proposal's delay variation, whatever the simulations say",
            *lines,
        )
        return Decision(pid, "reject", reasons, known, {}, used, tuple(unstable)), None
    if result.feasible:
        bounds = risk_bounds(model, result.periods, known) if with_bounds else {}
        if bounds:
            result.extra["risk_bounds"] = bounds
        lines += [
            f"{n}: at these periods its mean control-path delay may grow to {b:.4g} "
            f"(now {known[n]:.4g}) before the risk is exceeded"
            for n, b in sorted(bounds.items())
        ]
        return Decision(pid, "accept", tuple(lines), known, bounds, used), result
    offending = tuple(n for n in carried if guarantee["probability"][n]["p"] < conf) or carried
    reasons = (
        f"no sampling periods keep P(overshoot <= {limit:g} %) >= {conf:g}: "
        f"{result.reason or 'search infeasible'}",
        *lines,
    )
    return Decision(pid, "reject", reasons, known, {}, used, offending), None
