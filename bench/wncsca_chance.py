"""The agent's promise on a jittery, lossy network: the paper's method against the chance method
on the same realizations (issue 14).

``scenarios/jcstr_wncs_jitter.yaml`` (the demo's plant, controllers and agent; exponential
per-attempt jitter with the demo's mean per-hop delays, PRR 0.98) is run on the direct engine
(equal to the bus engines: ``tests/integration/test_engines_agree.py``) for ``--seeds`` seeds with
the agent's ``method`` set to ``paper`` and to ``chance``. A seed fixes the network's draws, so
both methods meet the same per-hop draws for the packets they send (not the same delays per
sample: the sample times differ with the periods). For each method it prints:

* the periods assigned and the projected network lifetime against the benchmark periods (what the
  guarantee costs in battery);
* over the paper's two set-point steps of every seed: the share whose measured overshoot exceeds
  the limit + 1 point (the acceptance: at most 5 % for the chance method), and per loop the
  measured frequency within the limit beside the agent's predicted probability (chance) with its
  95 % interval;

and, for the constant-delay demo (``scenarios/jcstr_wncs.yaml``, uniform +-10 % jitter), the
periods of its first proposal under both methods and their ratio (the acceptance: within 10 %)::

    python bench/wncsca_chance.py [--seeds 20] [--jobs 2]
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from agents.wncsca.chance import probability_interval
from core.record import loop_metrics
from core.time import to_units
from runtime.direct import simulate
from scenario import Scenario, load_scenario

__all__ = ["run_one", "main"]

ROOT = Path(__file__).resolve().parents[1]
JITTER = ROOT / "scenarios" / "jcstr_wncs_jitter.yaml"
DEMO = ROOT / "scenarios" / "jcstr_wncs.yaml"
METHODS = ("paper", "chance")


def with_agent(scenario: Scenario, agent: str, **update: Any) -> Scenario:
    """``scenario`` with its agent node's configuration updated (validated)."""
    cfg = scenario.nodes[agent].model_copy(update=update)
    data = scenario.model_dump()
    data["nodes"][agent] = cfg.model_dump()
    return type(scenario).model_validate(data)


def run_one(path: str, method: str, seed: int, end_time: float | None = None) -> dict[str, Any]:
    """One run: the periods and guarantee of the agent's first assignment, the lifetimes, and
    every set-point step's measured overshoot."""
    scenario = load_scenario(path)
    agent = scenario.agent_node()
    assert agent is not None
    scenario = with_agent(scenario, agent, method=method)
    data = scenario.model_dump()
    data["seed"] = seed
    if end_time is not None:
        data["end_time"] = end_time
        data["setpoints"] = [s for s in data["setpoints"] if s["t"] <= end_time]
        data["modes"] = [m for m in data["modes"] if m["t"] <= end_time]
    scenario = type(scenario).model_validate(data)
    rec = simulate(scenario)
    assigned = next((r for r in rec.wncsca["rates"] if r.get("assignment")), None)
    verdict = next(d for d in rec.wncsca["decisions"] if d["subject"] == "proposal")
    if assigned is None:  # rejected, no alternative: the benchmark periods stay
        assigned = rec.wncsca["rates"][-1]
        print(f"{method} seed {seed}: proposal {verdict['verdict']}: {verdict['reasons'][0]}")
    guarantee = (assigned.get("assignment") or {}).get("guarantee")
    steps = {
        name: [s["overshoot_pct"] for s in loop_metrics(rec, name)["steps"]]
        for name in sorted(rec.loops)
    }
    return {
        "method": method,
        "seed": seed,
        "periods": {n: to_units(p) for n, p in assigned["control_periods"].items()},
        "energy": assigned.get("energy"),
        "verdict": verdict["verdict"],
        "probability": guarantee["probability"] if guarantee else None,
        "steps": steps,
    }


def _pool(jobs: int, tasks: list[tuple[Any, ...]]) -> list[dict[str, Any]]:
    if jobs <= 1:
        return [run_one(*t) for t in tasks]
    with ProcessPoolExecutor(jobs) as ex:
        return list(ex.map(run_one, *zip(*tasks, strict=True)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20, help="seeds 0..N-1 (default 20)")
    ap.add_argument("--jobs", type=int, default=1, help="parallel processes (default 1)")
    ap.add_argument("--limit", type=float, default=25.0, help="overshoot limit, %% (25)")
    args = ap.parse_args(argv)
    tasks = [(str(JITTER), m, s) for m in METHODS for s in range(args.seeds)]
    results = _pool(args.jobs, tasks)
    print(f"## {JITTER.name}: {args.seeds} seeds, direct engine\n")
    print(
        "| method | periods (pu, min-max over seeds) | lifetime h, mean (benchmark) "
        "| steps > limit + 1 | share |"
    )
    print("|---|---|---|---:|---:|")
    shares = {}
    for method in METHODS:
        rows = [r for r in results if r["method"] == method]
        steps = [v for r in rows for vs in r["steps"].values() for v in vs if v is not None]
        over = sum(1 for v in steps if v > args.limit + 1.0)
        shares[method] = over / len(steps)
        rejected = sum(1 for r in rows if r["verdict"] != "accept")
        per = ", ".join(
            f"{n} {min(r['periods'][n] for r in rows):g}-{max(r['periods'][n] for r in rows):g}"
            for n in sorted(rows[0]["periods"])
        )
        if rejected:
            per += f" ({rejected} rejected: benchmark periods)"
        lives = [r["energy"] for r in rows if r["energy"]]
        a = sum(e["lifetime_h_assigned"] for e in lives) / max(1, len(lives))
        b = lives[0]["lifetime_h_benchmark"] if lives else math.nan
        share = f"{over} of {len(steps)} | {shares[method]:.1%}"
        print(f"| {method} | {per} | {a:.0f} ({b:.0f}) | {share} |")
    print("\n| method | loop | measured P(OS <= limit) [95 % CI] | predicted (mean over seeds) |")
    print("|---|---|---|---|")
    for method in METHODS:
        rows = [r for r in results if r["method"] == method]
        for loop in sorted(rows[0]["steps"]):
            vals = [v for r in rows for v in r["steps"][loop] if v is not None]
            within = sum(1 for v in vals if v <= args.limit)
            lo, hi = probability_interval(within, len(vals))
            preds = [r["probability"][loop]["p"] for r in rows if r["probability"]]
            pred = f"{sum(preds) / len(preds):.3f}" if preds else "-"
            print(
                f"| {method} | {loop} | {within / len(vals):.3f} [{lo:.3f}, {hi:.3f}] "
                f"({within} of {len(vals)}) | {pred} |"
            )
    demo = _pool(args.jobs, [(str(DEMO), m, 0, 1.0) for m in METHODS])
    print(f"\n## {DEMO.name} (constant mean delays, uniform +-10 % jitter): first proposal\n")
    print("| loop | paper | chance | chance / paper |")
    print("|---|---:|---:|---:|")
    paper, chance = (next(r for r in demo if r["method"] == m)["periods"] for m in METHODS)
    for loop in sorted(paper):
        print(f"| {loop} | {paper[loop]:g} | {chance[loop]:g} | {chance[loop] / paper[loop]:.3f} |")
    print(f"\nchance share over limit + 1: {shares['chance']:.1%} (target <= 5 %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
