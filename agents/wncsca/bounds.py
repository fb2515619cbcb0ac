"""Largest tolerable control-path delay of each loop at the benchmark sampling periods (seed 000,
III.C "adding time delay elements" and III.E step 2), by bisection on the overshoot limit.

The bound of a loop is found with every other loop at its benchmark period and zero delay. The
overshoot need not be monotone in the delay, so the bound is the largest delay *checked* to be
within the limit, never an interpolation. Bounds are cached per plant model (the model's
fingerprint covers plants, controllers, loops, the test and the phase handling).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from agents.wncsca.model import LoopModel

__all__ = ["DelayBound", "delay_bounds", "clear_cache"]

_CACHE: dict[tuple, dict[str, DelayBound]] = {}


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
        _CACHE[key] = {loop: _bound(model, loop) for loop in model.loops}
    return _CACHE[key]


def clear_cache() -> None:
    """Forget every cached bound (tests)."""
    _CACHE.clear()


def _bound(model: LoopModel, loop: str) -> DelayBound:
    cfg = model.config
    limit, res = cfg.overshoot_limit, cfg.delay_resolution
    trials: list[tuple[float, float]] = []

    def overshoot(delay: float) -> float:
        value = model.evaluate({}, {loop: delay}).overshoot_pct[loop]
        trials.append((delay, value))
        return value

    os0 = overshoot(0.0)
    if os0 > limit:
        return DelayBound(loop, 0.0, os0, tuple(trials))  # not even the benchmark is acceptable
    lo, os_lo = 0.0, os0
    hi = max(model.benchmark[loop], 16 * res)
    while True:  # grow until the limit is violated
        value = overshoot(hi)
        if value > limit:
            break
        lo, os_lo = hi, value
        if hi >= cfg.max_delay:
            return DelayBound(loop, lo, os_lo, tuple(trials))
        hi = min(2 * hi, cfg.max_delay)
    while hi - lo > res:
        mid = round((lo + hi) / 2 / res) * res
        if mid <= lo or mid >= hi:
            break
        value = overshoot(mid)
        if value <= limit:
            lo, os_lo = mid, value
        else:
            hi = mid
    return DelayBound(loop, lo, os_lo, tuple(trials))
