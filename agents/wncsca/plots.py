"""Plots of the coordination agent's searches (seed 000, Fig. 10 style), for ``wncs analyze``,
the run report and ``bench/wncsca_figures.py``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from agents.wncsca.assignment import Assignment, Trial

__all__ = ["fig10"]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def fig10(assignment: Assignment, path: Path, *, limit: float = 25.0) -> Path:
    """Seed 000, Fig. 10: the paper method's trials (period and the searched loop's overshoot
    against trial number, acceptable ``o`` / violating ``x``) from ``assignment.trace``."""
    plt = _pyplot()
    trials = [t for t in assignment.trace if t.loop is not None]
    fig, (ax_p, ax_os) = plt.subplots(2, 1, figsize=(6.4, 6.0), sharex=True)
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
    plt.close(fig)
    return path


def _os(t: Trial) -> float:
    value = t.overshoot_pct[t.loop] if t.loop is not None else max(t.overshoot_pct.values())
    return value if math.isfinite(value) else float("nan")
