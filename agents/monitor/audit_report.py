"""The plant-wide audit's outputs: the ranked table (CSV and text), every loop's report (JSON)
and a readable HTML report with small plots, worst loops first (:mod:`agents.monitor.audit`).

Files written to the output directory:

* ``audit.csv`` -- one row per loop, ranked: ``rank, loop, file, status, harris, ci_low,
  ci_high, oscillating, period_samples, regularity, flags, action, reason``;
* ``audit.json`` -- the same outcomes with each loop's full assessment report;
* ``audit.html`` -- the table, a bar chart of the indices, and for the ``plotted`` worst loops
  the analysed series and its autocorrelation (the oscillation's period marked). Figures are
  drawn with ``matplotlib.figure.Figure`` on an Agg canvas (no pyplot, the user's backend is
  left alone) and embedded as PNG.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["TABLE_COLUMNS", "table_rows", "format_table", "write_audit"]

TABLE_COLUMNS = (
    "rank",
    "loop",
    "file",
    "status",
    "harris",
    "ci_low",
    "ci_high",
    "oscillating",
    "period_samples",
    "regularity",
    "flags",
    "action",
    "reason",
)


def _num(v: Any, fmt: str = ".4g") -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def table_rows(ranked: Sequence[dict[str, Any]]) -> list[dict[str, str]]:
    """The ranked outcomes as rows of :data:`TABLE_COLUMNS` (text cells)."""
    rows = []
    for o in ranked:
        ci = o.get("ci") or [None, None]
        rows.append(
            {
                "rank": str(o["rank"]),
                "loop": o["loop"],
                "file": str(o.get("file", "")),
                "status": o["status"],
                "harris": _num(o.get("harris")),
                "ci_low": _num(ci[0]),
                "ci_high": _num(ci[1]),
                "oscillating": "yes" if o.get("oscillating") else "no",
                "period_samples": _num(o.get("period"), ".3g"),
                "regularity": _num(o.get("regularity"), ".3g"),
                "flags": " ".join(o.get("flags", [])),
                "action": o["action"],
                "reason": o.get("reason") or "",
            }
        )
    return rows


def format_table(ranked: Sequence[dict[str, Any]], *, width: int = 60) -> str:
    """A readable fixed-width table of the ranking (several lines, no trailing newline)."""
    head = f"{'#':>3} {'loop':<16} {'status':<9} {'Harris [interval]':<22} {'osc (period)':<13} "
    head += f"{'flags':<18} action"
    lines = [head]
    for r in table_rows(ranked):
        h = f"{r['harris']} [{r['ci_low']}, {r['ci_high']}]" if r["harris"] else "-"
        osc = f"yes ({r['period_samples']})" if r["oscillating"] == "yes" else "no"
        act = r["action"] if len(r["action"]) <= width else r["action"][: width - 3] + "..."
        lines.append(
            f"{r['rank']:>3} {r['loop'][:16]:<16} {r['status']:<9} {h:<22} {osc:<13} "
            f"{r['flags'][:18]:<18} {act}"
        )
    return "\n".join(lines)


def _png(fig: Any) -> str:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    buf = io.BytesIO()
    FigureCanvasAgg(fig).print_png(buf)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _bar_chart(ranked: Sequence[dict[str, Any]], poor: float, good: float) -> str:
    from matplotlib.figure import Figure

    done = [o for o in ranked if o.get("harris") is not None]
    fig = Figure(figsize=(8, max(2.0, 0.18 * len(done) + 1)), dpi=80)
    ax = fig.add_subplot(1, 1, 1)
    ys = list(range(len(done)))[::-1]
    vals = [o["harris"] for o in done]
    colors = ["tab:red" if o.get("oscillating") else "tab:blue" for o in done]
    ax.barh(ys, vals, color=colors)
    for y, o in zip(ys, done, strict=True):
        ci = o.get("ci") or [None, None]
        if ci[0] is not None and ci[1] is not None:
            ax.plot([ci[0], ci[1]], [y, y], color="k", lw=1)
    ax.set_yticks(ys, [o["loop"] for o in done], fontsize=6)
    ax.axvline(poor, color="tab:orange", ls="--", lw=1)
    ax.axvline(good, color="tab:green", ls="--", lw=1)
    ax.set_xlabel("Harris index (red: oscillating)")
    fig.tight_layout()
    return _png(fig)


def _loop_plot(o: dict[str, Any]) -> str:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 1.8), dpi=80)
    ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2, 1]})
    y = o.get("plot", {}).get("y", [])
    r = o.get("plot", {}).get("acf", [])
    ax1.plot(y, lw=0.8)
    ax1.set_title(f"{o['loop']}: analysed series (first {len(y)} samples)", fontsize=8)
    ax2.plot(r, lw=0.8)
    ax2.axhline(0.0, color="k", lw=0.5)
    if o.get("period"):
        for k in range(1, 5):
            if k * o["period"] < len(r):
                ax2.axvline(k * o["period"], color="tab:red", ls=":", lw=0.8)
    ax2.set_title("autocorrelation", fontsize=8)
    for ax in (ax1, ax2):
        ax.tick_params(labelsize=6)
    fig.tight_layout()
    return _png(fig)


def write_audit(
    ranked: Sequence[dict[str, Any]],
    out_dir: str | Path,
    *,
    unconfigured: Sequence[str] = (),
    poor: float = 0.3,
    good: float = 0.7,
    plotted: int = 20,
    title: str = "Loop audit",
) -> dict[str, Path]:
    """Write ``audit.csv``, ``audit.json`` and ``audit.html`` (module docstring); their paths.

    Raises
    ------
    OSError
        The directory or a file cannot be written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = table_rows(ranked)
    paths = {"csv": out / "audit.csv", "json": out / "audit.json", "html": out / "audit.html"}
    with paths["csv"].open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=TABLE_COLUMNS)
        w.writeheader()
        w.writerows(rows)
    slim = [{k: v for k, v in o.items() if k != "plot"} for o in ranked]
    paths["json"].write_text(
        json.dumps({"loops": slim, "unconfigured": list(unconfigured)}, indent=1) + "\n"
    )
    counts = {s: sum(o["status"] == s for o in ranked) for s in ("assessed", "refused", "broken")}
    osc = sum(bool(o.get("oscillating")) for o in ranked)
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title>",
        "<style>body{font-family:sans-serif;font-size:13px}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:2px 5px;vertical-align:top}"
        ".broken{color:#a00}.refused{color:#a60}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>{len(ranked)} loops: {counts['assessed']} assessed ({osc} oscillating), "
        f"{counts['refused']} refused, {counts['broken']} broken. Worst first: assessed loops by "
        f"increasing Harris index (poor below {poor:g}, good from {good:g}), then refused, then "
        "broken ones.</p>",
    ]
    if any(o.get("harris") is not None for o in ranked):
        parts.append(
            f"<img alt='Harris indices' src='data:image/png;base64,"
            f"{_bar_chart(ranked, poor, good)}'>"
        )
    parts.append("<table><tr>" + "".join(f"<th>{c}</th>" for c in TABLE_COLUMNS) + "</tr>")
    for r in rows:
        parts.append(
            f"<tr class='{r['status']}'>"
            + "".join(f"<td>{html.escape(r[c])}</td>" for c in TABLE_COLUMNS)
            + "</tr>"
        )
    parts.append("</table>")
    if unconfigured:
        parts.append(
            "<p>Files no loop names (and defaults give no pv/delay): "
            + ", ".join(html.escape(str(f)) for f in unconfigured)
            + "</p>"
        )
    worst = [o for o in ranked if o["status"] != "broken" and o.get("plot", {}).get("y")]
    if worst:
        parts.append(f"<h2>The {min(plotted, len(worst))} worst loops</h2>")
    for o in worst[:plotted]:
        parts.append(
            f"<h3>{o['rank']}. {html.escape(o['loop'])}</h3><p>{html.escape(o['action'])}</p>"
            f"<img alt='{html.escape(o['loop'])}' src='data:image/png;base64,{_loop_plot(o)}'>"
        )
    parts.append("</body></html>")
    paths["html"].write_text("\n".join(parts) + "\n")
    return paths
