"""Bench: the plant-wide audit (issue 16, item 4) on 100 synthetic loop files.

Writes 100 historian-style exports (``time;SP;PV;OP``, 751 rows at 10 s, as the refinery loops
of the issue): AR(1) loops of known Harris index ``(1 + phi^2 + phi^4)(1 - phi^2)`` (d = 3),
stiction-like limit cycles of period 15 samples, drifting loops, frozen transmitters, spikes and
four broken files (and the same at 5000 rows); runs the audit of ``wncs assess DIR --config
loops.yaml --jobs J`` with one and with two worker processes and prints the wall time of each,
the worker PIDs seen, the time the outputs take, the status counts, and how far the AR loops'
indices fall from their closed forms.

    .venv/bin/python bench/monitor_audit.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.signal import lfilter  # noqa: TID253 - not a node: imports what it uses at the top

from agents.monitor.audit import collect_loops, load_audit_config, rank, run_audit
from agents.monitor.audit_report import write_audit

N = 751


def write_plant(d: Path, n: int = N) -> dict[str, float]:
    """The 100 files and ``loops.yaml``; the AR loops' closed-form indices by loop name."""
    d.mkdir(parents=True, exist_ok=True)
    t = np.arange(n)
    closed = {}
    for i in range(100):
        rng = np.random.default_rng(i)
        kind = ("ar", "ar", "cycle", "drift", "ar", "frozen", "ar", "spike", "ar", "ar")[i % 10]
        phi = 0.3 + 0.65 * rng.random()
        pv = 50 + lfilter([1.0], [1.0, -phi], rng.standard_normal(n))
        if kind == "cycle":
            pv = (
                50
                + 2 / np.pi * np.arcsin(np.sin(2 * np.pi * t / 15))
                + 0.2 * rng.standard_normal(n)
            )
        elif kind == "drift":
            pv += 0.01 * t
        elif kind == "frozen":
            pv[200:] = pv[200]
        elif kind == "spike":
            pv[300] = 5000.0
        if kind in ("ar", "spike"):
            closed[f"L{i:03d}"] = (1 + phi**2 + phi**4) * (1 - phi**2)
        op = np.clip(40 + 5 * rng.standard_normal(n), 0, 100)
        lines = ["time;SP;PV;OP"] + [f"{10 * k};50;{pv[k]:.6f};{op[k]:.4f}" for k in range(n)]
        if i in (11, 33, 55, 99):
            lines = lines[: 20 * (i // 11)]  # broken: too short (or header only)
            closed.pop(f"L{i:03d}", None)
        (d / f"L{i:03d}.csv").write_text("\n".join(lines) + "\n")
    (d / "loops.yaml").write_text("defaults: {pv: PV, sp: SP, op: OP, delay: 3}\n")
    return closed


def run(d: Path, closed: dict[str, float]) -> None:
    cfg, specs = load_audit_config(d / "loops.yaml")
    loops, _ = collect_loops(str(d), cfg, specs)
    for jobs in (1, 2):
        t0 = time.perf_counter()
        outcomes = run_audit(loops, cfg.analysis, jobs=jobs)
        wall = time.perf_counter() - t0
        pids = {o["pid"] for o in outcomes if "pid" in o}
        print(f"  --jobs {jobs}: {wall:.1f} s wall for the assessments, {len(pids)} worker PIDs")
    t0 = time.perf_counter()
    paths = write_audit(rank(outcomes), d / "audit")
    print(f"  outputs (21 figures): {time.perf_counter() - t0:.1f} s")
    counts = Counter(o["status"] for o in outcomes)
    flags = Counter(f for o in outcomes for f in o.get("flags", []))
    print(f"  status {dict(counts)}; flags {dict(flags)}")
    err = [
        abs(o["harris"] - closed[o["loop"]])
        for o in outcomes
        if o["loop"] in closed and o.get("harris") is not None
    ]
    print(
        f"  AR loops: |index - closed form| median {np.median(err):.3f}, max {max(err):.3f} "
        f"over {len(err)} loops; written {paths['csv']}, {paths['html']}"
    )


if __name__ == "__main__":
    base = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="audit_"))
    for n in (N, 5000):
        print(f"== 100 loop files of {n} rows")
        run(base / f"n{n}", write_plant(base / f"n{n}", n))
