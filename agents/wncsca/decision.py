"""Judging a proposed network configuration (seed 000, III.E steps 1-2).

Step 1: a loop's control-path delay is the chosen estimate (time stamps, ping, or hops x per-hop
delay) of its sensor path plus that of its actuator path when the actuator is on the WSN too.
Step 2: accept the configuration (conditionally: periods are negotiated next) when every loop's
delay is below its bound at the benchmark periods; otherwise reject it, naming each offending
loop, its delay and its bound. A proposal that does not make sense (a path of an unknown loop, a
negative or missing delay, a malformed entry) is *refused*: neither accepted nor rejected, so
nothing changes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import ValidationError

from agents.wncsca.bounds import DelayBound
from agents.wncsca.config import ESTIMATES
from bus_schemas import DelayDistribution

__all__ = [
    "Decision",
    "ProposalError",
    "control_path_delays",
    "decide",
    "path_delay",
    "read_distribution",
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


def read_distribution(path: str, raw: Any) -> DelayDistribution:
    """A path entry's ``distribution``, validated.

    Raises
    ------
    ProposalError
        Naming the path and the field (``paths.<path>.distribution.<field>: ...``).
    """
    try:
        return DelayDistribution.model_validate(raw)
    except ValidationError as err:
        first = err.errors()[0]
        where = "".join(f".{p}" for p in first["loc"])
        raise ProposalError(f"paths.{path}.distribution{where}: {first['msg']}") from None


def path_delay(
    path: str, entry: Any, preferred: str, quantile: float = 0.95
) -> tuple[float, str] | tuple[None, None]:
    """``(delay, estimate used)`` of one path entry; ``(None, None)`` when the path is down.

    ``preferred="quantile"``: the ``quantile`` of the entry's delay ``distribution`` (a
    constant delay the path's delivered packets exceed with probability ``1 - quantile``; with
    a sensor and an actuator path the sum of their quantiles, an upper bound of the quantile of
    the sum); without a distribution the paper's estimates are used, in their order."""
    if not isinstance(entry, Mapping):
        raise ProposalError(f"paths.{path}: expected a mapping, got {type(entry).__name__}")
    hops = entry.get("hops")
    if isinstance(hops, bool) or not isinstance(hops, int):
        raise ProposalError(f"paths.{path}.hops: missing or not an integer ({hops!r})")
    route = entry.get("route", [])
    if not isinstance(route, list) or not all(isinstance(n, str) for n in route):
        raise ProposalError(f"paths.{path}.route: not a list of node names ({route!r})")
    estimates = entry.get("estimates")
    if not isinstance(estimates, Mapping):
        raise ProposalError(f"paths.{path}.estimates: missing or not a mapping")
    unknown = [e for e in estimates if e not in ESTIMATES]
    if unknown:
        raise ProposalError(f"paths.{path}.estimates: unknown estimate(s) {unknown!r}")
    for name, value in estimates.items():
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ProposalError(f"paths.{path}.estimates.{name}: not a number ({value!r})")
        try:
            value = float(value)
        except OverflowError:
            raise ProposalError(f"paths.{path}.estimates.{name}: out of range") from None
        if not math.isfinite(value) or value < 0:
            raise ProposalError(f"paths.{path}.estimates.{name}: a delay must be >= 0, got {value}")
    if hops < 0:
        return None, None
    if preferred == "quantile" and entry.get("distribution") is not None:
        dist = read_distribution(path, entry["distribution"])
        return float(np.interp(quantile, dist.probabilities, dist.delays)), "quantile"
    order = [preferred, *(e for e in ESTIMATES if e != preferred)]
    for name in order:
        value = estimates.get(name)
        if value is not None:
            return float(value), name
    raise ProposalError(f"paths.{path}.estimates: a routed path ({hops} hops) has no estimate")


def control_path_delays(
    paths: Any, loops: tuple[str, ...], preferred: str, quantile: float = 0.95
) -> tuple[dict[str, float | None], dict[str, str]]:
    """Each loop's control-path delay (``None``: a path of the loop is down) and the estimate used.

    Raises
    ------
    ProposalError
        For a path of an unknown loop or direction, a malformed entry, a negative delay, or a
        loop with no sensor path.
    """
    if not isinstance(paths, Mapping):
        raise ProposalError("paths: missing or not a mapping")
    delays: dict[str, float | None] = {}
    used: dict[str, str] = {}
    if not all(isinstance(p, str) for p in paths):
        raise ProposalError(f"paths: every key must be a path name, got {list(paths)!r}")
    for path in sorted(paths):
        loop, _, direction = str(path).rpartition(".")
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
    paths: Any,
    bounds: Mapping[str, DelayBound],
    preferred: str,
    *,
    wired: Mapping[str, float] | None = None,
    quantile: float = 0.95,
) -> Decision:
    """Accept or reject a proposal (III.E step 2); refuse it when it is malformed.

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
