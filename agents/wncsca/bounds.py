"""Largest tolerable control-path delay of each loop at the benchmark sampling periods (seed 000,
III.C "adding time delay elements" and III.E step 2), by bisection on the overshoot limit.

The bound of a loop is found with every other loop at its benchmark period and zero delay. The
overshoot need not be monotone in the delay, so the bound is the largest delay *checked* to be
within the limit, never an interpolation. Bounds are cached per plant model (the model's
fingerprint covers plants, controllers, loops, the test and the phase handling).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from agents.wncsca.model import LoopModel

__all__ = ["DelayBound", "delay_bounds", "largest_delay", "clear_cache"]

_CACHE: dict[tuple[str, float, float, float], dict[str, DelayBound]] = {}


@dataclass(frozen=True)
class DelayBound:
    """``tau_d_max`` of one loop (time units) and the overshoot there; ``trials`` lists every
    ``(delay, overshoot_pct)`` tried, in order."""

    loop: str
    tau_d_max: float
    overshoot_pct: float
    trials: tuple[tuple[float, float], ...] = field(default=())


def delay_bounds(model: LoopModel) -> dict[str, DelayBound]:
    """Every loop's largest tolerable delay at the benchmark periods (cached per model)."""
    cfg = model.config
    key = (model.fingerprint, cfg.overshoot_limit, cfg.delay_resolution, cfg.max_delay)
    if key not in _CACHE:
        _CACHE[key] = {loop: largest_delay(model, loop) for loop in model.loops}
    return _CACHE[key]


def clear_cache() -> None:
    """Forget every cached bound (tests)."""
    _CACHE.clear()


def _grid(value: float, res: float) -> float:
    return round(round(value / res) * res, 12)


def largest_delay(
    model: LoopModel,
    loop: str,
    periods: Mapping[str, float] | None = None,
    delays: Mapping[str, float] | None = None,
    resolution: float | None = None,
) -> DelayBound:
    """Largest control-path delay of ``loop`` checked to keep its overshoot within the limit,
    with the loops at ``periods`` (default: benchmark) and the other loops at ``delays``
    (default 0; ``loop``'s own entry is ignored).

    Doubling from the loop's period (at least 16 grid steps) until the limit is violated, then
    bisection on a grid of ``resolution`` (default: the model's ``delay_resolution``) down to one
    grid step. ``tau_d_max`` is a grid value within the limit whose next larger trial violated it
    (or ``max_delay``); when even zero delay violates, it is 0 with that overshoot (> limit).
    Seed 000, III.C ("adding time delay elements"), III.D (Fig. 9) and III.E step 2.
    """
    cfg = model.config
    res = cfg.delay_resolution if resolution is None else resolution
    if not res > 0:
        raise ValueError(f"resolution must be > 0, got {res}")
    limit = cfg.overshoot_limit
    periods = dict(periods or {})
    base = {n: float((delays or {}).get(n, 0.0)) for n in model.loops}
    trials: list[tuple[float, float]] = []

    def overshoot(delay: float) -> float:
        value = model.evaluate(periods, {**base, loop: delay}).overshoot_pct[loop]
        trials.append((delay, value))
        return value

    os0 = overshoot(0.0)
    if os0 > limit:
        return DelayBound(loop, 0.0, os0, tuple(trials))
    lo, os_lo = 0.0, os0
    hi = _grid(max(float(periods.get(loop, model.benchmark[loop])), 16 * res), res)
    while True:  # grow until the limit is violated
        value = overshoot(hi)
        if value > limit:
            break
        lo, os_lo = hi, value
        if hi >= cfg.max_delay:
            return DelayBound(loop, lo, os_lo, tuple(trials))
        hi = _grid(min(2 * hi, cfg.max_delay), res)
    while hi - lo > res * (1 + 1e-9):
        mid = _grid((lo + hi) / 2, res)
        if mid <= lo or mid >= hi:
            break
        value = overshoot(mid)
        if value <= limit:
            lo, os_lo = mid, value
        else:
            hi = mid
    return DelayBound(loop, lo, os_lo, tuple(trials))
