"""A run's artefacts as CSV files (``wncs export RUN_DIR --csv``), for spreadsheets and notebooks.

The run is read by :func:`runtime.report.load_run` (``history.sqlite`` of a bus run, ``record.json``
of a direct run: the record ``wncs report`` draws from). Times are in the scenario's time units;
a missing value (``null`` in ``summary.json``) is an empty cell. Files:

* ``loop_<loop>.csv``: ``t``, ``t_sampled``, ``y``, ``setpoint``, ``u``: every sample delivered
  to the loop's controller (``t`` its delivery and the move's time, ``t_sampled`` when it was
  taken), the set point in force then and the move computed from it;
* ``plant_<plant>.csv``: ``t`` and each state on the plant's monitoring grid (the true output);
* ``network_paths.csv``: per loop's sensor path its hops, delivered delays (mean, p95, max),
  samples sent, lost, in flight at the end, moves lost (``summary.json``'s ``network.paths``);
* ``network_nodes.csv``, with a WSN: per node ``energy_mAh``, ``battery_pct``, ``lifetime_h``;
* with a coordination agent, ``wncsca_decisions.csv`` (``t``, ``subject``, ``proposal``,
  ``verdict``, ``reasons`` joined by ``; ``) and ``wncsca_assignments.csv`` (``t``, ``mode``,
  ``proposal``, ``method``, then per loop ``LOOP.period``, ``LOOP.control_period``,
  ``LOOP.closed``).

Parquet is not written: neither pyarrow nor pandas is a dependency of the project.
"""

from __future__ import annotations

import bisect
import csv
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from core.record import LoopRecord, RunRecord, summarize
from core.time import to_units
from runtime.report import load_run

__all__ = ["export_csv", "loop_rows"]


def _write(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows([["" if v is None else v for v in row] for row in rows])
    return path


def loop_rows(loop: LoopRecord) -> list[tuple[Any, ...]]:
    """``(t, t_sampled, y, setpoint, u)`` per delivered sample, times in time units; the set
    point is the one in force at ``t`` (the last step at or before it)."""
    steps = [t for t, _ in loop.setpoints]
    rows = []
    for i, t in enumerate(loop.t):
        k = bisect.bisect_right(steps, t) - 1
        sp = loop.setpoints[k][1] if k >= 0 else None
        sampled = to_units(loop.t_sampled[i]) if i < len(loop.t_sampled) else None
        rows.append((to_units(t), sampled, loop.y[i], sp, loop.u[i]))
    return rows


def _records(rec: RunRecord, summary: dict[str, Any], out: Path) -> list[Path]:
    written = []
    for name, loop in sorted(rec.loops.items()):
        written.append(
            _write(
                out / f"loop_{name}.csv", ("t", "t_sampled", "y", "setpoint", "u"), loop_rows(loop)
            )
        )
    for name, plant in sorted(rec.plants.items()):
        rows = ([to_units(t), *x] for t, x in zip(plant.t, plant.x, strict=True))
        written.append(_write(out / f"plant_{name}.csv", ("t", *plant.state_names), rows))
    paths = summary["network"]["paths"]
    if paths:
        fields = list(next(iter(paths.values())))
        rows = ([loop, *(p.get(f) for f in fields)] for loop, p in paths.items())
        written.append(_write(out / "network_paths.csv", ("loop", *fields), rows))
    nodes = summary["network"]["nodes"]
    if nodes:
        fields = ["energy_mAh", "battery_pct", "lifetime_h"]
        rows = ([n, *((e or {}).get(f) for f in fields)] for n, e in nodes.items())
        written.append(_write(out / "network_nodes.csv", ("node", *fields), rows))
    return written


def _agent(summary: dict[str, Any], out: Path) -> list[Path]:
    w = summary.get("wncsca")
    if not w:
        return []
    decisions = (
        (d["t"], d["subject"], d.get("proposal"), d["verdict"], "; ".join(d.get("reasons", [])))
        for d in w["decisions"]
    )
    written = [
        _write(
            out / "wncsca_decisions.csv",
            ("t", "subject", "proposal", "verdict", "reasons"),
            decisions,
        )
    ]
    loops = sorted(summary["loops"])
    header = ["t", "mode", "proposal", "method"]
    for loop in loops:
        header += [f"{loop}.period", f"{loop}.control_period", f"{loop}.closed"]
    rows = []
    for a in w["assignments"]:
        row = [a["t"], a["mode"], a.get("proposal"), a.get("method")]
        for loop in loops:
            row += [
                a["periods"].get(loop),
                a["control_periods"].get(loop),
                a["closed"].get(loop),
            ]
        rows.append(row)
    written.append(_write(out / "wncsca_assignments.csv", header, rows))
    return written


def export_csv(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """Write every artefact of the run in ``run_dir`` as CSV into ``out`` (default
    ``run_dir/csv``); returns the files written.

    Raises
    ------
    ConfigError
        If ``run_dir`` is not a run directory (no ``run.json``) or its scenario does not load.
    """
    run_dir = Path(run_dir)
    _, rec = load_run(run_dir)
    target = Path(out) if out is not None else run_dir / "csv"
    target.mkdir(parents=True, exist_ok=True)
    summary = summarize(rec)
    return _records(rec, summary, target) + _agent(summary, target)
