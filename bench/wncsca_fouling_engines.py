"""The fouling scenario on the bus decides as on the direct engine (issue 35, acceptance: "the bus
engines give the same decisions").

``scenarios/jcstr_fouling.yaml`` (identification first, the paper's steps, the jacket fouling
caught by the model watch, re-identification and new periods; ``tests/integration/
test_wncsca_fouling.py`` checks it on the direct engine) is launched on the direct engine and on
``--engine`` (default ``threads``: real Zenoh sessions on a router), and their summaries are
compared wall-clock measurements apart, part by part: the agent's decisions, its rate
assignments, the identified models with their covariances, the watch's flags, the loops' traces
and step metrics, the network's configurations. It prints each part's verdict and the wall time
of both runs (a long run: about 1.5 min direct, several minutes on the bus)::

    python bench/wncsca_fouling_engines.py [--engine threads|processes] [--end-time 67]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

from runtime.launcher import launch

__all__ = ["main", "comparable"]

ROOT = Path(__file__).resolve().parents[1]
FOULING = ROOT / "scenarios" / "jcstr_fouling.yaml"
WALL = {"decision_time_s", "wall_s", "phases_s", "engine", "timing", "router"}
"""Summary entries that are wall-clock measurements or exist on one engine only."""


def comparable(x: Any) -> Any:
    """``x`` without its wall-clock entries (:data:`WALL`), recursively."""
    if isinstance(x, dict):
        return {k: comparable(v) for k, v in x.items() if k not in WALL}
    if isinstance(x, list):
        return [comparable(v) for v in x]
    return x


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", default="threads", choices=("threads", "processes"))
    ap.add_argument("--end-time", type=float, default=67.0, help="end of the run, pu (67)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        runs, walls = {}, {}
        for engine in ("direct", args.engine):
            t0 = time.perf_counter()
            res = launch(
                FOULING,
                Path(tmp) / engine,
                engine=engine,
                overrides=[f"end_time={args.end_time:g}"],
                plots="none",
            )
            walls[engine] = time.perf_counter() - t0
            if res.code != 0:
                print(f"{engine}: the run failed: {res.error}")
                return 1
            runs[engine] = comparable(res.summary)
    direct, bus = runs["direct"], runs[args.engine]
    agent_d, agent_b = direct.get("wncsca", {}), bus.get("wncsca", {})
    print(f"## {FOULING.name} to {args.end_time:g} pu: direct against {args.engine}\n")
    print("| part | equal | what |")
    print("|---|---|---|")
    for part in sorted(set(agent_d) | set(agent_b)):
        a, b = agent_d.get(part), agent_b.get(part)
        n = len(a) if isinstance(a, list | dict) else "-"
        print(f"| wncsca.{part} | {a == b} | {n} entries |")
    for part in ("loops", "network", "messages"):
        print(f"| {part} | {direct.get(part) == bus.get(part)} | |")
    equal = direct == bus
    print(f"\nwhole summaries equal: {equal}")
    print(f"wall time: direct {walls['direct']:.0f} s, {args.engine} {walls[args.engine]:.0f} s")
    return 0 if equal else 1


if __name__ == "__main__":
    raise SystemExit(main())
