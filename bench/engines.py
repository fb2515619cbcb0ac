"""Wall time of the JCSTR benchmark by each engine, and the ratio to ``direct``.

Run phase (first round to the last) is reported apart from start-up (router, process or thread
start, imports, until every participant is alive). Also the direct engine's throughput in runs per
second, which is what the coordination agent pays per candidate sampling period.

For the bus engines also the cost of one clock round (run phase over the rounds the history
holds; with sparse rounds a node is ticked only when it has a timer due or a message to collect)
and the floor it is compared with: one Zenoh round trip client -> router -> client -> router ->
client on loopback (a ping answered by a second client), measured right before each launch
(median of 200 pings; this shared machine's round trip moves by 2x within an hour, so each
launch is set against its own floor and the ratios' median printed). The floor is measured
twice: with the router and the two clients placed as the engine places the clock, the router and
a node (a router process; the answering client in this process for the threads engine, in a
process of its own for the processes engine), and with all three in this process, where zenoh
crosses no process boundary (a floor no run's round can reach; with ``ZENOH_RUNTIME='(rx:
(handover: app), tx: (handover: app), acc: (handover: app))'`` it is about 0.1 ms, 2-4x faster
than across processes: ``docs/benchmarks.md``). The threads engine's nodes share one session
(:func:`runtime.launcher._run_threads`), so its rounds no longer take the router's path at all:
its floor here is the issue's, a round trip through the router, not the path it takes (a ping
on one session is about 0.07 ms: ``docs/benchmarks.md``).

With ``--against REV`` it first times the direct engine here and at git revision ``REV``
(alternately, same machine, same moment; see ``bench/against.py``) and prints both and their
ratio: the before-and-after figure of a change to the engine.

The threads engine's process and router run on one CPU by default (:mod:`runtime.affinity`), and
its floors are measured pinned the same way. With ``--placements`` it also launches each bus
engine placed the other way (``wncs run --affinity``): the threads engine spread over every CPU,
the processes engine on the first CPU but the historian on the last (floors pinned likewise).

    .venv/bin/python bench/engines.py [--repeat N] [--against REV] [--placements]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from against import Comparison

from kernel.bus import Session, open_client, open_router
from kernel.router_process import RouterProcess
from runtime.affinity import ANY, cpus_of, pinned_here, with_default
from runtime.direct import simulate
from runtime.launcher import launch
from scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"

# CPU time (not wall time: another process's load is not ours), fastest of 15 batches of 20
DIRECT_MS = """
import json, time
from kernel.bus import open_client, open_router
from runtime.direct import simulate
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


_PONG = """
import sys
from kernel.bus import open_client
session = open_client(sys.argv[1])
sub = session.declare_subscriber(
    "bench/ping", lambda s: session.put("bench/pong", s.payload.to_bytes())
)
print("ready", flush=True)
sys.stdin.read()
"""


def _ping(a: Session, answered: threading.Event, n: int) -> float:
    """Median ms of ``n`` pings from ``a`` (after 20 to warm up), ``answered`` set by the pong."""
    times = []
    time.sleep(0.5)  # let the subscriptions reach the router
    for _ in range(n + 20):
        answered.clear()
        t0 = time.perf_counter()
        a.put("bench/ping", b"x")
        if answered.wait(2.0):
            times.append(time.perf_counter() - t0)
    if len(times) <= 20:
        raise SystemExit("the round-trip probe got no answers")
    return statistics.median(times[20:]) * 1e3


