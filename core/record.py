"""What a run leaves behind, engine-independent: per-loop traces and per-plant true outputs.

The ``direct`` engine fills a :class:`RunRecord` as it simulates; the bus engines rebuild one from
``history.sqlite``. :func:`summarize` turns it into the ``summary.json`` contract.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from core.metrics import iae, step_metrics
from core.time import to_units

__all__ = [
    "Simulate",
    "LoopRecord",
    "LinkRecord",
    "PlantRecord",
    "RunRecord",
    "summarize",
    "loop_metrics",
    "wncsca_summary",
]


@dataclass
class LoopRecord:
    """One loop: every delivered sample and the control move computed from it.

    An actuator-only loop (``sensor`` ``None``) has one entry per move instead: ``t`` (and
    ``t_sampled``) the time it was computed, ``y`` ``None``. A measurement-only loop
    (``actuator: null``) records its delivered samples with ``u`` ``None`` (no move is made).
    """

    plant: str
    sensor: str | None
    t: list[int] = field(default_factory=list)  # ticks of delivery = of the control move
    y: list[float] = field(default_factory=list)
    u: list[float | None] = field(default_factory=list)  # None: no move (controller lost)
    t_sampled: list[int] = field(default_factory=list)
    setpoints: list[tuple[int, float]] = field(default_factory=list)  # (ticks, value), from t=0
    settling_band: float = 0.02
    sent: int = 0  # samples taken by the loop's sensor (delivered ones are in t/y)
    lost: int = (
        0  # samples the network lost (the rest of sent - delivered was in flight at the end)
    )
    lost_moves: int = 0  # control moves lost on the actuator path
    # a TSCH network: "<direction>.<reason>" -> packets it dropped (queue_full, ...)
    lost_by_reason: dict[str, int] = field(default_factory=dict)


@dataclass
class LinkRecord:
    """One link (data between controllers): transmissions, and every delivery."""

    sent: int = 0
    lost: int = 0
    t: list[int] = field(default_factory=list)  # ticks of delivery
    t_sent: list[int] = field(default_factory=list)  # ticks of transmission, per delivery


@dataclass
class PlantRecord:
    """One plant's true state on its monitoring grid."""

    state_names: tuple[str, ...]
    t: list[int] = field(default_factory=list)
    x: list[list[float]] = field(default_factory=list)

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(t_units, values)`` of one state variable."""
        i = self.state_names.index(name)
        return (
            np.array([to_units(v) for v in self.t]),
            np.array([row[i] for row in self.x], dtype=float),
        )


@dataclass
class RunRecord:
    scenario: str
    seed: int
    engine: str
    end_time: int  # ticks
    time_unit: str = "pu"
    loops: dict[str, LoopRecord] = field(default_factory=dict)
    links: dict[str, LinkRecord] = field(default_factory=dict)
    plants: dict[str, PlantRecord] = field(default_factory=dict)
    published: dict[str, int] = field(default_factory=dict)
    dropped_invalid: dict[str, int] = field(default_factory=dict)
    lost: int = 0
    dropped_nodes: dict[str, int] = field(default_factory=dict)
    disturbances: dict[str, list[int]] = field(default_factory=dict)  # plant -> ticks
    hops: dict[str, int] = field(default_factory=dict)  # loop -> sensor-path hops (0: wired)
    configurations: list[dict[str, Any]] = field(default_factory=list)  # t, event, source, paths
    net_nodes: dict[str, Any] = field(default_factory=dict)  # WSN node -> energy at the end
    wncsca: dict[str, list[Any]] = field(default_factory=dict)  # proposals, decisions, ...
    monitor: dict[str, list[Any]] = field(default_factory=dict)  # loop -> the monitor's assessments
    wall_s: float = 0.0
    phases: dict[str, float] = field(default_factory=dict)
    invalid: list[dict[str, Any]] = field(default_factory=list)  # history rows not validated


Simulate = Callable[[Any], RunRecord]
"""Runs a validated scenario to its record (:func:`runtime.direct.simulate`): what the
coordination agent is handed, and what a node kind's build is given (``scenario``)."""


