"""What a sampling-period search returns: the periods, their predicted overshoots, and the trace.

Shared by the paper's successive approximation (:mod:`agents.wncsca.paper`) and the fast method
(:mod:`agents.wncsca.fast`), so the agent, ``wncs analyze`` and the summaries treat them alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["Trial", "Assignment"]


@dataclass(frozen=True)
class Trial:
    """One simulated candidate: which loop was searched (``None``: a joint check), its trial
    period, every loop's period and worst-case overshoot, and whether the searched loop (or, for a
    joint check, every loop) was within the limit."""

    alternation: int
    loop: str | None
    step: str  # start | double | halve | down | check | verify
    period: float | None
    periods: dict[str, float]
    overshoot_pct: dict[str, float]
    ok: bool

    def as_dict(self) -> dict[str, Any]:
        return {
            "alternation": self.alternation,
            "loop": self.loop,
            "step": self.step,
            "period": self.period,
            "periods": dict(self.periods),
            "overshoot_pct": {n: _json_float(v) for n, v in self.overshoot_pct.items()},
            "ok": self.ok,
        }


@dataclass
class Assignment:
    """Sampling periods chosen under given delays.

    ``feasible`` is False when no period set within the limit was found (``periods`` then holds
    the benchmark periods and ``reason`` says why); ``overshoot_pct`` is the checked worst case at
    ``periods``.
    """

    method: str
    delays: dict[str, float]
    periods: dict[str, float]
    overshoot_pct: dict[str, float]
    feasible: bool
    converged: bool
    alternations: int
    trace: list[Trial] = field(default_factory=list)
    simulations: int = 0
    decision_time_s: float = 0.0
    reason: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "delays": dict(self.delays),
            "periods": dict(self.periods),
            "overshoot_pct": {n: _json_float(v) for n, v in self.overshoot_pct.items()},
            "feasible": self.feasible,
            "converged": self.converged,
            "alternations": self.alternations,
            "simulations": self.simulations,
            "decision_time_s": self.decision_time_s,
            "reason": self.reason,
            "trace": [t.as_dict() for t in self.trace],
            **self.extra,
        }


def _json_float(value: float) -> float | None:
    return None if value != value or value in (float("inf"), float("-inf")) else float(value)
