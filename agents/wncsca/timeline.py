"""A readable timeline of what the coordination agent saw and decided, from ``summary.json``'s
``wncsca`` section: proposals (hops, delay estimates), verdicts with reasons, assigned periods and
loop states, the projected lifetime gain, and the measured overshoot of every set-point step."""

from __future__ import annotations

import math
import re
from typing import Any

__all__ = ["format_timeline"]


def _periods(periods: dict[str, float]) -> str:
    return ", ".join(f"{n} {p:.4g}" for n, p in periods.items())


def _estimate(e: Any) -> Any:
    """The hops estimate of a path (ping if there is none), as the gateway sent it."""
    if not isinstance(e, dict):
        return e
    value = e.get("hops") if e.get("hops") is not None else e.get("ping")
    return f"{value:.4g}" if isinstance(value, int | float) else value


def _order(entry: dict[str, Any]) -> float:
    order = entry.get("order")
    return math.inf if order is None else float(order)


def _cause(p: dict[str, Any]) -> str:
    return str(p["source"]) if p["source"] == p["event"] else f"{p['source']}: {p['event']}"


Event = tuple[float, float, str]
"""One line of the timeline: its time, its order among events at that time, its text."""


def format_timeline(summary: dict[str, Any]) -> str:
    """The agent's timeline, one event per line, in time order."""
    w = summary.get("wncsca")
    if not w:
        return ""
    unit = summary.get("time_unit", "pu")
    events = [
        *_proposals(w),
        *_decisions(w),
        *_assignments(w, unit),
        *_energy(w),
        *_steps(summary),
    ]
    lines = [
        f"{t:8.3f} {unit}  {text}" for t, _, text in sorted(events, key=lambda e: (e[0], e[1]))
    ]
    return "\n".join(lines)


def _proposals(w: dict[str, Any]) -> list[Event]:
    """Each proposal with its cause, hop counts and delay estimates."""
    events = []
    for p in w.get("proposals", []):
        est = ", ".join(f"{path} {_estimate(e)}" for path, e in (p.get("estimates") or {}).items())
        hops = ", ".join(f"{k} {v}" for k, v in (p.get("hops") or {}).items())
        text = f"proposal #{p['id']} ({_cause(p)}): hops {hops}; delays {est}"
        events.append((p["t"], _order(p), text))
    return events


def _decisions(w: dict[str, Any]) -> list[Event]:
    """Each verdict, with how long it took and its reasons."""
    events = []
    for d in w.get("decisions", []):
        what = f"proposal #{d['proposal']}" if d["subject"] == "proposal" else d["subject"]
        took = f" [{d['decision_time_s']:.2f} s]" if d.get("decision_time_s") is not None else ""
        text = f"{what}: {d['verdict'].upper()}{took} - " + "; ".join(d["reasons"])
        events.append((d["t"], _order(d), text))
    return events


def _assignments(w: dict[str, Any], unit: str) -> list[Event]:
    """Each change of the assigned rates (a repeat of the previous state is left out)."""
    events = []
    previous = None
    for a in w.get("assignments", []):
        state = (
            a["mode"],
            tuple(a["periods"].items()),
            tuple(a["closed"].items()),
            tuple(a["control_periods"].items()),
            tuple(a.get("link_periods", {}).items()),
        )
        if state != previous:
            events.append((a["t"], _order(a), _rates(a, unit)))
        previous = state
    return events


def _rates(a: dict[str, Any], unit: str) -> str:
    """One assignment: mode, periods, loop states, link periods and the search behind it."""
    closed = a["closed"]
    loops = (
        "closed"
        if all(closed.values())
        else ("open (outputs held)" if not any(closed.values()) else str(closed))
    )
    line = f"rates: mode {a['mode']}"
    if a["periods"]:
        line += f", periods {_periods(a['periods'])} {unit}, loops {loops}"
    if a["control_periods"] != a["periods"]:
        line += f" (control periods {_periods(a['control_periods'])} {unit})"
    if a.get("link_periods"):
        line += f", update periods of links {_periods(a['link_periods'])} {unit}"
    if a.get("search"):
        s = a["search"]
        os_ = ", ".join(f"{n} {v:.1f} %" for n, v in s["overshoot_pct"].items() if v is not None)
        line += (
            f"; negotiated by the {s['method']} method in {s['alternations']} alternation(s), "
            f"{len(s['trace'])} trials, predicted overshoot {os_}"
        )
    return line


def _energy(w: dict[str, Any]) -> list[Event]:
    """Each projected lifetime gain, just after the assignment it follows."""
    return [
        (
            e["t"],
            _order(e) + 0.5,
            f"projected network lifetime {e['lifetime_h_assigned']:.0f} h under "
            f"the negotiated periods vs {e['lifetime_h_benchmark']:.0f} h at the benchmark "
            f"periods (x{e['ratio']:.2f})",
        )
        for e in w.get("energy", [])
        if e.get("ratio") is not None
    ]


def _steps(summary: dict[str, Any]) -> list[Event]:
    """Each set-point step with its measured overshoot, last among events at its time; beside
    it the overshoot the agent predicted when it judged the step (the chance method), and a
    warning when the measured one passed the agent's limit. The moves of an identification
    experiment are its excitation, not steps: one line per loop counts them."""
    w = summary.get("wncsca") or {}
    predicted, limit = _predictions(w.get("decisions", []))
    windows = [(m["t_start"], m["t_end"]) for m in w.get("models", [])]
    events = []
    for name, lp in summary.get("loops", {}).items():
        for a, b in windows:
            moves = [s for s in lp.get("steps", []) if a <= s["t"] <= b]
            if moves:
                events.append(
                    (
                        a,
                        math.inf,
                        f"{name}: {len(moves)} set-point moves of the identification "
                        f"experiment to t={b:g} (excitation, not judged steps)",
                    )
                )
        for s in lp.get("steps", []):
            if any(a <= s["t"] <= b for a, b in windows):
                continue
            measured = s["overshoot_pct"]
            text = f"{name} set point {s['from']:g} -> {s['to']:g}: measured overshoot "
            text += "n/a" if measured is None else f"{measured:.1f} %"
            guess = predicted.get((name, s["from"], s["to"]))
            if guess is not None:
                text += f" (predicted {guess:.1f} %)"
            if limit is not None and measured is not None and measured > limit:
                text += f"  WARNING: past the {limit:g} % limit"
            events.append((s["t"], math.inf, text))
    return events


_JUDGED = re.compile(
    r"step (?P<loop>\S+) (?P<a>[-+0-9.eE]+) -> (?P<b>[-+0-9.eE]+)\b.*?"
    r"predicted overshoot (?P<os>[-+0-9.eE]+|inf) %"
)
_LIMIT = re.compile(r"P\(overshoot <= (?P<limit>[0-9.eE+-]+) %\)")


def _predictions(
    decisions: list[dict[str, Any]],
) -> tuple[dict[tuple[str, float, float], float], float | None]:
    """The overshoot predicted for each judged step (loop, from, to) and the agent's limit, read
    from the decisions' reasons (``None``: no judged step says it)."""
    out: dict[tuple[str, float, float], float] = {}
    limit = None
    for d in decisions:
        for reason in d.get("reasons", []):
            if limit is None and (m := _LIMIT.search(reason)):
                limit = float(m["limit"])
            if d.get("subject") == "setpoint" and (m := _JUDGED.search(reason)):
                out[(m["loop"], float(m["a"]), float(m["b"]))] = float(m["os"])
    return out, limit
