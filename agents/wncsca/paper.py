"""The paper's successive approximation of the longest sampling periods (seed 000, III.E step 3).

For one loop, with every other loop fixed at its current period and every loop at its control-path
delay (step 3a): start from the ideal period ``tau_si`` and double it until the overshoot limit is
violated; then halve the last interval, keep the half whose end is acceptable, and go on halving
("increasing/decreasing tau_s") until an acceptable trial is within ``eps_OS`` of the limit
(Fig. 10: trials 2, 4, 8, then 7 tau_si). Loops alternate, each searched with the others at
their latest periods (steps 3b-3c), until every loop is within the limit and a loop's period
changed by less than ``eps_L`` since its previous search, or every loop has been searched and all
are within the limit (the paper stops at point D on that ground, III.E worked example) (3d).

Nothing assumes the overshoot is monotone in the period: a search's result is always a period
whose overshoot was *checked* within the limit, and the joint result is checked once more.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

from agents.wncsca.assignment import Assignment, Trial
from agents.wncsca.model import LoopModel

__all__ = ["successive_approximation", "search_loop"]


def _grid(value: float, res: float) -> float:
    return round(round(value / res) * res, 12)


def search_loop(
    model: LoopModel,
    loop: str,
    periods: Mapping[str, float],
    delays: Mapping[str, float],
    trace: list[Trial],
    alternation: int = 0,
) -> tuple[float, float] | None:
    """Longest acceptable period of ``loop`` with the other loops at ``periods`` (step 3a).

    Returns ``(period, overshoot_pct)`` of the last acceptable trial, or ``None`` when even the
    shortest period tried violates the limit. Every trial is appended to ``trace``.
    """
    cfg = model.config
    limit, eps, res = cfg.overshoot_limit, cfg.os_tolerance, cfg.resolution
    trials = 0

    def check(period: float, step: str) -> float:
        nonlocal trials
        trials += 1
        trial = {**periods, loop: period}
        ev = model.evaluate(trial, delays)
        value = ev.overshoot_pct[loop]
        trace.append(
            Trial(alternation, loop, step, period, ev.periods, ev.overshoot_pct, value <= limit)
        )
        return value

    p = _grid(cfg.ideal_period.get(loop, model.benchmark[loop]), res)
    value = check(p, "start")
    if value > limit:  # the ideal period itself is too slow under these delays: halve downwards
        hi = p
        while value > limit:
            p = _grid(p / 2, res)
            if p < res or p >= hi or trials >= cfg.max_trials:
                return None
            hi_candidate, value = p, check(p, "down")
            if value > limit:
                hi = hi_candidate
        lo, os_lo = p, value
    else:
        lo, os_lo = p, value
        while True:  # double until the limit is violated
            p = _grid(min(2 * lo, cfg.max_period), res)
            if p <= lo:
                return lo, os_lo  # max_period reached without a violation
            value = check(p, "double")
            if value > limit:
                hi = p
                break
            lo, os_lo = p, value
            if trials >= cfg.max_trials:
                return lo, os_lo
    while os_lo < limit - eps and trials < cfg.max_trials:  # halve the last interval
        mid = _grid((lo + hi) / 2, res)
        if mid <= lo or mid >= hi:
            break
        value = check(mid, "halve")
        if value <= limit:
            lo, os_lo = mid, value
        else:
            hi = mid
    return lo, os_lo


def successive_approximation(
    model: LoopModel, delays: Mapping[str, float], order: list[str] | None = None
) -> Assignment:
    """The paper's method for every loop of ``model`` under control-path ``delays``."""
    t0 = time.perf_counter()
    sims0 = model.simulations
    cfg = model.config
    limit = cfg.overshoot_limit
    order = list(order or cfg.order or model.loops)
    unknown = [n for n in order if n not in model.loops]
    if unknown:
        raise ValueError(f"order: unknown loop(s) {unknown} (loops: {list(model.loops)})")
    order += [n for n in model.loops if n not in order]
    delays = {n: float(delays.get(n, 0.0)) for n in model.loops}
    periods = dict(model.benchmark)
    trace: list[Trial] = []
    found: dict[str, float] = {}
    converged = False
    feasible = True
    reason = ""
    alternation = 0
    for alternation in range(1, cfg.max_alternations + 1):
        for loop in order:
            result = search_loop(model, loop, periods, delays, trace, alternation)
            if result is None:
                feasible = False
                reason = (
                    f"{loop}: no period down to {cfg.resolution:g} keeps the overshoot within "
                    f"{limit:g} % with the other loops at {_fmt(periods, loop)}"
                )
                break
            previous = found.get(loop)
            periods[loop] = found[loop] = result[0]
            joint = model.evaluate(periods, delays)
            all_ok = joint.ok(limit)
            small_change = previous is not None and abs(result[0] - previous) < cfg.period_tolerance
            if all_ok and (small_change or len(found) == len(order)):
                converged = True
                break
        if converged or not feasible:
            break
    final = model.evaluate(periods, delays)
    trace.append(
        Trial(
            alternation, None, "verify", None, final.periods, final.overshoot_pct, final.ok(limit)
        )
    )
    if feasible and not final.ok(limit):
        # out of alternations with a loop over the limit: fall back to the jointly checked trial
        # that saves the most samples, else to the benchmark periods
        candidates = [t for t in trace if all(v <= limit for v in t.overshoot_pct.values())]
        if candidates:
            best = max(candidates, key=lambda t: -sum(1 / p for p in t.periods.values()))
            periods = dict(best.periods)
            reason = "no convergence: the best jointly acceptable trial is assigned"
        else:
            feasible = False
            reason = "no jointly acceptable periods found"
    if not feasible:
        periods = dict(model.benchmark)
    final = model.evaluate(periods, delays)
    return Assignment(
        method="paper",
        delays=delays,
        periods=periods,
        overshoot_pct=final.overshoot_pct,
        feasible=feasible and final.ok(limit),
        converged=converged,
        alternations=alternation,
        trace=trace,
        simulations=model.simulations - sims0,
        decision_time_s=time.perf_counter() - t0,
        reason=reason,
    )


def _fmt(periods: Mapping[str, float], skip: str) -> str:
    return ", ".join(f"{n}={p:g}" for n, p in periods.items() if n != skip) or "-"
