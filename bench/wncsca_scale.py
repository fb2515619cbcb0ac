"""The coordination agent's decision time on N loops (issue 20, item 5): the paper's successive
approximation against the fast method, at equal answers.

The problems are ``runtime/agent_problems.py``'s: N JCSTR loops (reactor variants, a level and a
temperature loop each, a tank for an odd N), every loop on a wired path of its own delay, the
agent's configuration of ``scenarios/jcstr_wncs.yaml`` with eps_OS 0.2 points (with 1 point the
paper's method stops anywhere in [24, 25] %, which spans more than 5 % of the period where a
temperature overshoot is flat in the period; bench/wncsca_methods.py shows it on two loops).

For each N it prints the decision time of the paper's method, of the fast method (its non-linear
checks batched when the loops are on several plants: agents/wncsca/batch.py) and of the fast
method with every check on the engine (``batched=False``), the ratios, the largest relative
difference between the fast and the paper's periods, and what each simulated; and the CPU
time of this process for the paper's and the fast method (fastest run each, building the model
included), whose ratio moves less than the wall clock's when other processes load the machine::

    python bench/wncsca_scale.py [--loops 2,5,10] [--repeat N] [--eps 0.2]

Every run is on a fresh model (no memo shared); the fast methods keep their fastest of
``--repeat`` runs (another process's load only slows), the paper's method runs once for N >= 10
(a minute on this machine) and ``--repeat`` times below.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from agents.wncsca.assignment import Assignment
from agents.wncsca.fast import fast_periods
from agents.wncsca.paper import successive_approximation
from runtime.agent_problems import jcstr_loops
from runtime.direct import loop_model

__all__ = ["measure", "main"]


def _best(run: Callable[[], Assignment], repeat: int) -> tuple[Assignment, float]:
    """The run of least decision time, and the least CPU time of the runs (this process's,
    model building included: less sensitive than the wall clock to the other processes)."""
    runs, cpu = [], []
    for _ in range(max(1, repeat)):
        c0 = time.process_time()
        runs.append(run())
        cpu.append(time.process_time() - c0)
    best = min(runs, key=lambda a: a.decision_time_s)
    if any(a.periods != best.periods for a in runs):
        raise RuntimeError("repeated runs disagree")
    return best, min(cpu)


def measure(n: int, repeat: int = 3, eps: float = 0.2) -> dict[str, Any]:
    """The three methods on the ``n``-loop problem: their assignments and the figures."""
    scenario, delays = jcstr_loops(n, os_tolerance=eps)
    paper, paper_cpu = _best(
        lambda: successive_approximation(loop_model(scenario), delays), repeat if n < 10 else 1
    )
    fast, fast_cpu = _best(lambda: fast_periods(loop_model(scenario), delays), repeat)
    engine, _ = _best(lambda: fast_periods(loop_model(scenario), delays, batched=False), repeat)
    diff = max(abs(fast.periods[k] / p - 1.0) for k, p in paper.periods.items())
    return {
        "n": n,
        "plants": len({lp.plant for lp in scenario.loops.values()}),
        "paper": paper,
        "fast": fast,
        "cpu": (paper_cpu, fast_cpu),
        "engine": engine,
        "diff": diff,
        "same": fast.periods == engine.periods,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--loops", default="2,5,10", help="comma-separated loop counts")
    parser.add_argument("--repeat", type=int, default=3, help="runs per method, fastest kept")
    parser.add_argument("--eps", type=float, default=0.2, help="eps_OS, percentage points")
    args = parser.parse_args(argv)
    print(
        "| loops | plants | paper s | fast s | paper / fast | fast, engine checks s | "
        "paper / that | CPU s paper / fast (ratio) | max fast-paper period diff | paper sims | "
        "fast batched trials (batches) | fast checks | fast, engine checks sims |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in (int(v) for v in args.loops.split(",")):
        r = measure(n, args.repeat, args.eps)
        p, f, e = r["paper"], r["fast"], r["engine"]
        print(
            f"| {n} | {r['plants']} | {p.decision_time_s:.2f} | {f.decision_time_s:.3f} | "
            f"{p.decision_time_s / f.decision_time_s:.1f}x | {e.decision_time_s:.3f} | "
            f"{p.decision_time_s / e.decision_time_s:.1f}x | "
            f"{r['cpu'][0]:.2f} / {r['cpu'][1]:.3f} ({r['cpu'][0] / r['cpu'][1]:.1f}x) | "
            f"{100 * r['diff']:.2f} % | "
            f"{p.simulations} | {f.extra['batched_trials']} ({f.extra['batches']}) | "
            f"{f.extra['checks']} | {e.simulations} |",
            flush=True,
        )
        if not r["same"]:
            print(f"  n={n}: batched and engine checks chose differently: {f.periods} {e.periods}")
        if not (p.feasible and f.feasible):
            print(f"  n={n}: infeasible: paper {p.reason!r}, fast {f.reason!r}")


if __name__ == "__main__":
    main()
