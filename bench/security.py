"""What a secure run costs (issue 19): the same scenario with and without the router's access
control and authentication, on both bus engines.

Runs the scenario ``--repeat`` times per engine in each mode, alternately (secure, insecure,
secure, ...), and prints the median of the run phase (first tick to the clock's stop, from
``summary.json``'s ``phases_s``) and of the whole launch (start-up included: the secure run
writes its credentials and access control first), with the ratio secure / insecure. The
histories are compared too: a secure run's must equal the insecure run's, bit for bit.

    .venv/bin/python bench/security.py [--scenario scenarios/jcstr_benchmark.yaml] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from runtime.history import messages_digest
from runtime.launcher import launch


def _one(scenario: str, engine: str, secure: bool, root: Path, i: int) -> tuple[float, float, str]:
    out = root / f"{engine}-{'secure' if secure else 'insecure'}-{i}"
    t0 = time.perf_counter()
    result = launch(scenario, out, engine=engine, insecure=not secure)
    wall = time.perf_counter() - t0
    if result.code != 0:
        raise SystemExit(f"{engine} ({'secure' if secure else 'insecure'}): {result.error}")
    return result.summary["phases_s"]["run"], wall, messages_digest(out / "history.sqlite")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="scenarios/jcstr_benchmark.yaml")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for engine in ("threads", "processes"):
            runs: dict[bool, list[tuple[float, float, str]]] = {True: [], False: []}
            for i in range(args.repeat):
                for secure in (True, False):
                    runs[secure].append(_one(args.scenario, engine, secure, root, i))
            digests = {d for side in runs.values() for _, _, d in side}
            med = {
                s: (statistics.median(r for r, _, _ in v), statistics.median(w for _, w, _ in v))
                for s, v in runs.items()
            }
            (run_s, wall_s), (run_i, wall_i) = med[True], med[False]
            same = "identical" if len(digests) == 1 else "DIFFER"
            print(
                f"{engine:9s} run phase: secure {run_s:.3f} s, insecure {run_i:.3f} s "
                f"(x{run_s / run_i:.2f}); whole launch: secure {wall_s:.2f} s, insecure "
                f"{wall_i:.2f} s (x{wall_s / wall_i:.2f}); histories {same} "
                f"(median of {args.repeat})"
            )


if __name__ == "__main__":
    main()
