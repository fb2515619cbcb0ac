"""Start-up cost of a node process (issue 20, item 3): import time per node kind.

Every node process runs ``wncs node SCENARIO NAME ...``, which imports ``cli.main`` and with
it every node kind (the scenario's unions are built from the registries). Printed, each measured
in ``--repeat`` fresh interpreters (median wall time of the import alone): the interpreter with
numpy, scipy, pydantic and zenoh; each node kind's behaviour module, as a lean entry point would
load it; and ``cli.main``, what a node loads today. Then the ten slowest modules of
``import cli.main`` by cumulative time (``python -X importtime``).

Then the start-up of the processes engine on the JCSTR benchmark (``wncs run`` until the first
round: router, node processes, imports, sessions, every node alive), here and at ``--against
REV`` (default ``0b9e00f``, the last commit before the fork server of ``runtime/forkserver.py``,
where each node was a fresh ``wncs node`` interpreter), alternately in fresh processes
(``bench/against.py``; each side's node processes import that side's tree).

    .venv/bin/python bench/startup.py [--repeat 5] [--against REV] [--launches 5]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys

from against import Comparison

MODULES = {
    "python + numpy, scipy, pydantic, zenoh": "numpy, scipy, pydantic, zenoh",
    "plant (plants.behaviour)": "plants.behaviour",
    "controller (controllers.behaviour)": "controllers.behaviour",
    "network / gateway (gateway.behaviour)": "gateway.behaviour",
    "operator (agents.operator.behaviour)": "agents.operator.behaviour",
    "agent (agents.wncsca.behaviour)": "agents.wncsca.behaviour",
    "monitor (agents.monitor.behaviour)": "agents.monitor.behaviour",
    "scenario schema (scenario)": "scenario",
    "what the fork server imports (runtime.nodes)": "runtime.nodes",
    "wncs node (cli.main)": "cli.main",
}


def import_seconds(module: str, repeat: int) -> float:
    code = (
        f"import time; t0 = time.perf_counter(); import {module}; print(time.perf_counter() - t0)"
    )
    times = []
    for _ in range(repeat):
        out = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        )
        times.append(float(out.stdout.strip().splitlines()[-1]))
    return statistics.median(times)


def slowest(module: str, n: int = 10) -> list[tuple[float, str]]:
    out = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", f"import {module}"],
        capture_output=True,
        text=True,
        check=True,
    )
    rows = []
    for line in out.stderr.splitlines():
        parts = line.split("|")
        if len(parts) == 3 and parts[1].strip().isdigit():
            rows.append((int(parts[1]) / 1e6, parts[2].rstrip()))
    return sorted(rows, reverse=True)[:n]


# start-up phase of one processes-engine run of the benchmark, in the tree at ROOT
PROCESSES_STARTUP = """
import json, os, tempfile
os.environ["PYTHONPATH"] = ROOT  # the node processes import this tree too
from runtime.launcher import launch
with tempfile.TemporaryDirectory() as tmp:
    res = launch(ROOT + "/scenarios/jcstr_benchmark.yaml", tmp + "/run", engine="processes")
    assert res.code == 0, res.error
    print(json.dumps(res.summary["phases_s"]["startup"]))
"""


def processes_startup(rev: str, launches: int) -> None:
    """Start-up of the processes engine on the benchmark, here and at ``rev``."""
    with Comparison(rev) as cmp:
        ours, theirs = cmp.run(PROCESSES_STARTUP, rounds=launches)
    print(f"\nprocesses engine start-up on jcstr_benchmark (s), {launches} alternating launches:")
    cmp.print_table(ours, theirs, digits=2)
    print(f"this tree / {rev}: {statistics.median(ours) / statistics.median(theirs):.2f} (medians)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--against", default="0b9e00f", help="revision to compare start-up with")
    parser.add_argument("--launches", type=int, default=5, help="launches per side")
    args = parser.parse_args()
    print(f"import time, median of {args.repeat} fresh interpreters")
    print("| what | s |")
    print("|---|---:|")
    for label, module in MODULES.items():
        print(f"| {label} | {import_seconds(module, args.repeat):.2f} |")
    print("\nslowest modules under `import cli.main` (cumulative s):")
    for seconds, name in slowest("cli.main"):
        print(f"  {seconds:6.3f}  {name}")
    processes_startup(args.against, args.launches)


if __name__ == "__main__":
    main()
