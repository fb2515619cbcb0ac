"""Speed of the TSCH MAC (issue 15): simulated slotframes per second of wall time.

A square grid of ``n`` nodes 20 m apart with the gateway in a corner; every other node is a
sensor sending one packet per ``period`` slots to the gateway over its shortest route (breadth
first over the grid's neighbours); the central scheduler gives every flow its chains of cells
(one retry cell per hop) in a slotframe of ``length`` slots with 16 channel offsets; every link
has a PDR of ``pdr`` on every channel. The MAC then runs ``frames`` slotframes with every
packet submitted at its sampling instant, as the gateway does. Printed per size: cells, flows,
packets carried and lost, wall time, slotframes per second and packets per second.

    .venv/bin/python bench/tsch_slotframes.py [--sizes 50 200] [--frames 200] [--pdr 0.9]
"""

from __future__ import annotations

import argparse
import math
import time
from collections import deque

import numpy as np

from gateway.tsch.mac import TschMac
from gateway.tsch.schedule import Flow, build_schedule

SLOT_TICKS = 10_000  # 10 ms at 1 s per time unit


def grid_routes(n: int) -> dict[str, tuple[str, ...]]:
    """Shortest routes to the gateway ``n0`` on a square grid of ``n`` nodes (4-neighbours)."""
    side = math.ceil(math.sqrt(n))
    names = [f"n{i}" for i in range(n)]
    pos = {names[i]: (i % side, i // side) for i in range(n)}
    at = {p: name for name, p in pos.items()}
    parent: dict[str, str | None] = {"n0": None}
    todo = deque(["n0"])
    while todo:
        u = todo.popleft()
        x, y = pos[u]
        for v in (at.get((x + 1, y)), at.get((x - 1, y)), at.get((x, y + 1)), at.get((x, y - 1))):
            if v is not None and v not in parent:
                parent[v] = u
                todo.append(v)
    routes = {}
    for name in names[1:]:
        route = [name]
        while parent[route[-1]] is not None:
            route.append(parent[route[-1]])  # type: ignore[arg-type]
        routes[name] = tuple(route)
    return routes


def run(n: int, frames: int, pdr: float, length: int, period: int) -> dict[str, float]:
    routes = grid_routes(n)
    flows = [
        Flow(f"{s}.sensor", r, period, offset=k % period) for k, (s, r) in enumerate(routes.items())
    ]
    schedule = build_schedule(flows, length, 16, retry_cells=1)
    mac = TschMac(
        schedule,
        slot_ticks=SLOT_TICKS,
        hopping=tuple(range(11, 27)),
        pdr=lambda a, b, ch, t: pdr,
        rng=np.random.default_rng(1),
        queue_capacity=16,
        max_retries=3,
    )
    sends = sorted(
        (f.offset + k * f.period, f.name, f.route)
        for f in flows
        for k in range((frames * length - f.offset + f.period - 1) // f.period)
    )
    delivered = lost = 0
    wall0 = time.perf_counter()
    for i, (slot, name, route) in enumerate(sends):
        t = slot * SLOT_TICKS
        for o in mac.advance(t):
            delivered += o.delivered
            lost += not o.delivered
        early = mac.submit((name, i), route, t)
        lost += early is not None
    for o in mac.advance(frames * length * SLOT_TICKS):
        delivered += o.delivered
        lost += not o.delivered
    wall = time.perf_counter() - wall0
    return {
        "nodes": n,
        "flows": len(flows),
        "cells": len(schedule.cells),
        "lacking": sum(schedule.lacking.values()),
        "delivered": delivered,
        "lost": lost,
        "wall_s": wall,
        "frames_per_s": frames / wall,
        "packets_per_s": (delivered + lost) / wall,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 200])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--pdr", type=float, default=0.9)
    parser.add_argument("--length", type=int, default=101, help="slots per slotframe")
    parser.add_argument("--period", type=int, default=505, help="slots between a flow's packets")
    args = parser.parse_args()
    print(
        f"TSCH MAC: {args.frames} slotframes of {args.length} slots, PDR {args.pdr}, "
        f"a packet per {args.period} slots per sensor"
    )
    print(
        f"{'nodes':>6}{'flows':>7}{'cells':>7}{'lacking':>9}{'delivered':>11}{'lost':>7}"
        f"{'wall s':>9}{'frames/s':>10}{'packets/s':>11}"
    )
    for n in args.sizes:
        r = run(n, args.frames, args.pdr, args.length, args.period)
        print(
            f"{r['nodes']:>6}{r['flows']:>7}{r['cells']:>7}{r['lacking']:>9}{r['delivered']:>11}"
            f"{r['lost']:>7}{r['wall_s']:>9.2f}{r['frames_per_s']:>10.1f}{r['packets_per_s']:>11.0f}"
        )


if __name__ == "__main__":
    main()