def round_trip_ms(n: int = 300, topology: str = "in-process") -> float:
    """Median wall time of one ping answered by another client through a router.

    ``topology`` places them: ``"in-process"``, a router embedded here and both clients here;
    ``"threads"``, the threads engine's: a router process (:class:`RouterProcess`, as a run
    starts it) and both clients here; ``"processes"``, the processes engine's: a router process,
    the pinging client here and the answering one in a process of its own.
    """
    answered = threading.Event()
    with contextlib.ExitStack() as stack:  # closes what it opened, last first
        if topology == "in-process":
            router, locators = open_router("tcp/127.0.0.1:0")
            stack.callback(router.close)
        else:
            router_process = RouterProcess("tcp/127.0.0.1:0")
            locators = router_process.locators
            stack.callback(router_process.close)
        endpoint = next(loc for loc in locators if loc.startswith("tcp/"))
        a = open_client(endpoint)
        stack.callback(a.close)
        stack.callback(a.declare_subscriber("bench/pong", lambda s: answered.set()).undeclare)
        if topology == "processes":
            child = subprocess.Popen(
                [sys.executable, "-c", _PONG, endpoint],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
            )
            stack.callback(child.wait)
            stack.callback(child.kill)
            assert child.stdout is not None
            child.stdout.readline()  # its subscriber is declared
        else:
            b = open_client(endpoint)
            stack.callback(b.close)
            pong = b.declare_subscriber(
                "bench/ping", lambda s: b.put("bench/pong", s.payload.to_bytes())
            )
            stack.callback(pong.undeclare)
        return _ping(a, answered, n)


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
    parser.add_argument(
        "--placements",
        action="store_true",
        help="also launch each bus engine placed the other way (runtime.affinity): threads "
        "spread over every CPU, processes with '*=' the first and historian= the last",
    )
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
    # per launch kind: (its run's ms per round, its topology's round trip, the in-process one)
    launches: dict[str, list[tuple[float, float, float]]] = {}
    kinds: list[tuple[str, str, dict[str, frozenset[int]]]] = [
        (engine, engine, {}) for engine in ("direct", "threads", "processes")
    ]
    if args.placements:
        cpus = sorted(os.sched_getaffinity(0))
        first, last = frozenset(cpus[:1]), frozenset(cpus[-1:])
        every = ",".join(map(str, cpus))
        kinds += [
            (f"threads --affinity '*={every}'", "threads", {"*": frozenset(cpus)}),
            (
                f"processes --affinity '*={cpus[0]}' --affinity historian={cpus[-1]}",
                "processes",
                {"*": first, "historian": last},
            ),
        ]
    with tempfile.TemporaryDirectory() as tmp:
        for kind, (name, engine, affinity) in enumerate(kinds):
            walls, runs, starts = [], [], []
            for i in range(args.repeat):
                if engine != "direct":  # the floors of this very launch, just before it, with
                    # the router and the clients pinned as the run's '*' (they inherit it)
                    with pinned_here(cpus_of(with_default(affinity, engine), ANY)):
                        floor = round_trip_ms(200, topology=engine)
                        floor_here = round_trip_ms(200)
                out = Path(tmp) / f"{kind}-{i}"
                res = launch(SCENARIO, out, engine=engine, affinity=affinity)
                if res.code != 0:
                    raise SystemExit(f"{name}: {res.error}")
                s = res.summary
                walls.append(s["wall_s"])
                runs.append(s["phases_s"].get("run", s["wall_s"]))
                starts.append(s["phases_s"].get("startup", 0.0))
                if engine != "direct":
                    rounds[name] = rounds_of(out)
                    launches.setdefault(name, []).append(
                        (runs[-1] / rounds[name] * 1e3, floor, floor_here)
                    )
            rows[name] = (
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
    print(
        "\nper round against the Zenoh round trip (client -> router -> client and back) measured "
        "right before each launch, with the router and clients placed as the engine places "
        "them, and with all three in this process; ratios are medians of the launches' own"
    )
    print(
        "| engine | rounds | run ms per round | round trip as the engine places them, ms | "
        "per round / that | round trip in one process, ms | per round / that |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for engine, each in launches.items():
        per_round, floor, floor_here = (statistics.median(x) for x in zip(*each, strict=True))
        ratio = [r / f for r, f, _ in each]
        ratio_here = [r / f for r, _, f in each]
        print(
            f"| {engine} | {rounds[engine]} | {per_round:.3f} | {floor:.3f} | "
            f"{statistics.median(ratio):.1f}x ({', '.join(f'{x:.1f}' for x in ratio)}) | "
            f"{floor_here:.3f} | {statistics.median(ratio_here):.1f}x |"
        )


if __name__ == "__main__":
    main()
