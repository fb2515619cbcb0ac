"""Plots of the coordination agent's searches (seed 000, Fig. 10 style), for ``wncs analyze``,
the run report and ``bench/wncsca_figures.py``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from agents.wncsca.assignment import Assignment, Trial

__all__ = ["fig10"]


def _figure(figsize: tuple[float, float]) -> Any:
    """A figure of its own (no pyplot: a notebook's backend and current figure are left alone)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def fig10(assignment: Assignment, path: Path, *, limit: float = 25.0) -> Path:
    """Seed 000, Fig. 10: the paper method's trials (period and the searched loop's overshoot
    against trial number, acceptable ``o`` / violating ``x``) from ``assignment.trace``."""
    trials = [t for t in assignment.trace if t.loop is not None]
    fig = _figure((6.4, 6.0))
    (ax_p, ax_os) = fig.subplots(2, 1, sharex=True)
    loops = sorted({t.loop for t in trials if t.loop is not None})
    colours = dict(zip(loops, ("tab:blue", "tab:red", "tab:green", "tab:purple"), strict=False))
    for loop in loops:
        xs = [i for i, t in enumerate(trials, 1) if t.loop == loop]
        mine = [t for t in trials if t.loop == loop]
        c = colours[loop]
        for ax, ys in ((ax_p, [t.period for t in mine]), (ax_os, [_os(t) for t in mine])):
            ok = [(x, y) for x, y, t in zip(xs, ys, mine, strict=True) if t.ok]
            bad = [(x, y) for x, y, t in zip(xs, ys, mine, strict=True) if not t.ok]
            if ok:
                ax.plot(*zip(*ok, strict=True), "o", color=c, label=f"{loop}, within limit")
            if bad:
                ax.plot(*zip(*bad, strict=True), "x", color=c, ms=8, label=f"{loop}, violates")
    previous = None
    for i, t in enumerate(trials, 1):  # a search starts where the searched loop changes
        key = (t.alternation, t.loop)
        if previous is not None and key != previous:
            for ax in (ax_p, ax_os):
                ax.axvline(i - 0.5, color="0.7", lw=0.8, ls=":")
        previous = key
    ax_os.axhline(limit, color="k", ls="--", lw=0.8, label=f"limit {limit:g} %")
    ax_p.set_ylabel("trial period $\\tau_s$, pu")
    ax_os.set_ylabel("overshoot of the searched loop, %")
    ax_os.set_xlabel("trial")
    delays = ", ".join(f"{n} {d:g}" for n, d in assignment.delays.items())
    final = ", ".join(f"{n} {p:g}" for n, p in assignment.periods.items())
    ax_p.set_title(
        f"Successive approximation (paper), delays {delays} pu\nresult: {final} pu", fontsize=9
    )
    for ax in (ax_p, ax_os):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def _os(t: Trial) -> float:
    value = t.overshoot_pct[t.loop] if t.loop is not None else max(t.overshoot_pct.values())
    return value if math.isfinite(value) else float("nan")


def assignment_from_dict(search: dict[str, Any]) -> Assignment:
    """An :class:`Assignment` back from its ``as_dict`` form (a summary's ``search``)."""
    trace = [
        Trial(
            alternation=t["alternation"],
            loop=t["loop"],
            step=t["step"],
            period=t["period"],
            periods=t["periods"],
            overshoot_pct={n: math.inf if v is None else v for n, v in t["overshoot_pct"].items()},
            ok=t["ok"],
        )
        for t in search["trace"]
    ]
    return Assignment(
        method=search["method"],
        delays=search["delays"],
        periods=search["periods"],
        overshoot_pct={n: math.inf if v is None else v for n, v in search["overshoot_pct"].items()},
        feasible=search["feasible"],
        converged=search["converged"],
        alternations=search["alternations"],
        trace=trace,
    )


def run_plots(
    w: dict[str, Any],
    out: Path,
    *,
    unit: str = "pu",
    limit: float = 25.0,
    end_time: float | None = None,
) -> list[Path]:
    """A run's agent plots: ``wncsca_periods.png`` (each loop's sampling period against time,
    open intervals shaded, proposals marked by verdict) and ``search_<n>.png`` (Fig. 10 style,
    one per negotiation)."""
    paths = []
    assignments = w.get("assignments", [])
    if assignments:
        fig = _figure((8, 4))
        ax = fig.subplots()
        loops = sorted(assignments[0]["periods"])
        end = max(a["t"] for a in assignments) if end_time is None else end_time
        ts = [a["t"] for a in assignments] + [end]
        for i, loop in enumerate(loops):
            ps = [a["periods"][loop] for a in assignments]
            cs = [a["control_periods"][loop] for a in assignments]
            lw = 2 * (len(loops) - i) + 0.5  # earlier loops wider, visible under later ones
            ax.step(ts, [*ps, ps[-1]], where="post", color=f"C{i}", lw=lw, label=f"{loop}")
            ax.step(
                ts,
                [*cs, cs[-1]],
                where="post",
                color=f"C{i}",
                ls=":",
                lw=1.2,
                label=f"{loop}: negotiated control period",
            )
        links = sorted(assignments[0].get("link_periods", {}))
        for k, link in enumerate(links, start=len(loops)):
            hs = [a["link_periods"][link] for a in assignments]
            ax.step(ts, [*hs, hs[-1]], where="post", color=f"C{k}", ls="--", label=f"link {link}")
        for a, t_next in zip(assignments, ts[1:], strict=True):
            if a["closed"] and not any(a["closed"].values()):
                ax.axvspan(a["t"], t_next, color="0.9", lw=0)
        marks = {
            "accept": ("g", "^"),
            "reject": ("r", "v"),
            "refuse": ("k", "x"),
            "keep": ("m", "s"),
        }
        for d in w.get("decisions", []):
            if d["subject"] == "proposal" and d["verdict"] in marks:
                c, m = marks[d["verdict"]]
                ax.plot([d["t"]], [0.03], m, color=c, ms=9, transform=ax.get_xaxis_transform())
        ax.set_yscale("log")
        ax.set_xlabel(f"time [{unit}]")
        ax.set_ylabel(f"sampling / update period [{unit}]")
        ax.set_title(
            "WNCSCA: periods (grey: loops open; ^ accepted, v rejected proposals)", fontsize=9
        )
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = out / "wncsca_periods.png"
        fig.savefig(path, dpi=110)
        paths.append(path)
    for n, a in enumerate(a for a in assignments if a.get("search")):
        paths.append(fig10(assignment_from_dict(a["search"]), out / f"search_{n}.png", limit=limit))
    return paths
