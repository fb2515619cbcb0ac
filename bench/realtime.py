"""Real-time pacing: a 3 pu run with ``--realtime 1.0`` should take 3 s of wall time (+-10 %).

Measures the run phase (first round to the last) of the benchmark cut to 3 pu, paced at
1 s per pu, by the processes engine, and prints it with the deviation from 3 s.

    .venv/bin/python bench/realtime.py [--seconds-per-unit S] [--engine processes|threads]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import yaml

from runtime.launcher import launch

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"
END = 3.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds-per-unit", type=float, default=1.0)
    parser.add_argument("--engine", default="processes", choices=("processes", "threads"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = yaml.safe_load(SCENARIO.read_text())
        data["end_time"] = END
        data["name"] = "jcstr_benchmark_3pu"
        path = Path(tmp) / "scenario.yaml"
        path.write_text(yaml.safe_dump(data))
        res = launch(path, Path(tmp) / "out", engine=args.engine, realtime=args.seconds_per_unit)
        if res.code != 0:
            raise SystemExit(res.error)
        run = res.summary["phases_s"]["run"]
    target = END * args.seconds_per_unit
    dev = (run - target) / target * 100
    verdict = "within" if abs(dev) <= 10 else "OUTSIDE"
    print(
        f"{END:g} pu at {args.seconds_per_unit:g} s/pu ({args.engine}): run phase {run:.3f} s "
        f"wall, target {target:.3f} s, deviation {dev:+.1f} % ({verdict} +-10 %)"
    )


if __name__ == "__main__":
    main()