def loop_metrics(rec: RunRecord, name: str) -> dict[str, Any]:
    """Overshoot, settling time and IAE of loop ``name``, per step and overall.

    Each step is judged over the window from the step to the loop's next step, the next scheduled
    disturbance on its plant, or the end of the run, whichever comes first. An actuator-only
    loop measures nothing: every figure is ``None``.
    """
    loop = rec.loops[name]
    if loop.sensor is None:
        return {"overshoot_pct": None, "settling_time": None, "iae": None, "steps": []}
    t, y = rec.plants[loop.plant].signal(loop.sensor)
    end = to_units(rec.end_time)
    changes = loop.setpoints
    steps = []
    for i in range(1, len(changes)):
        (t_step, r_to), (_, r_from) = changes[i], changes[i - 1]
        if r_to == r_from:
            continue
        t_next = to_units(changes[i + 1][0]) if i + 1 < len(changes) else end
        # a disturbance on the plant also ends the set-point response's window
        cut = [to_units(d) for d in rec.disturbances.get(loop.plant, []) if d > t_step]
        t_next = min([t_next, *cut])
        m = step_metrics(
            t,
            y,
            t_step=to_units(t_step),
            t_end=t_next,
            r_from=r_from,
            r_to=r_to,
            band=loop.settling_band,
        )
        steps.append(
            {
                "t": m.t,
                "from": m.r_from,
                "to": m.r_to,
                "overshoot_pct": m.overshoot_pct,
                "settling_time": m.settling_time,
                "iae": m.iae,
            }
        )
    # set point as a function of time on the monitoring grid, for the whole-run IAE
    r = np.empty_like(y)
    grid = rec.plants[loop.plant].t
    j = 0
    for k, tk in enumerate(grid):
        while j + 1 < len(changes) and changes[j + 1][0] <= tk:
            j += 1
        r[k] = changes[j][1]
    overshoots = [v for s in steps if (v := s["overshoot_pct"]) is not None]
    settle = [s["settling_time"] for s in steps]
    settled = [v for v in settle if v is not None]
    return {
        "overshoot_pct": max(overshoots, default=None),
        "settling_time": None if not steps or len(settled) < len(settle) else max(settled),
        "iae": iae(t, y, r),
        "steps": steps,
    }


def _delays(t: list[int], t_sent: list[int]) -> dict[str, float | None]:
    delays = np.array([to_units(d - s) for d, s in zip(t, t_sent, strict=True)])
    return {
        "delay_mean": float(delays.mean()) if len(delays) else None,
        "delay_p95": float(np.percentile(delays, 95)) if len(delays) else None,
        "delay_max": float(delays.max()) if len(delays) else None,
    }


def path_stats(rec: RunRecord) -> dict[str, dict[str, Any]]:
    """Per loop sensor path: hops, delivered delays (mean, p95, max; time units), sent, lost.
    An actuator-only loop has no sensor path: no delays, nothing sent."""
    out: dict[str, dict[str, Any]] = {}
    for name, loop in sorted(rec.loops.items()):
        sensed = loop.sensor is not None
        delivered = len(loop.t) if sensed else 0
        out[name] = {
            "hops": rec.hops.get(name, 0),
            **_delays(loop.t if sensed else [], loop.t_sampled if sensed else []),
            "sent": loop.sent,
            "lost": loop.lost,
            "in_flight_at_end": loop.sent - delivered - loop.lost,
            "moves_lost": loop.lost_moves,
        }
        if loop.lost_by_reason:  # a TSCH network says why
            out[name]["lost_by_reason"] = dict(sorted(loop.lost_by_reason.items()))
    return out


def link_stats(rec: RunRecord) -> dict[str, dict[str, Any]]:
    """Per link: delivered delays (mean, p95, max; time units), sent, delivered, lost."""
    return {
        name: {
            **_delays(lk.t, lk.t_sent),
            "sent": lk.sent,
            "delivered": len(lk.t),
            "lost": lk.lost,
            "in_flight_at_end": lk.sent - len(lk.t) - lk.lost,
        }
        for name, lk in sorted(rec.links.items())
    }


