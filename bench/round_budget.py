"""Where a bus round's time goes (issue 20, item 2): unit costs times what a round does.

A profiler is no help on the threads engine (every node shares the interpreter lock, so a call
that releases it, a zenoh put or an SQLite commit, is charged with the other threads' work),
nor on the processes engine (eight processes on two cores). So this bench measures each step of
a round alone, in one thread, and multiplies by how often a run does it:

* from a real threads run of the scenario (default the JCSTR benchmark): the rounds, the data
  messages, their deliveries (each message to the historian and to every node listening to its
  key), the nodes' participations (``Stop.rounds_taken``) and the ticks: one per node taking
  part (``clock/tick/<node>``), plus one to every node every ``kernel.clock.SYNC_ROUNDS``
  rounds, and the clock's logs of ticks (``clock/log``, counted in the run: the historian's and
  the progress line's; until they took the log, each woke for every tick). (The historian
  subscribed to ``**`` until it took the data keys alone, :func:`bus_schemas.keys.data_all`:
  it also woke for every addressed tick and every Done, to drop them);
* unit costs, median of many: encoding a message (``model_dump`` + msgpack), decoding and
  validating one (envelope + body), a zenoh ``put`` (the call alone; batched, as the nodes and
  the clock publish, and ``express`` as they did before: an immediate write per message, 60
  times dearer for no shorter round), a queue hop between two
  threads (one wake-up: zenoh-python runs each subscriber's callback in a thread of its own,
  so a sample costs one hop to reach its callback; a node's round runs in its tick's callback
  and the clock's next tick goes out from the Done's callback, and a data message is filed by
  its callback: no second hop, but for the clock's log to an observer's loop), an SQLite insert
  and a commit (the historian's), and a Zenoh round trip (``bench/engines.py``) over a router
  process as a threads run places it, and all in one process;
* the round's skeleton: a tick's callback at the node puts a ``Done`` and the ``Done``'s callback
  at the clock puts the next tick (as :mod:`kernel.node` and :mod:`kernel.clock` do), over a
  router in a process of its own, as in a run, with no work at all: the floor of the protocol
  as built. (Since the threads engine's nodes share one session, its ticks and ``Done``s no
  longer cross the router: the skeleton is the processes engine's floor, and a threads run's
  trips are shorter than it: ``docs/benchmarks.md``.)

Printed: per round, each part's count and cost, their sum, and the measured per-round wall cost
of the run (run phase over rounds) with its ratio to the round trip. What the sum does not cover
is the rounds' critical path: the tick's and the Dones' trips over the router and the threads
waiting for the interpreter lock. So a threads run and a processes run are stamped
(:func:`critical_path`, :class:`Stamps`; in the processes run each process stamps itself and
dumps its stamps as its node ends): for each round with one node taking part, the tick's way
out to the node's callback, the node's round, its ``Done``'s way back to the clock's callback
and the clock's work to the next tick, set beside the skeleton's one way; and how much of the
run its slowest rounds hold.

    .venv/bin/python bench/round_budget.py [SCENARIO]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import queue
import sqlite3
import statistics
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from unittest import mock

from engines import round_trip_ms, rounds_of

from bus_schemas import Done, Stop, Tick, codec
from kernel.bus import open_client, open_router
from kernel.clock import SYNC_ROUNDS, ClockRunner
from kernel.node import BusNode
from kernel.router_process import RouterProcess
from runtime.direct import behaviour_of
from runtime.history import connect
from runtime.launcher import launch
from scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"


def median_us(fn: Callable[[], object], n: int = 2000) -> float:
    """Median wall time of ``fn()`` in microseconds, over batches of 50 calls."""
    fn()
    per = []
    for _ in range(max(n // 50, 5)):
        t0 = time.perf_counter()
        for _ in range(50):
            fn()
        per.append((time.perf_counter() - t0) / 50)
    return statistics.median(per) * 1e6


def unit_costs() -> dict[str, float]:
    """Microseconds per step, each alone in one thread."""
    announced = {"loop/level/meas": (2**63 + 1,), "plant/reactor/state": (2**62 + 3,)}
    tick = Tick(
        round=12,
        t=1_200_000,
        expected={"loop/level/meas": 1, "plant/reactor/state": 1},
        digests=announced,
    )
    done = Done(
        round=12,
        node="level_controller",
        published={"loop/level/u": 1},
        digests={"loop/level/u": (2**63 + 5,)},
        next_time=None,
    )
    raw = codec.encode(run="r0123456789", src="clock", seq=7, round=12, t=1_200_000, body=tick)
    out: dict[str, float] = {}
    out["encode"] = median_us(
        lambda: codec.encode(run="r0123456789", src="n", seq=1, round=12, t=1, body=done)
    )
    out["decode"] = median_us(lambda: codec.decode_body(codec.decode_envelope(raw), Tick))
    q: queue.Queue[bytes] = queue.Queue()
    back: queue.Queue[bytes] = queue.Queue()

    def echo() -> None:
        while (item := q.get()) != b"":
            back.put(item)

    th = threading.Thread(target=echo, daemon=True)
    th.start()

    def hop_pair() -> None:
        q.put(raw)
        back.get()

    out["queue hop"] = median_us(hop_pair, 1000) / 2
    q.put(b"")
    th.join()
    router, locators = open_router("tcp/127.0.0.1:0")
    endpoint = next(loc for loc in locators if loc.startswith("tcp/"))
    a, b = open_client(endpoint), open_client(endpoint)
    sub = b.declare_subscriber("bench/x", lambda s: None)
    pub = a.declare_publisher("bench/x")  # batched, as the nodes and the clock publish
    express = a.declare_publisher("bench/x", express=True)  # what they did before
    time.sleep(0.5)
    try:
        out["zenoh put"] = median_us(lambda: pub.put(raw))
        out["(express put)"] = median_us(lambda: express.put(raw))
    finally:
        sub.undeclare()
        pub.undeclare()
        express.undeclare()
        a.close()
        b.close()
        router.close()
    with tempfile.TemporaryDirectory() as tmp:
        db = connect(Path(tmp) / "h.sqlite", create=True)
        row = (1, 2, "loop/level/u", "level_controller", 3, raw)
        out["sqlite insert"] = median_us(
            lambda: db.execute(
                "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)",
                row,
            )
        )
        ticks = itertools.count()

        def tick_and_commit() -> None:
            db.execute(
                "INSERT INTO ticks (round, t, expected) VALUES (?, ?, ?)", (next(ticks), 0, "{}")
            )
            db.commit()

        out["sqlite commit"] = median_us(tick_and_commit, 500)
        db.close()
    return out


def skeleton_ms(n: int = 400) -> float:
    """Median wall time of a round with no work (see the module docstring), milliseconds."""
    router = RouterProcess("tcp/127.0.0.1:0")
    endpoint = next(loc for loc in router.locators if loc.startswith("tcp/"))
    clock, node = open_client(endpoint), open_client(endpoint)
    done_pub = node.declare_publisher("bench/done")
    tick_pub = clock.declare_publisher("bench/tick")
    times: list[float] = []
    over = threading.Event()

    def on_done(_: object) -> None:  # the clock's Done callback: the round ends, the next starts
        times.append(time.perf_counter())
        if len(times) > n + 50:
            over.set()
        else:
            tick_pub.put(b"x" * 40)

    subs = [
        clock.declare_subscriber("bench/done", on_done),
        node.declare_subscriber("bench/tick", lambda s: done_pub.put(s.payload.to_bytes())),
    ]
    time.sleep(0.5)  # let the subscriptions reach the router
    try:
        times.append(time.perf_counter())
        tick_pub.put(b"x" * 40)
        if not over.wait(timeout=60):
            raise SystemExit("the skeleton's rounds did not complete within 60 s")
    finally:
        for sub in subs:
            sub.undeclare()
        clock.close()
        node.close()
        router.close()
    rounds = [b - a for a, b in itertools.pairwise(times)]
    return statistics.median(rounds[50:]) * 1e3


def counts(scenario_path: Path) -> tuple[dict[str, float], float, int]:
    """What one threads run does per round, its per-round wall cost (ms) and its rounds."""
    scenario = load_scenario(scenario_path)
    names = scenario.participants()
    behaviours = {n: behaviour_of(scenario, n) for n in names if n != "historian"}
    logs = [0]
    publish_log = ClockRunner._publish_log

    def counted(self: ClockRunner, stop: Stop | None = None) -> None:
        logs[0] += 1
        publish_log(self, stop)

    ClockRunner._publish_log = counted  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            res = launch(scenario_path, Path(tmp) / "run", engine="threads")
        finally:
            ClockRunner._publish_log = publish_log  # type: ignore[method-assign]
        if res.code != 0:
            raise SystemExit(res.error)
        rounds = rounds_of(Path(tmp) / "run")
        db = sqlite3.connect(Path(tmp) / "run" / "history.sqlite")
        msg_keys = [k for (k,) in db.execute("SELECT key FROM messages")]
        (stop,) = db.execute("SELECT value FROM meta WHERE name = 'stop'").fetchone()
        db.close()
        run_ms = res.summary["phases_s"]["run"] * 1e3
    rounds_taken = json.loads(stop)["rounds_taken"]
    taken = sum(rounds_taken.values())
    # ticks addressed to the round's nodes (clock/tick/<node>; the historian takes the clock's
    # log), and to every node every SYNC_ROUNDS rounds
    addressed = (taken - rounds_taken.get("historian", 0)) / rounds + (len(names) - 1) / SYNC_ROUNDS
    listeners = {
        k: 1 + sum(b.listens_to(k) for b in behaviours.values()) for k in set(msg_keys)
    }  # the historian and every behaviour subscribed to it
    deliveries = sum(listeners[k] for k in msg_keys)
    per_round = {
        "messages published (encode + put)": len(msg_keys) / rounds,
        "Done answers (encode + put; clock: callback hop + decode)": taken / rounds,
        "message deliveries (callback hop + decode, filed there)": deliveries / rounds,
        "ticks put (one per addressee, and the clock's logs)": addressed + logs[0] / rounds,
        "tick deliveries to their nodes (callback hop + decode)": addressed,
        "the clock's log to the historian and the progress line (2 hops + decode each)": 2
        * logs[0]
        / rounds,
        "historian rows (insert)": (len(msg_keys) + rounds) / rounds,
        "historian commits (one per log)": logs[0] / rounds,
    }
    return per_round, run_ms / rounds, rounds


SEGMENTS = (
    "tick out -> the node's tick callback (clock -> router -> node, the callback's thread)",
    "the node's round (decode, collect, behaviour, its puts and its Done)",
    "the node's Done -> the clock's Done callback (node -> router -> clock)",
    "the clock's Done callback -> the next tick out (decode, plan, encode, put)",
)


class Stamps:
    """Critical-path stamps (``perf_counter``: ``CLOCK_MONOTONIC``, one clock for every thread
    and process of the machine) at each tick published, each node's tick callback entered and
    left, and each ``Done`` callback of the clock entered, by round."""

    def __init__(self) -> None:
        self.ticks: dict[int, float] = {}
        self.nodes: dict[int, list[tuple[float, float]]] = {}
        self.dones: dict[int, list[float]] = {}

    def install(self, dump_to: Path | None = None) -> Callable[[], None]:
        """Stamp this process's clock and nodes; return what takes the stamping off again.
        With ``dump_to`` each clock's and node's ``run`` writes this process's stamps there as
        it ends (a forked node ends with ``os._exit``: no ``atexit``)."""
        local = threading.local()
        publish_tick, on_tick, round_, on_done = (
            ClockRunner._publish_tick,
            BusNode._on_tick,
            BusNode._round_,
            ClockRunner._on_done,
        )

        def stamped_publish_tick(runner: ClockRunner, tick: Tick, to: frozenset[str]) -> None:
            publish_tick(runner, tick, to)
            self.ticks[tick.round] = time.perf_counter()

        def stamped_on_tick(node: BusNode, sample: Any) -> None:
            t0, local.round = time.perf_counter(), None
            try:
                on_tick(node, sample)
            finally:
                if local.round is not None:
                    self.nodes.setdefault(local.round, []).append((t0, time.perf_counter()))

        def noted_round(node: BusNode, tick: Tick) -> None:
            local.round = tick.round
            round_(node, tick)

        def stamped_on_done(runner: ClockRunner, sample: Any) -> None:
            self.dones.setdefault(runner._tick.round, []).append(time.perf_counter())
            on_done(runner, sample)

        patches: dict[tuple[type, str], Callable[..., Any]] = {
            (ClockRunner, "_publish_tick"): stamped_publish_tick,
            (BusNode, "_on_tick"): stamped_on_tick,
            (BusNode, "_round_"): noted_round,
            (ClockRunner, "_on_done"): stamped_on_done,
        }
        if dump_to is not None:
            for cls in (BusNode, ClockRunner):
                patches[(cls, "run")] = self._dumping(cls.run, dump_to)  # type: ignore[attr-defined]
        originals = {where: getattr(*where) for where in patches}
        for (cls, name), fn in patches.items():
            setattr(cls, name, fn)

        def restore() -> None:
            for (cls, name), fn in originals.items():
                setattr(cls, name, fn)

        return restore

    def _dumping(self, run: Callable[[Any], int], dump_to: Path) -> Callable[[Any], int]:
        def dumping_run(obj: Any) -> int:
            try:
                return run(obj)
            finally:
                data = {"ticks": self.ticks, "nodes": self.nodes, "dones": self.dones}
                (dump_to / f"{os.getpid()}.json").write_text(json.dumps(data))

        return dumping_run

    def merge(self, path: Path) -> None:
        """Add the stamps another process dumped (:meth:`install`) to these."""
        data = json.loads(path.read_text())
        self.ticks.update({int(r): t for r, t in data["ticks"].items()})
        for r, spans in data["nodes"].items():
            self.nodes.setdefault(int(r), []).extend((a, b) for a, b in spans)
        for r, ts in data["dones"].items():
            self.dones.setdefault(int(r), []).extend(ts)

    def segments(self) -> tuple[dict[str, list[float]], list[float]]:
        """In microseconds, the four :data:`SEGMENTS` of every round in which exactly one node
        took part (its tick to the next tick; the rounds with more nodes overlap theirs), and
        every round's length."""
        segments: dict[str, list[float]] = {s: [] for s in SEGMENTS}
        lengths = []
        ticks, nodes, dones = self.ticks, self.nodes, self.dones
        for r in range(1, max(ticks)):  # round 0 is start-up
            if r + 1 not in ticks:
                continue
            lengths.append((ticks[r + 1] - ticks[r]) * 1e6)
            if len(nodes.get(r, ())) != 1 or len(dones.get(r, ())) != 1:
                continue
            (t_in, t_out), (t_done,) = nodes[r][0], dones[r]
            stamps = (ticks[r], t_in, t_out, t_done, ticks[r + 1])
            for what, (a, b) in zip(SEGMENTS, itertools.pairwise(stamps), strict=True):
                segments[what].append((b - a) * 1e6)
        return segments, lengths


