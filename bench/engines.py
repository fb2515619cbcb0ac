"""Wall time of the JCSTR benchmark by each engine, and the ratio to ``direct``.

Run phase (first round to the last) is reported apart from start-up (router, process or thread
start, imports, until every participant is alive). Also the direct engine's throughput in runs per
second, which is what the coordination agent pays per candidate sampling period.

With ``--against REV`` it first times the direct engine here and at git revision ``REV``
(alternately, same machine, same moment; see ``bench/against.py``) and prints both and their
ratio: the before-and-after figure of a change to the engine.

    .venv/bin/python bench/engines.py [--repeat N] [--against REV]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from against import Comparison

from runtime.direct import simulate
from runtime.launcher import launch
from runtime.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"

# CPU time (not wall time: another process's load is not ours), fastest of 15 batches of 20
DIRECT_MS = """
import json, time
from runtime.direct import simulate
from runtime.scenario import load_scenario
scenario = load_scenario(ROOT + "/scenarios/jcstr_benchmark.yaml")
simulate(scenario)
best = float("inf")
for _ in range(15):
    t0 = time.process_time()
    for _ in range(20):
        simulate(scenario)
    best = min(best, (time.process_time() - t0) / 20)
print(json.dumps(best * 1e3))
"""


def against(rev: str, rounds: int) -> None:
    """The direct engine's time per benchmark run here and at ``rev``."""
    with Comparison(rev) as cmp:
        ours, theirs = cmp.run(DIRECT_MS, rounds=rounds)
    print(f"direct engine, CPU ms per jcstr_benchmark run, {rounds} alternating processes:")
    print("| tree | fastest | median |")
    print("|---|---:|---:|")
    for label, xs in (("this tree", ours), (rev, theirs)):
        print(f"| {label} | {min(xs):.1f} | {statistics.median(xs):.1f} |")
    print(f"this tree / {rev}: {min(ours) / min(theirs):.2f} (fastest against fastest)\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--against", metavar="REV", help="also time the direct engine at REV")
    args = parser.parse_args()
    if args.against:
        against(args.against, rounds=5)

    scenario = load_scenario(SCENARIO)
    simulate(scenario)  # warm up imports and caches
    n = 50
    t0 = time.perf_counter()
    for _ in range(n):
        simulate(scenario)
    per_run = (time.perf_counter() - t0) / n
    print(
        f"direct engine, in process: {per_run * 1e3:.1f} ms per benchmark run "
        f"({1 / per_run:.0f} runs/s, {n} runs)"
    )

    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ("direct", "threads", "processes"):
            walls, runs, starts = [], [], []
            for i in range(args.repeat):
                res = launch(SCENARIO, Path(tmp) / f"{engine}{i}", engine=engine)
                if res.code != 0:
                    raise SystemExit(f"{engine}: {res.error}")
                s = res.summary
                walls.append(s["wall_s"])
                runs.append(s["phases_s"].get("run", s["wall_s"]))
                starts.append(s["phases_s"].get("startup", 0.0))
            rows[engine] = (
                statistics.median(walls),
                statistics.median(runs),
                statistics.median(starts),
            )
    base_wall, base_run, _ = rows["direct"]
    print()
    print("| engine | wall s | start-up s | run s | wall / direct | run / direct |")
    print("|---|---:|---:|---:|---:|---:|")
    for engine, (wall, run, start) in rows.items():
        print(
            f"| {engine} | {wall:.3f} | {start:.3f} | {run:.3f} | {wall / base_wall:.0f}x "
            f"| {run / base_run:.0f}x |"
        )
    print(f"\nmedians of {args.repeat} launches each (wncs run incl. summary and plots)")


if __name__ == "__main__":
    main()