def summarize(rec: RunRecord) -> dict[str, Any]:
    """The ``summary.json`` contract of a run (see README, "Run artefacts")."""
    loops = {}
    for name, loop in sorted(rec.loops.items()):
        entry = loop_metrics(rec, name)
        entry["trace"] = {
            "t": [to_units(v) for v in loop.t],
            "y": list(loop.y),
            "u": list(loop.u),
        }
        loops[name] = entry
    paths = path_stats(rec)
    links = link_stats(rec)
    return {
        "scenario": rec.scenario,
        "seed": rec.seed,
        "engine": rec.engine,
        "time_unit": rec.time_unit,
        "end_time": to_units(rec.end_time),
        "loops": loops,
        "messages": {
            "published": dict(sorted(rec.published.items())),
            "dropped_invalid": dict(sorted(rec.dropped_invalid.items())),
            "lost": rec.lost
            + sum(p["lost"] + p["moves_lost"] for p in paths.values())
            + sum(lk["lost"] for lk in links.values()),
            **({"invalid_in_history": rec.invalid} if rec.invalid else {}),
        },
        "network": {
            "paths": paths,
            **({"links": links} if links else {}),
            "nodes": dict(sorted(rec.net_nodes.items())),
            "configurations": [{**c, "t": to_units(c["t"])} for c in rec.configurations],
        },
        "events": [
            {"t": to_units(c["t"]), "kind": c["event"], "source": c["source"]}
            for c in rec.configurations
            if c["source"] != "initial"
        ],
        "dropped_nodes": dict(sorted(rec.dropped_nodes.items())),
        **({"wncsca": wncsca_summary(rec.wncsca)} if rec.wncsca else {}),
        **({"monitor": rec.monitor} if rec.monitor else {}),
        "wall_s": rec.wall_s,
        "phases_s": rec.phases,
    }


def wncsca_summary(raw: dict[str, list[Any]]) -> dict[str, Any]:
    """The coordination agent's part of ``summary.json``: ``decisions`` (time, subject, proposal,
    verdict, reasons, delays, bounds), ``assignments`` (time, mode, period and closed state per
    loop, predicted overshoot, method, search trace when negotiated) and ``energy`` (projected
    network lifetime under the assigned periods against the benchmark periods, per negotiation)
    and, after an identification experiment, ``models`` (the estimates of ``wncsca/model``).
    Times in time units; periods in time units; ``order`` is the message's place in the history
    (several happen at one instant, in microsteps)."""
    timing: dict[Any, list[float]] = {}  # proposal -> the wall times of its judgements, in order
    for entry in raw.get("timing", []):
        timing.setdefault(entry["proposal"], []).append(entry["decision_s"])
    decisions = []
    for d in raw.get("decisions", []):
        entry = {**d, "t": to_units(d["t"])}
        # each judgement of a proposal (a later one: judged again on an identified model) has
        # its own timing; a "keep" is no judgement and has none
        took = timing.get(d.get("proposal")) if d.get("subject") == "proposal" else None
        if took and d.get("verdict") != "keep":
            entry["decision_time_s"] = took.pop(0)
        decisions.append(entry)
    assignments, energy = [], []
    for r in raw.get("rates", []):
        t = to_units(r["t"])
        assignments.append(
            {
                "t": t,
                "order": r.get("order"),
                "mode": r["mode"],
                "proposal": r["proposal"],
                "periods": {n: to_units(p) for n, p in r["periods"].items()},
                "closed": r["closed"],
                "control_periods": {n: to_units(p) for n, p in r["control_periods"].items()},
                "link_periods": {n: to_units(p) for n, p in r.get("link_periods", {}).items()},
                "method": r.get("method"),
                "overshoot_pct": r.get("overshoot_pct", {}),
                **({"search": r["assignment"]} if r.get("assignment") else {}),
            }
        )
        if r.get("energy"):
            energy.append(
                {"t": t, "order": r.get("order"), "proposal": r["proposal"], **r["energy"]}
            )
    models = [
        {
            **m,
            "t": to_units(m["t"]),
            "t_start": to_units(m["t_start"]),
            "t_end": to_units(m["t_end"]),
        }
        for m in raw.get("models", [])
    ]
    return {
        "proposals": [_proposal(p) for p in raw.get("proposals", [])],
        "decisions": decisions,
        **({"models": models} if models else {}),
        "assignments": assignments,
        "energy": energy,
        "applied": [
            {
                "t": to_units(a["t"]),
                "event": a["event"],
                "proposal": a.get("proposal"),
                "periods": {n: to_units(p) for n, p in a.get("periods", {}).items()},
            }
            for a in raw.get("applied", [])
        ],
    }


def _proposal(p: dict[str, Any]) -> dict[str, Any]:
    """One proposal as the summary lists it; a malformed one (the agent refused it) is listed as
    it came, with what could be read."""
    raw_paths = p.get("paths")
    paths: dict[str, Any] = raw_paths if isinstance(raw_paths, dict) else {}
    entries = {k: v for k, v in paths.items() if isinstance(v, dict)}
    return {
        "t": to_units(p["t"]),
        "order": p.get("order"),
        "id": p.get("id"),
        "event": p.get("event"),
        "source": p.get("source"),
        "hops": {k: v.get("hops") for k, v in entries.items()},
        "estimates": {k: v.get("estimates") for k, v in entries.items()},
    }
