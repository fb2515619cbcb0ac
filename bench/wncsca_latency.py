"""Decision latency of the coordination agent on the bus (issue: "from a proposal on the bus to the
rates on the bus"), per method.

Runs ``scenarios/jcstr_wncs.yaml`` (threads engine by default) once per method and prints, for
every proposal, the agent's wall-clock time from handling ``net/proposal`` to publishing its
decision and ``wncsca/rates`` (the agent's ``wncsca/timing`` messages; bus transport adds about a
clock round, ~2 ms here, on top)::

    python bench/wncsca_latency.py [--engine threads|processes] [--methods paper,fast]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import yaml

from runtime.launcher import launch

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_wncs.yaml"


def latencies(method: str, engine: str) -> list[tuple[float, int, str, float]]:
    """``(t, proposal, verdict, decision_s)`` of every proposal of one demo run."""
    with tempfile.TemporaryDirectory() as tmp:
        data = yaml.safe_load(SCENARIO.read_text())
        data["nodes"]["wncsca"]["method"] = method
        path = Path(tmp) / "scenario.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        result = launch(path, Path(tmp) / "out", engine=engine)
        if result.code != 0:
            raise SystemExit(f"{method}: run failed: {result.error}")
        summary = json.loads((Path(tmp) / "out" / "summary.json").read_text())
    return [
        (d["t"], d["proposal"], d["verdict"], d["decision_time_s"])
        for d in summary["wncsca"]["decisions"]
        if d["subject"] == "proposal" and d.get("decision_time_s") is not None
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", default="threads", choices=("threads", "processes"))
    parser.add_argument("--methods", default="paper,fast")
    args = parser.parse_args(argv)
    print("| method | t pu | proposal | verdict | decision s |")
    print("|---|---:|---:|---|---:|")
    totals = {}
    for method in args.methods.split(","):
        rows = latencies(method, args.engine)
        for t, pid, verdict, s in rows:
            print(f"| {method} | {t:g} | {pid} | {verdict} | {s:.3f} |")
        totals[method] = sum(s for *_, s in rows)
    if len(totals) == 2:
        (a, ta), (b, tb) = totals.items()
        print(f"\ntotal decision time {a} {ta:.3f} s, {b} {tb:.3f} s, ratio {ta / tb:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
