"""The agent's update-period governance of controllers that exchange estimates (seed 001).

For loops of this kind (a scenario's ``links:``: controllers of interconnected units with local
observers and embedded models of their neighbours) the agent does not simulate: it asks the
controllers' law for the linearized networked loop (``closed_loop()``: flow ``Acl`` and update
reset ``Rcl``, the same matrices the law runs) and applies the spectral-radius test of
:mod:`agents.update_period.delay` — seed 001's ``rho(M(h)) < 1`` when the estimates arrive at
once, its extension to updates landing ``d`` later otherwise. Nothing here knows the plant.

A group is a set of controllers connected by links; all links of a group share one update period
(as in the paper). Its delay is the largest of its links' delays: the wired ``delay`` of the
scenario, or the chosen estimate of a gateway's proposal. The agent assigns
``h = margin x h_max(d)`` (inside the first interval of stabilizing periods, checked), and
rejects a configuration under which no period stabilizes the group.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from agents.update_period.delay import DelayedUpdates, HRange, find_h_range
from agents.update_period.sampled import SampledQDC
from agents.wncsca.config import LinksConfig

if TYPE_CHECKING:
    from controllers.qdc.design import LinearUnits
    from controllers.qdc.network import QDCNetwork

__all__ = ["Link", "LinkGroup", "LinkVerdict", "judge_links", "link_groups"]


@dataclass(frozen=True)
class LinkGroup:
    """Controllers joined by links, and their networked loop (continuous-time local loops; and
    as sampled, when the sampled analysis is asked for)."""

    name: str
    controllers: tuple[str, ...]
    links: tuple[str, ...]
    system: DelayedUpdates
    sampled: SampledQDC | None = None


@dataclass(frozen=True)
class LinkVerdict:
    """What the analysis says about one group under one delay."""

    group: str
    links: tuple[str, ...]
    verdict: str  # accept | reject
    delay: float
    h_min: float
    h_max: float
    h: float | None
    rho: float | None
    periods: dict[str, float] = field(default_factory=dict)
    reasons: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        def num(v: float | None) -> float | None:
            return v if v is not None and math.isfinite(v) else None

        return {
            "group": self.group,
            "links": list(self.links),
            "verdict": self.verdict,
            "delay": self.delay,
            "h_min": num(self.h_min),
            "h_max": num(self.h_max),
            "h": self.h,
            "rho": self.rho,
            "periods": dict(self.periods),
            "reasons": list(self.reasons),
        }


class Link(Protocol):
    """A link between two controllers, as the scenario configures it (``links:``)."""

    @property
    def from_(self) -> str: ...

    @property
    def to(self) -> str: ...


def link_groups(
    links: Mapping[str, Link],
    build: Callable[[str], Any],
    analysis: str = "spectral_radius",
    *,
    tau_s: Callable[[str], float],
) -> list[LinkGroup]:
    """The groups of controllers joined by ``links`` (a scenario's ``links:``, by name).

    Parameters
    ----------
    links : mapping
        Each link's sending (``from_``) and receiving (``to``) controller node, by link name.
    build : callable
        ``build(controller) -> law`` (the law the controller node runs); the law of every
        controller of a group offers ``closed_loop() -> (Acl, Rcl)``, and for the ``sampled``
        analysis ``networked_model() -> (plant, network)``.
    analysis : {"spectral_radius", "sampled"}
        With ``sampled`` the groups also carry the sampled-data loop at the controllers'
        sampling period (``tau_s(controller)``, one per group).
    tau_s : callable
        A multi-loop controller's sampling period (time units).

    Raises
    ------
    ValueError
        A linked controller whose law offers no ``closed_loop`` (the agent cannot analyse it), or
        laws of one group that describe different networked loops (their design settings differ).
    """
    parent: dict[str, str] = {}

    def find(a: str) -> str:
        while parent.setdefault(a, a) != a:
            a = parent[a]
        return a

    for lk in links.values():
        parent[find(lk.from_)] = find(lk.to)
    members: dict[str, list[str]] = {}
    for c in sorted(parent):
        members.setdefault(find(c), []).append(c)
    groups = []
    for ctrls in sorted(members.values()):
        system = None
        for c in ctrls:
            law = build(c)
            if not hasattr(law, "closed_loop"):
                raise ValueError(
                    f"nodes.{c}.law: type {type(law).__name__} offers no closed_loop(); the agent "
                    "cannot analyse its links (links governance needs a law such as qdc)"
                )
            acl, rcl = law.closed_loop()
            if system is None:
                system = DelayedUpdates(np.asarray(acl, float), np.asarray(rcl, float))
            elif not (
                np.allclose(acl, system.Acl, rtol=1e-9, atol=1e-12)
                and np.allclose(rcl, system.Rcl, rtol=1e-9, atol=1e-12)
            ):
                raise ValueError(
                    f"nodes.{c}.law: describes another networked loop than {ctrls[0]}'s; the "
                    "linked controllers must share the design settings"
                )
        if system is None:
            raise ValueError(f"links: the group of {ctrls} has no controller to analyse")
        names = tuple(sorted(n for n, lk in links.items() if lk.from_ in ctrls or lk.to in ctrls))
        sampled = _sampled(tau_s, ctrls, law) if analysis == "sampled" else None
        groups.append(LinkGroup("+".join(ctrls), tuple(ctrls), names, system, sampled))
    return groups


def _sampled(tau_s: Callable[[str], float], ctrls: list[str], law: Any) -> SampledQDC:
    taus = {c: tau_s(c) for c in ctrls}
    if len(set(taus.values())) != 1:
        raise ValueError(
            f"links.analysis: sampled needs one sampling period for the linked controllers, "
            f"got {taus}"
        )
    if not hasattr(law, "networked_model"):
        raise ValueError(
            f"nodes.{ctrls[0]}.law: type {type(law).__name__} offers no networked_model(); use "
            "links.analysis: spectral_radius"
        )
    parts: tuple[LinearUnits, QDCNetwork] = law.networked_model()  # plant, network
    return SampledQDC.from_law_parts(*parts, taus[ctrls[0]])


def judge_links(group: LinkGroup, delays: Mapping[str, float], config: LinksConfig) -> LinkVerdict:
    """Accept (and assign the update period) or reject ``group`` with its links' ``delays``."""
    d = max((float(delays.get(n, 0.0)) for n in group.links), default=0.0)
    if math.isinf(d):
        return _reject(group, d, f"links {', '.join(group.links)}: a link has no route")
    if not d < config.h_hi:
        return _reject(
            group, d, f"delay {d:g} is not below the longest period scanned {config.h_hi:g}"
        )
    if config.analysis == "sampled":
        return _judge_sampled(group, d, config)
    r: HRange = find_h_range(group.system, d, h_hi=config.h_hi, n_grid=config.n_grid)
    if not r.feasible:
        return _reject(
            group,
            d,
            f"links {', '.join(group.links)}: no update period in ({d:g}, {config.h_hi:g}] keeps "
            f"rho(M_d(h)) < 1 with delay {d:g}",
        )
    if math.isinf(r.h_max):
        h = config.h_hi
        why = f"stable for every period scanned up to {config.h_hi:g}: assigned the longest"
    else:
        h = config.margin * r.h_max
        why = f"h = {config.margin:g} x h_max"
        if not h > r.h_min:
            h = 0.5 * (r.h_min + r.h_max)
            why = "h = middle of the stabilizing interval (margin x h_max is below its start)"
    rho = float(group.system.spectral_radius(h, d))
    if not rho < 1.0:  # a window narrower than the scan: say so rather than assign it
        return _reject(group, d, f"the period found, {h:g}, gives rho = {rho:.4f} >= 1")
    text = (
        f"links {', '.join(group.links)}: delay {d:.4g}, stabilizing update periods "
        f"({r.h_min:.4g}, {r.h_max:.4g}); {why} = {h:.4g} (rho(M) = {rho:.3f})"
    )
    return LinkVerdict(
        group.name,
        group.links,
        "accept",
        d,
        r.h_min,
        r.h_max,
        h,
        rho,
        {n: h for n in group.links},
        (text,),
    )


def _judge_sampled(group: LinkGroup, d: float, config: LinksConfig) -> LinkVerdict:
    """The sampled-data test: periods ``N tau_s``, the delay rounded up to whole samples."""
    system = group.sampled
    if system is None:
        raise ValueError(f"group {group.name}: built without the sampled loop")
    tau = system.tau_s
    n_delay = math.ceil(d / tau - 1e-9)
    n_hi = max(1, math.floor(config.h_hi / tau + 1e-9))
    ns = np.arange(1, n_hi + 1)
    rho = np.array([system.spectral_radius(int(n), n_delay) for n in ns])
    stable = rho < 1.0
    links = ", ".join(group.links)
    if not stable.any():
        return _reject(
            group,
            d,
            f"links {links}: no update period N x {tau:g} <= {config.h_hi:g} keeps the sampled "
            f"loop stable with delay {d:g} ({n_delay} samples)",
        )
    first = int(np.argmax(stable))
    after = np.nonzero(~stable[first:])[0]
    last = n_hi - 1 if after.size == 0 else first + int(after[0]) - 1
    n_lo, n_max = int(ns[first]), int(ns[last])
    n = max(n_lo, math.floor(config.margin * n_max + 1e-9))
    h_max = math.inf if after.size == 0 else n_max * tau
    text = (
        f"links {links}: delay {d:.4g} ({n_delay} samples of {tau:g}), sampled loop stable for "
        f"h = {n_lo * tau:.4g} ... {n_max * tau:.4g}; h = {n} x {tau:g} = {n * tau:.4g} "
        f"(margin {config.margin:g}; rho = {rho[n - 1]:.3f})"
    )
    return LinkVerdict(
        group.name,
        group.links,
        "accept",
        d,
        n_lo * tau,
        h_max,
        n * tau,
        float(rho[n - 1]),
        {k: n * tau for k in group.links},
        (text,),
    )


def _reject(group: LinkGroup, d: float, reason: str) -> LinkVerdict:
    nan = math.nan
    return LinkVerdict(group.name, group.links, "reject", d, nan, nan, None, None, {}, (reason,))
