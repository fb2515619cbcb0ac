"""What a secure run costs (issue 19): the same scenario with and without the router's access
control and authentication, and over mutual TLS (``--tls``), on both bus engines.

Runs the scenario ``--repeat`` times per engine in each mode, alternately (secure, insecure,
tls, secure, ...), and prints the median of the run phase (first tick to the clock's stop, from
``summary.json``'s ``phases_s``) and of the whole launch (start-up included: the secure run
writes its credentials and access control first, the TLS run its CA and a certificate per
node too), with the ratios secure / insecure and tls / secure. The histories are compared too:
every mode's must equal the others', bit for bit.

    .venv/bin/python bench/security.py [--scenario scenarios/jcstr_benchmark.yaml] [--repeat 5]
        [--modes secure,insecure,tls]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from runtime.history import messages_digest
from runtime.launcher import launch

MODES = ("secure", "insecure", "tls")


def _one(scenario: str, engine: str, mode: str, root: Path, i: int) -> tuple[float, float, str]:
    out = root / f"{engine}-{mode}-{i}"
    t0 = time.perf_counter()
    result = launch(scenario, out, engine=engine, insecure=mode == "insecure", tls=mode == "tls")
    wall = time.perf_counter() - t0
    if result.code != 0:
        raise SystemExit(f"{engine} ({mode}): {result.error}")
    return result.summary["phases_s"]["run"], wall, messages_digest(out / "history.sqlite")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="scenarios/jcstr_benchmark.yaml")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument(
        "--modes", default=",".join(MODES), help="comma-separated, of " + str(MODES)
    )
    args = parser.parse_args()
    modes = [m for m in args.modes.split(",") if m]
    if not modes or any(m not in MODES for m in modes):
        parser.error(f"--modes: each of {MODES}")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for engine in ("threads", "processes"):
            runs: dict[str, list[tuple[float, float, str]]] = {m: [] for m in modes}
            for i in range(args.repeat):
                for mode in modes:
                    runs[mode].append(_one(args.scenario, engine, mode, root, i))
            digests = {d for side in runs.values() for _, _, d in side}
            med = {
                m: (statistics.median(r for r, _, _ in v), statistics.median(w for _, w, _ in v))
                for m, v in runs.items()
            }
            parts = [f"{m} {med[m][0]:.3f} s / {med[m][1]:.2f} s" for m in modes]
            ratios = [
                f"{a}/{b} x{med[a][0] / med[b][0]:.2f} / x{med[a][1] / med[b][1]:.2f}"
                for a, b in (("secure", "insecure"), ("tls", "secure"))
                if a in med and b in med
            ]
            same = "identical" if len(digests) == 1 else "DIFFER"
            print(
                f"{engine:9s} run phase / whole launch: {'; '.join(parts)}; "
                f"{'; '.join(ratios)}; histories {same} (median of {args.repeat})"
            )


if __name__ == "__main__":
    main()
