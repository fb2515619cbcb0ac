"""Digests of every shipped scenario's run record, here and (``--against REV``) in another tree.

A refit must not move a single sample: this runs each scenario of ``scenarios/`` on the direct
engine (the same behaviours the bus engines run; ``tests/integration/test_engines_agree.py``
holds the engines together) and prints the blake2b digest of its record as ``record.json``
keeps it (:func:`runtime.report.save_record`), wall-clock figures left out (the agent's decision
times). With ``--against REV`` the same is computed in a worktree of ``REV`` and every scenario
is compared; the exit code is 1 when any differs. A scenario with an agent whose method is not
``fast`` runs once more with ``method: fast`` (``name.yaml[fast]``), so the fast method's
predictor is held bit-equal too (the shipped scenarios use ``chance`` and ``paper``).

    .venv/bin/python bench/traces_digest.py --against HEAD~3
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from against import ROOT, Comparison, measure_in

SNIPPET = """
import hashlib, json, sys, tempfile
from pathlib import Path
from runtime.direct import simulate
from runtime.report import save_record
# load_scenario is the tree's own, from the prelude of every measurement (bench/against.py)

WALL = {"decision_time_s", "wall_s", "phases_s", "timing"}

def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if k not in WALL}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x

out = {}
with tempfile.TemporaryDirectory() as tmp:
    for path in sorted(Path(ROOT, "scenarios").glob("*.yaml")):
        scenario = load_scenario(path)
        runs = {path.name: scenario}
        for name, node in scenario.nodes.items():  # the other methods' searches too
            if getattr(node, "method", "fast") != "fast":
                nodes = {**scenario.nodes, name: node.model_copy(update={"method": "fast"})}
                runs[path.name + "[fast]"] = scenario.model_copy(update={"nodes": nodes})
        for label, run in runs.items():
            try:
                save_record(simulate(run), Path(tmp))
            except ValueError as err:  # a method refused by the scenario's loops
                out[label] = "refused: " + str(err).splitlines()[0][:40]
                continue
            data = strip(json.loads((Path(tmp) / "record.json").read_text()))
            text = json.dumps(data, sort_keys=True).encode()
            out[label] = hashlib.blake2b(text, digest_size=16).hexdigest()
print(json.dumps(out))
"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", metavar="REV", help="compare with revision REV")
    args = parser.parse_args(argv)
    ours: dict[str, str] = measure_in(ROOT, SNIPPET)
    if args.against is None:
        for name, digest in ours.items():
            print(f"{name:32s} {digest}")
        return 0
    with Comparison(args.against) as cmp:
        theirs: dict[str, str] = measure_in(Path(cmp.tree), SNIPPET)
    differ = 0
    for name in sorted(set(ours) | set(theirs)):
        a, b = ours.get(name, "-"), theirs.get(name, "-")
        same = "same" if a == b else "DIFFERS"
        differ += a != b
        print(f"{name:32s} {a} {b} {same}")
    print(f"{len(ours)} scenarios here, {len(theirs)} at {args.against}: {differ} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