STAMPS_ENV = "WNCS_BENCH_STAMPS"
SITECUSTOMIZE = f"""
import os
if os.environ.get({STAMPS_ENV!r}):
    from pathlib import Path
    from round_budget import Stamps
    Stamps().install(dump_to=Path(os.environ[{STAMPS_ENV!r}]))
"""
"""Every process of a processes run imports it at its start (``PYTHONPATH``): the fork server
installs the stamping before it forks the nodes."""


def critical_path(
    scenario_path: Path, engine: str = "threads"
) -> tuple[dict[str, list[float]], list[float]]:
    """Where the wall time of a run's rounds goes (:class:`Stamps`, :meth:`Stamps.segments`):
    the threads engine stamped in this process, the processes engine in each of its processes
    (a ``sitecustomize`` on their ``PYTHONPATH``)."""
    stamps = Stamps()
    with tempfile.TemporaryDirectory() as tmp:
        if engine == "threads":
            restore = stamps.install()
            try:
                res = launch(scenario_path, Path(tmp) / "run", engine="threads")
            finally:
                restore()
        else:
            site, dumps = Path(tmp) / "site", Path(tmp) / "stamps"
            site.mkdir()
            dumps.mkdir()
            (site / "sitecustomize.py").write_text(SITECUSTOMIZE)
            here = Path(__file__).resolve().parent
            path = os.pathsep.join([str(site), str(here), str(here.parent)])
            with mock.patch.dict(os.environ, {"PYTHONPATH": path, STAMPS_ENV: str(dumps)}):
                res = launch(scenario_path, Path(tmp) / "run", engine=engine)
            for dump in dumps.glob("*.json"):
                stamps.merge(dump)
    if res.code != 0:
        raise SystemExit(res.error)
    return stamps.segments()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", type=Path, default=SCENARIO)
    args = parser.parse_args()
    per_round, wall_ms, rounds = counts(args.scenario)
    unit = unit_costs()
    floor = round_trip_ms(topology="threads")  # a router process, both clients here, as in a run
    floor_here = round_trip_ms()  # all in this process: a floor below any run's round
    bare = skeleton_ms()
    print("unit costs, one thread, median (us):")
    for what, us in unit.items():
        print(f"  {what:14s} {us:7.1f}")
    cost = {
        "messages published (encode + put)": unit["encode"] + unit["zenoh put"],
        "Done answers (encode + put; clock: callback hop + decode)": unit["encode"]
        + unit["zenoh put"]
        + unit["queue hop"]
        + unit["decode"],
        "message deliveries (callback hop + decode, filed there)": unit["queue hop"]
        + unit["decode"],
        "ticks put (one per addressee, and the clock's logs)": unit["zenoh put"],
        "tick deliveries to their nodes (callback hop + decode)": unit["queue hop"]
        + unit["decode"],
        "the clock's log to the historian and the progress line (2 hops + decode each)": 2
        * unit["queue hop"]
        + unit["decode"],
        "historian rows (insert)": unit["sqlite insert"],
        "historian commits (one per log)": unit["sqlite commit"],
    }
    print(f"\n{args.scenario.name}, threads engine: {rounds} rounds")
    print("| part of a round | per round | us each | us per round |")
    print("|---|---:|---:|---:|")
    total = 0.0
    for what, n in per_round.items():
        us = n * cost[what]
        total += us
        print(f"| {what} | {n:.2f} | {cost[what]:.1f} | {us:.0f} |")
    print(f"| the tick's encoding (once) | 1 | {unit['encode']:.1f} | {unit['encode']:.0f} |")
    total += unit["encode"]
    print(f"| **sum of the parts** | | | **{total:.0f}** |")
    print(
        f"\nmeasured: {wall_ms * 1e3:.0f} us per round (run phase / rounds); Zenoh round trip "
        f"over a router process {floor * 1e3:.0f} us: {wall_ms / floor:.1f}x the floor (all in "
        f"one process {floor_here * 1e3:.0f} us: {wall_ms / floor_here:.1f}x); the parts are "
        f"{total / (wall_ms * 1e3):.0%} of it, the rest is the round's critical path (tick out, "
        "Dones back over the router) and threads waiting for the interpreter lock"
    )
    print(
        f"the round's skeleton (tick to a node's callback, Done back to the clock's callback, no "
        f"work): {bare * 1e3:.0f} us, {bare / floor:.1f}x the round trip; the run's rounds "
        f"cost {wall_ms / bare:.1f}x their skeleton"
    )
    for engine in ("threads", "processes"):
        _print_critical_path(engine, *critical_path(args.scenario, engine), bare)


def _print_critical_path(
    engine: str, segments: dict[str, list[float]], lengths: list[float], bare_ms: float
) -> None:
    n_single = len(next(iter(segments.values())))
    mean_single = sum(statistics.mean(v) for v in segments.values())
    print(
        f"\nthe critical path, from stamps in a {engine} run: the {n_single} of "
        f"{len(lengths)} rounds with one node taking part (mean {mean_single:.0f} us)"
    )
    print("| segment | median us | mean us | share of the mean |")
    print("|---|---:|---:|---:|")
    for what, xs in segments.items():
        mean = statistics.mean(xs)
        print(f"| {what} | {statistics.median(xs):.0f} | {mean:.0f} | {mean / mean_single:.0%} |")
    lengths.sort()
    slow = [x for x in lengths if x > 2000]
    print(
        f"every round: median {statistics.median(lengths):.0f} us, 90th percentile "
        f"{lengths[int(0.9 * len(lengths))]:.0f} us, longest {lengths[-1]:.0f} us; rounds over "
        f"2 ms: {len(slow)} holding {sum(slow) / sum(lengths):.0%} of the run; the skeleton's "
        f"one way (threads placement) is {bare_ms * 1e3 / 2:.0f} us"
    )


if __name__ == "__main__":
    main()
