"""Wall time per simulated unit against the number of loops (issue 20, item 4).

For each N (default 10, 50, 100) the scale scenario of ``wncs scale N`` (N tanks, each its own
non-linear PI, every sensor two hops from one of N/10 gateways, staggered set-point steps; see
``runtime/scale.py``), cut to ``--end-time`` (default 10 s, so that the bus engines' runs stay a
few minutes), on each engine:

* ``direct``: :func:`runtime.direct.simulate` in this process (no plots), fastest of two;
* ``threads`` and ``processes``: ``wncs run`` (:func:`runtime.launcher.launch`), start-up (until
  the first round) apart from the run phase (first round to the clock's stop); the rounds are
  the history's ticks.

``--plant tank_train`` runs the plant-wide scenario of coupled loops instead (N tanks in series
in one plant, each tank's outflow partly feeding the next; ``wncs scale N --plant tank_train``,
``scenarios/tank_train_20.yaml`` at N = 20), ``--plant jcstr`` N/2 reactors (times in pu).

Printed: a table per engine and N (nodes, rounds, start-up, run, run seconds per simulated
second and per round) and, per engine, the exponent ``k`` of ``run per unit ~ N^k`` fitted by
least squares on log-log axes (1: linear growth; 2: quadratic). Independent loops sample at
their own instants once the WSN has delayed them, so the rounds grow as N: ``k`` near 1 needs a
round whose cost does not grow with the number of nodes.

    .venv/bin/python bench/scale.py [--loops 10 50 100] [--engines direct threads processes]
                                    [--end-time 10] [--plant tank|jcstr|tank_train]

The coupled scenario as shipped (20 loops, 60 s) on the bus engines::

    .venv/bin/python bench/scale.py --plant tank_train --loops 20 --end-time 60 \
                                    --engines threads processes
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from engines import rounds_of

from runtime.direct import simulate
from runtime.launcher import launch
from runtime.scale import PLANTS, write_scale
from scenario import load_scenario


def growth(ns: list[int], per_unit: list[float]) -> float:
    """The exponent k of ``per_unit ~ N^k`` (least squares on log-log axes)."""
    k, _ = np.polyfit(np.log(ns), np.log(per_unit), 1)
    return float(k)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loops", type=int, nargs="+", default=[10, 50, 100])
    parser.add_argument(
        "--engines", nargs="+", default=["direct", "threads", "processes"], help="engines to run"
    )
    parser.add_argument(
        "--end-time", type=float, default=10.0, help="simulated time per run (s; jcstr: pu)"
    )
    parser.add_argument(
        "--plant", choices=PLANTS, default="tank", help="tank_train: the coupled loops of one plant"
    )
    args = parser.parse_args()
    unit = "pu" if args.plant == "jcstr" else "s"
    print(
        f"scale scenarios ({args.plant} loops over WSN paths), {args.end_time:g} {unit} "
        "simulated each"
    )
    print(
        "| engine | loops | nodes | rounds | start-up s | run s "
        f"| run s per sim {unit} | ms/round |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    fits: dict[str, tuple[list[int], list[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.loops:
            path = Path(tmp) / f"scale{n}.yaml"
            write_scale(n, path, plant=args.plant, end_time=args.end_time)
            scenario = load_scenario(path)
            nodes = len(scenario.participants()) + 1  # and the clock
            for engine in args.engines:
                if engine == "direct":
                    runs = []
                    for _ in range(2):
                        t0 = time.perf_counter()
                        simulate(scenario)
                        runs.append(time.perf_counter() - t0)
                    start, run, rounds = 0.0, min(runs), None
                else:
                    out = Path(tmp) / f"{engine}{n}"
                    res = launch(path, out, engine=engine)
                    if res.code != 0:
                        print(f"| {engine} | {n} | {nodes} | failed: {res.error} |")
                        continue
                    phases = res.summary["phases_s"]
                    start, run, rounds = phases["startup"], phases["run"], rounds_of(out)
                per_unit = run / args.end_time
                fits.setdefault(engine, ([], []))
                fits[engine][0].append(n)
                fits[engine][1].append(per_unit)
                per_round = "-" if rounds is None else f"{run / rounds * 1e3:.2f}"
                print(
                    f"| {engine} | {n} | {nodes} | {rounds or '-'} | {start:.2f} | {run:.2f} "
                    f"| {per_unit:.3f} | {per_round} |",
                    flush=True,
                )
    print("\ngrowth of the run time per simulated unit with N (1 = linear, 2 = quadratic):")
    for engine, (ns, per_unit) in fits.items():
        if len(ns) > 1:
            print(f"  {engine}: N^{growth(ns, per_unit):.2f} over N = {ns}")


if __name__ == "__main__":
    main()
