"""A run's artefacts as tables (``wncs export RUN_DIR --csv|--parquet``), for spreadsheets and
notebooks.

The run is read by :func:`runtime.report.load_run` (``history.sqlite`` of a bus run, ``record.json``
of a direct run: the record ``wncs report`` draws from). Times are in the scenario's time units;
a missing value (``null`` in ``summary.json``) is an empty cell in CSV, a null in Parquet. Tables,
one file each (``<name>.csv`` or ``<name>.parquet``):

* ``loop_<loop>``: ``t``, ``t_sampled``, ``y``, ``setpoint``, ``u``: every sample delivered
  to the loop's controller (``t`` its delivery and the move's time, ``t_sampled`` when it was
  taken), the set point in force then and the move computed from it;
* ``plant_<plant>``: ``t`` and each state on the plant's monitoring grid (the true output);
* ``network_paths``: per loop's sensor path its hops, delivered delays (mean, p95, max),
  samples sent, lost, in flight at the end, moves lost (``summary.json``'s ``network.paths``);
* ``network_nodes``, with a WSN: per node ``energy_mAh``, ``battery_pct``, ``lifetime_h``;
* with a coordination agent, ``wncsca_decisions`` (``t``, ``subject``, ``proposal``,
  ``verdict``, ``reasons`` joined by ``; ``) and ``wncsca_assignments`` (``t``, ``mode``,
  ``proposal``, ``method``, then per loop ``LOOP.period``, ``LOOP.control_period``,
  ``LOOP.closed``).

The same tables are the notebook API's DataFrames (:meth:`wncs.Result.tables`).
"""

from __future__ import annotations

import bisect
import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from core.record import LoopRecord, PlantRecord, RunRecord, summarize
from core.time import to_units
from runtime.report import load_run

__all__ = ["FORMATS", "Table", "loop_table", "plant_table", "tables", "export_run"]

FORMATS = ("csv", "parquet")

Table = tuple[tuple[str, ...], list[tuple[Any, ...]]]
"""A table: its header and its rows."""


def loop_table(loop: LoopRecord) -> Table:
    """``(t, t_sampled, y, setpoint, u)`` per delivered sample, times in time units; the set
    point is the one in force at ``t`` (the last step at or before it)."""
    steps = [t for t, _ in loop.setpoints]
    rows = []
    for i, t in enumerate(loop.t):
        k = bisect.bisect_right(steps, t) - 1
        sp = loop.setpoints[k][1] if k >= 0 else None
        sampled = to_units(loop.t_sampled[i]) if i < len(loop.t_sampled) else None
        rows.append((to_units(t), sampled, loop.y[i], sp, loop.u[i]))
    return ("t", "t_sampled", "y", "setpoint", "u"), rows


def plant_table(plant: PlantRecord) -> Table:
    """``t`` and each state on the plant's monitoring grid."""
    rows = [(to_units(t), *x) for t, x in zip(plant.t, plant.x, strict=True)]
    return ("t", *plant.state_names), rows


def _agent(summary: dict[str, Any]) -> dict[str, Table]:
    w = summary.get("wncsca")
    if not w:
        return {}
    decisions = [
        (d["t"], d["subject"], d.get("proposal"), d["verdict"], "; ".join(d.get("reasons", [])))
        for d in w["decisions"]
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
        rows.append(tuple(row))
    return {
        "wncsca_decisions": (("t", "subject", "proposal", "verdict", "reasons"), decisions),
        "wncsca_assignments": (tuple(header), rows),
    }


def tables(rec: RunRecord, summary: dict[str, Any]) -> dict[str, Table]:
    """Every table of the run (module docstring), by name."""
    out: dict[str, Table] = {}
    for name, loop in sorted(rec.loops.items()):
        out[f"loop_{name}"] = loop_table(loop)
    for name, plant in sorted(rec.plants.items()):
        out[f"plant_{name}"] = plant_table(plant)
    paths = summary["network"]["paths"]
    if paths:
        fields = [f for f in next(iter(paths.values())) if f != "lost_by_reason"]
        rows = [(loop, *(p.get(f) for f in fields)) for loop, p in paths.items()]
        out["network_paths"] = (("loop", *fields), rows)
    nodes = summary["network"]["nodes"]
    if nodes:
        fields = ["energy_mAh", "battery_pct", "lifetime_h"]
        rows = [(n, *((e or {}).get(f) for f in fields)) for n, e in nodes.items()]
        out["network_nodes"] = (("node", *fields), rows)
    out.update(_agent(summary))
    return out


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows([["" if v is None else v for v in row] for row in rows])
    return path


def _write_parquet(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    import pandas as pd  # noqa: PLC0415 - heavy, only for Parquet: kept out of node processes

    pd.DataFrame(list(rows), columns=list(header)).to_parquet(path, index=False)
    return path


def export_run(
    run_dir: str | Path, out: str | Path | None = None, *, fmt: str = "csv"
) -> list[Path]:
    """Write every table of the run in ``run_dir`` as ``fmt`` files (``csv`` or ``parquet``)
    into ``out`` (default ``run_dir/<fmt>``); returns the files written.

    Raises
    ------
    ConfigError
        If ``run_dir`` is not a run directory (no ``run.json``) or its scenario does not load.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {fmt!r}")
    run_dir = Path(run_dir)
    _, rec = load_run(run_dir)
    target = Path(out) if out is not None else run_dir / fmt
    target.mkdir(parents=True, exist_ok=True)
    write = _write_csv if fmt == "csv" else _write_parquet
    return [
        write(target / f"{name}.{fmt}", header, rows)
        for name, (header, rows) in tables(rec, summarize(rec)).items()
    ]
