"""Judging a proposed network configuration (seed 000, III.E steps 1-2).

Step 1: a loop's control-path delay is the chosen estimate (time stamps, ping, or hops x per-hop
delay) of its sensor path plus that of its actuator path when the actuator is on the WSN too.
Step 2: accept the configuration (conditionally: periods are negotiated next) when every loop's
delay is below its bound at the benchmark periods; otherwise reject it, naming each offending
loop, its delay and its bound. A proposal that does not make sense (a path of an unknown loop, a
negative or missing delay, a malformed entry) is *refused*: neither accepted nor rejected, so
nothing changes. The shape of a proposal (types, signs, the estimates' names) is its schema's
(:class:`bus_schemas.Proposal`, checked before the agent sees it); what the schema cannot know
(the loops, the directions) is checked here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.wncsca.bounds import DelayBound
from agents.wncsca.config import ESTIMATES
from bus_schemas.bodies import PathConfig

__all__ = [
    "Decision",
    "ProposalError",
    "control_path_delays",
    "decide",
    "path_delay",
]

_DIRECTIONS = ("sensor", "actuator")


class ProposalError(ValueError):
    """A proposal that cannot be judged; the message names the path and field."""


@dataclass(frozen=True)
class Decision:
    """The verdict on one proposal: ``accept``, ``reject`` or ``refuse`` (malformed)."""

    proposal: int | None
    verdict: str
    reasons: tuple[str, ...]
    delays: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, float] = field(default_factory=dict)
    estimates_used: Mapping[str, str] = field(default_factory=dict)
    offending: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "proposal": self.proposal,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "delays": dict(self.delays),
            "bounds": dict(self.bounds),
            "estimates_used": dict(self.estimates_used),
            "offending": list(self.offending),
        }


def path_delay(
    path: str, entry: PathConfig, preferred: str, quantile: float = 0.95
) -> tuple[float, str] | tuple[None, None]:
    """``(delay, estimate used)`` of one path entry; ``(None, None)`` when the path is down.

    ``preferred="quantile"``: the ``quantile`` of the entry's delay ``distribution`` (a
    constant delay the path's delivered packets exceed with probability ``1 - quantile``; with
    a sensor and an actuator path the sum of their quantiles, an upper bound of the quantile of
    the sum); without a distribution the paper's estimates are used, in their order.

    Raises
    ------
    ProposalError
        A routed path without any estimate.
    """
    if entry.hops < 0:
        return None, None
    if preferred == "quantile" and entry.distribution is not None:
        dist = entry.distribution
        return float(np.interp(quantile, dist.probabilities, dist.delays)), "quantile"
    given: dict[str, float | None] = {str(k): v for k, v in entry.estimates.items()}
    for name in [preferred, *(e for e in ESTIMATES if e != preferred)]:
        value = given.get(name)
        if value is not None:
            return float(value), name
    raise ProposalError(
        f"paths.{path}.estimates: a routed path ({entry.hops} hops) has no estimate"
    )


def control_path_delays(
    paths: Mapping[str, PathConfig], loops: tuple[str, ...], preferred: str, quantile: float = 0.95
) -> tuple[dict[str, float | None], dict[str, str]]:
    """Each loop's control-path delay (``None``: a path of the loop is down) and the estimate used.

    Raises
    ------
    ProposalError
        For a path of an unknown loop or direction, a routed path without estimate, or a loop
        with no sensor path (what the schema cannot know).
    """
    delays: dict[str, float | None] = {}
    used: dict[str, str] = {}
    for path in sorted(paths):
        loop, _, direction = path.rpartition(".")
        if loop not in loops:
            raise ProposalError(f"paths.{path}: unknown loop {loop!r} (loops: {list(loops)})")
        if direction not in _DIRECTIONS:
            raise ProposalError(f"paths.{path}: unknown direction {direction!r}")
        value, name = path_delay(path, paths[path], preferred, quantile)
        so_far = delays.get(loop, 0.0)  # None: another path of the loop is down
        if value is None or name is None or so_far is None:
            delays[loop] = None
            continue
        delays[loop] = so_far + value
        used[f"{loop}.{direction}"] = name
    missing = [n for n in loops if f"{n}.sensor" not in paths]
    if missing:
        raise ProposalError(f"paths: no sensor path for loop(s) {missing}")
    return delays, used


def decide(
    proposal: int | None,
    paths: Mapping[str, PathConfig],
    bounds: Mapping[str, DelayBound],
    preferred: str,
    *,
    wired: Mapping[str, float] | None = None,
    quantile: float = 0.95,
) -> Decision:
    """Accept or reject a proposal (III.E step 2); refuse it when it makes no sense for these
    loops (a path of an unknown loop, a loop without a sensor path, a routed path without an
    estimate: :func:`control_path_delays`).

    ``wired`` gives the constant delay of loops not carried by the proposing network (they
    need no path in the proposal).
    """
    loops = tuple(sorted(bounds))
    wired = dict(wired or {})
    carried = tuple(n for n in loops if n not in wired)
    try:
        delays, used = control_path_delays(paths, carried, preferred, quantile)
    except ProposalError as err:
        return Decision(proposal, "refuse", (f"proposal refused: {err}",))
    delays = {**{n: float(v) for n, v in wired.items()}, **delays}
    limits = {n: bounds[n].tau_d_max for n in loops}
    reasons, offending = [], []
    for n in loops:
        d = delays[n]
        if d is None:
            reasons.append(f"{n}: control path down (no route)")
            offending.append(n)
        elif not d < limits[n]:
            reasons.append(
                f"{n}: control-path delay {d:.4g} >= its bound {limits[n]:.4g} "
                "at the benchmark periods"
            )
            offending.append(n)
    if offending:
        return Decision(
            proposal, "reject", tuple(reasons), _known(delays), limits, used, tuple(offending)
        )
    reasons = [f"{n}: delay {delays[n]:.4g} < bound {limits[n]:.4g}" for n in loops]
    return Decision(proposal, "accept", tuple(reasons), _known(delays), limits, used)


def _known(delays: Mapping[str, float | None]) -> dict[str, float]:
    return {n: float(v) for n, v in delays.items() if v is not None}
