"""Wall time of the JCSTR benchmark by each engine, and the ratio to ``direct``.

Run phase (first round to the last) is reported apart from start-up (router, process or thread
start, imports, until every participant is alive). Also the direct engine's throughput in runs per
second, which is what the coordination agent pays per candidate sampling period.

For the bus engines also the cost of one clock round (run phase over the rounds the history
holds; with sparse rounds a node is ticked only when it has a timer due or a message to collect)
and the floor it is compared with: one Zenoh round trip client -> router -> client -> router ->
client on loopback (a ping answered by a second client), measured right before each launch
(median of 200 pings; this shared machine's round trip moves by 2x within an hour, so each
launch is set against its own floor and the ratios' median printed).

With ``--against REV`` it first times the direct engine here and at git revision ``REV``
(alternately, same machine, same moment; see ``bench/against.py``) and prints both and their
ratio: the before-and-after figure of a change to the engine.

    .venv/bin/python bench/engines.py [--repeat N] [--against REV]
"""

from __future__ import annotations

import argparse
import sqlite3
import statistics
import tempfile
import threading
import time
from pathlib import Path

from against import Comparison

from kernel.bus import open_client, open_router
from runtime.direct import simulate
from runtime.launcher import launch
from runtime.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"

# CPU time (not wall time: another process's load is not ours), fastest of 15 batches of 20
DIRECT_MS = """
import json, time
from kernel.bus import open_client, open_router
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
    cmp.print_table(ours, theirs, digits=1)
    print(f"this tree / {rev}: {min(ours) / min(theirs):.2f} (fastest against fastest)\n")


def round_trip_ms(n: int = 300) -> float:
    """Median wall time of one ping answered by another client through an embedded router."""
    router, locators = open_router("tcp/127.0.0.1:0")
    endpoint = next(loc for loc in locators if loc.startswith("tcp/"))
    a, b = open_client(endpoint), open_client(endpoint)
    got = threading.Event()
    subs = [
        b.declare_subscriber("bench/ping", lambda s: b.put("bench/pong", s.payload.to_bytes())),
        a.declare_subscriber("bench/pong", lambda s: got.set()),
    ]
    times = []
    try:
        time.sleep(0.5)  # let the subscriptions reach the router
        for _ in range(n + 20):
            got.clear()
            t0 = time.perf_counter()
            a.put("bench/ping", b"x")
            if not got.wait(2.0):
                continue
            times.append(time.perf_counter() - t0)
    finally:
        for sub in subs:
            sub.undeclare()
        a.close()
        b.close()
        router.close()
    return statistics.median(times[20:]) * 1e3


def rounds_of(run_dir: Path) -> int:
    """The clock rounds of a bus run (its history's ticks)."""
    db = sqlite3.connect(run_dir / "history.sqlite")
    try:
        (n,) = db.execute("SELECT COUNT(*) FROM ticks").fetchone()
    finally:
        db.close()
    return int(n)


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
    rounds: dict[str, int] = {}
    ratios: dict[str, list[float]] = {"threads": [], "processes": []}
    floors: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ("direct", "threads", "processes"):
            walls, runs, starts = [], [], []
            for i in range(args.repeat):
                if engine != "direct":  # the floor of this very launch, just before it
                    floors.append(round_trip_ms(200))
                res = launch(SCENARIO, Path(tmp) / f"{engine}{i}", engine=engine)
                if res.code != 0:
                    raise SystemExit(f"{engine}: {res.error}")
                s = res.summary
                walls.append(s["wall_s"])
                runs.append(s["phases_s"].get("run", s["wall_s"]))
                starts.append(s["phases_s"].get("startup", 0.0))
                if engine != "direct":
                    rounds[engine] = rounds_of(Path(tmp) / f"{engine}{i}")
                    per_round = runs[-1] / rounds[engine] * 1e3
                    ratios[engine].append(per_round / floors[-1])
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
    lo, hi, mid = min(floors), max(floors), statistics.median(floors)
    print(
        "\nZenoh round trip on loopback (client -> router -> client and back), measured before "
        f"each launch: {lo:.3f}-{hi:.3f} ms, median {mid:.3f}"
    )
    print("| engine | rounds | run ms per round | per round / its launch's round trip (median) |")
    print("|---|---:|---:|---:|")
    for engine in ("threads", "processes"):
        per_round = rows[engine][1] / rounds[engine] * 1e3
        each = ", ".join(f"{r:.1f}" for r in ratios[engine])
        print(
            f"| {engine} | {rounds[engine]} | {per_round:.3f} | "
            f"{statistics.median(ratios[engine]):.1f}x ({each}) |"
        )


if __name__ == "__main__":
    main()
