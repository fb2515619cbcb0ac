"""What a run's artefacts cost at scale (issue 41, item 3): the whole ``wncs run`` command
against its run phase, by engine and ``--plots`` choice.

``wncs scale N --end-time T`` writes N tank loops over WSN areas; each engine runs it as a user
would (a ``wncs run`` process, timed from outside) with ``--plots summary`` (the default beyond
10 loops) and ``--plots all``. Printed: the command's wall time, the run phase its summary
states, and their ratio (the target: at most 2 at 100 loops).

    python bench/artefacts.py [--loops 100] [--end-time 10] [--engines direct,threads]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["main"]

WNCS = [sys.executable, "-m", "cli"]


def _timed_run(scenario: Path, out: Path, engine: str, plots: str) -> tuple[float, float]:
    t0 = time.perf_counter()
    subprocess.run(
        [*WNCS, "run", str(scenario), "--out", str(out), "--engine", engine, "--quiet"]
        + ["--plots", plots],
        check=True,
    )
    wall = time.perf_counter() - t0
    summary = json.loads((out / "summary.json").read_text())
    return wall, float(summary["phases_s"]["run"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--loops", type=int, default=100)
    ap.add_argument("--end-time", type=float, default=10.0)
    ap.add_argument("--engines", default="direct,threads")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / "scale.yaml"
        subprocess.run(
            [*WNCS, "scale", str(args.loops), "--end-time", str(args.end_time)]
            + ["--out", str(scenario)],
            check=True,
            capture_output=True,
        )
        print(f"{args.loops} tank loops, {args.end_time:g} s simulated")
        print(f"{'engine':>8} {'--plots':>8} {'command s':>10} {'run s':>7} {'ratio':>6}")
        for engine in args.engines.split(","):
            for plots in ("summary", "all"):
                out = Path(tmp) / f"{engine}-{plots}"
                wall, run = _timed_run(scenario, out, engine, plots)
                print(f"{engine:>8} {plots:>8} {wall:10.1f} {run:7.1f} {wall / run:6.2f}")


if __name__ == "__main__":
    main()
