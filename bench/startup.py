"""Start-up cost of a node process (issue 20, item 3): import time per node kind.

Every node process runs ``wncs node SCENARIO NAME ...``, which imports ``runtime.cli`` and with
it every node kind (the scenario's unions are built from the registries). Printed, each measured
in ``--repeat`` fresh interpreters (median wall time of the import alone): the interpreter with
numpy, scipy, pydantic and zenoh; each node kind's behaviour module, as a lean entry point would
load it; and ``runtime.cli``, what a node loads today. Then the ten slowest modules of
``import runtime.cli`` by cumulative time (``python -X importtime``).

    .venv/bin/python bench/startup.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys

MODULES = {
    "python + numpy, scipy, pydantic, zenoh": "numpy, scipy, pydantic, zenoh",
    "plant (plants.behaviour)": "plants.behaviour",
    "controller (controllers.behaviour)": "controllers.behaviour",
    "network / gateway (gateway.behaviour)": "gateway.behaviour",
    "operator (agents.operator.behaviour)": "agents.operator.behaviour",
    "agent (agents.wncsca.behaviour)": "agents.wncsca.behaviour",
    "monitor (agents.monitor.behaviour)": "agents.monitor.behaviour",
    "scenario schema (runtime.scenario)": "runtime.scenario",
    "wncs node today (runtime.cli)": "runtime.cli",
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(f"import time, median of {args.repeat} fresh interpreters")
    print("| what | s |")
    print("|---|---:|")
    for label, module in MODULES.items():
        print(f"| {label} | {import_seconds(module, args.repeat):.2f} |")
    print("\nslowest modules under `import runtime.cli` (cumulative s):")
    for seconds, name in slowest("runtime.cli"):
        print(f"  {seconds:6.3f}  {name}")


if __name__ == "__main__":
    main()
