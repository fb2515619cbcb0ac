"""An assessment as a plant engineer reads it: :func:`format_report` turns the JSON report of
``wncs assess`` (:meth:`agents.monitor.assess.AssessmentResult.to_dict` plus where the data came
from) into text: Harris index with its uncertainty, per candidate secondary the four variance
components and the predicted variance under cascade control, the ranking and the recommendation.
"""

from __future__ import annotations

from typing import Any

__all__ = ["format_report"]


def _g(v: Any, fmt: str = ".4g") -> str:
    return "n/a" if v is None else format(v, fmt)


def _pct(v: Any, total: Any) -> str:
    if v is None or not total:
        return "n/a"
    return f"{100.0 * v / total:.1f} %"


def _source(report: dict[str, Any]) -> str:
    data = report.get("data", {})
    w = report.get("window")
    if data.get("kind") == "run" and w is not None:
        u = w["time_unit"]
        span = f"taken {w['first_sampled']:g}-{w['last_sampled']:g} {u}" if w["samples"] else "none"
        return (
            f"run {data['path']} ({data.get('engine', '?')} engine): loop {w['loop']!r}, "
            f"{w['samples']} samples {span}, delivered before {w['until']:g} {u}"
            + (f", last {w['window']} delivered" if w["window"] else "")
            + (f", {w['gaps']} gaps in the sampling" if w["gaps"] else "")
        )
    return f"{data.get('path', report.get('source'))} ({report['n_samples']} rows)"


def format_report(report: dict[str, Any]) -> str:
    """The report as readable text (several lines, no trailing newline)."""
    lines = [f"Assessment of {report['primary']!r} from {_source(report)}"]
    var = report["variance"]
    what = report["primary"]
    sp = report.get("setpoint")
    if sp:
        what = f"control error {sp} - {report['primary']}"
    lines.append(f"primary: {what}; delay d = {report['delay']} samples; variance {_g(var)}")
    h = report["harris"]
    if h["status"] == "ok":
        lo, hi = h["ci"]
        lines.append(
            f"Harris index {_g(h['index'], '.3f')} +- {_g(h['std'], '.3f')} "
            f"({100 * h['confidence']:g} % interval {_g(lo, '.3f')}-{_g(hi, '.3f')}; "
            f"AR({h['order']}), minimum variance {_g(h['sigma2_mv'])}, {h['uncertainty']} "
            "method)" + (" -- above 1: estimation noise" if h.get("above_one") else "")
        )
    else:
        kind = f", {h['kind']}" if h.get("kind") else ""
        lines.append(f"Harris index: unidentifiable ({h['reason']}{kind}): {h['detail']}")
    osc = report.get("oscillation")
    if osc:
        lines.append(f"Oscillation (ACF test, Thornhill et al. 2003): {osc['text']}")
    scr = report.get("screening")
    if scr:
        flags = ", ".join(scr["flags"]) or "none"
        lines.append(f"Data quality: {flags}; rows {scr['rows'][0]}-{scr['rows'][1]} analysed")
    cands = report["candidates"]
    if cands:
        lines.append(
            "Candidate secondaries (variance components of the primary, seed 004 eq. (11)-(15)):"
        )
    for c in cands:
        head = f"  {c['name']} (d1 = {c['d1']}, d2 = {c['d2']})"
        if c["status"] != "ok":
            lines.append(f"{head}: unidentifiable ({c['reason']}): {c['detail']}")
            continue
        comp = c["components"]
        total = sum(v for v in comp.values() if v is not None)
        lines.append(
            f"{head}, VAR({c['order']}): "
            + ", ".join(f"{k} {_g(v)} ({_pct(v, total)})" for k, v in comp.items())
        )
        pr = c["prediction"]
        lo, hi = pr["band"]
        red = pr["reduction"]
        lines.append(
            f"      under cascade: {_g(pr['point'])} (band {_g(lo)}-{_g(hi)}, at best "
            f"{_g(pr['minimum'])}); {_g(None if red is None else 100 * red, '.0f')} % less "
            f"than now"
        )
    if cands:
        ranking = report["ranking"]
        lines.append(
            "Ranking: "
            + ("  ".join(f"{i + 1}. {n}" for i, n in enumerate(ranking)) or "none identified")
        )
        lo, hi = report["config"]["removed_2a"]
        lines.append(
            f"Band: {report['band_rule']}: a cascade removes 1b, 2b and {100 * lo:g}-{100 * hi:g} "
            "% of 2a (1a is the least variance any cascade can reach)"
        )
        lines.append(f"Recommendation: {report['recommendation']['text']}")
    for note in report.get("notes", []):
        lines.append(f"Note: {note}")
    for hint in report.get("hints", []):
        lines.append(f"Hint: {hint}")
    return "\n".join(lines)
