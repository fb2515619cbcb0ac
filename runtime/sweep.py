"""Parameter sweeps (``wncs sweep``): a scenario run on the direct engine at every point of a grid
of overrides, in parallel processes, into one table and one plot.

A grid axis is ``--grid dotted.path=VALUES``: ``a:b:n`` is ``n`` evenly spaced values from ``a`` to
``b`` inclusive (integers stay integers when every value is one; floats are rounded to 12
significant digits, so ``0.1:0.4:7`` gives ``0.15``, not ``0.15000000000000002``), ``x,y,z`` a list
of values, each parsed as YAML like a ``--set`` value. The grid is the Cartesian product of the
axes, in the order given (the last axis varies fastest). Each point is the scenario with the
``--set`` overrides and then the point's values applied through :mod:`scenario.overrides`, exactly
as ``wncs run --set`` applies them, and validated like the file: a bad point is refused before
anything runs, naming the ``--grid`` argument and the value.

``DIR/sweep.csv`` has one row per point: the grid values, then per loop ``LOOP.overshoot_pct``,
``LOOP.settling_time`` and ``LOOP.iae`` from the run's summary (empty where the figure is
``null``) and, with a coordination agent, ``LOOP.control_period`` from its last assignment.
``DIR/sweep.parquet`` is the same table in Parquet (types kept: integers, floats, nulls).
``DIR/sweep.png`` draws each loop's overshoot against the first axis, one line per value of the
other axes.
"""

from __future__ import annotations

import csv
import itertools
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from core.errors import ConfigError
from core.record import summarize
from runtime.direct import simulate
from scenario import load_scenario
from scenario.overrides import Override, parse_override
from scenario.yaml_positions import read_yaml

__all__ = [
    "Axis",
    "FIGURES",
    "SWEEP_CSV",
    "SWEEP_PNG",
    "SWEEP_PARQUET",
    "parse_axis",
    "parse_range",
    "grid_points",
    "check_grid",
    "run_point",
    "sweep",
]

SWEEP_CSV = "sweep.csv"
SWEEP_PNG = "sweep.png"
SWEEP_PARQUET = "sweep.parquet"
FIGURES = ("overshoot_pct", "settling_time", "iae")
"""The summary's figures per loop, in the table's order."""


@dataclass(frozen=True)
class Axis:
    """One ``--grid PATH=VALUES``: the argument as given, the dotted path and its values."""

    text: str
    path: str
    values: tuple[Any, ...]

    def override(self, value: Any) -> Override:
        """The ``--set`` override that puts ``value`` at this axis's path."""
        return Override(f"{self.path}={value}", tuple(self.path.split(".")), value)


def _number(text: str, where: str) -> int | float:
    value = read_yaml(text, source=where)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{where}: {text.strip()!r} is not a number")
    return value


def parse_range(text: str, *, where: str = "--grid") -> tuple[int | float, ...]:
    """``"a:b:n"`` -> ``n`` evenly spaced values from ``a`` to ``b`` inclusive.

    Integers stay integers when ``a``, ``b`` and every step are integral; floats are rounded to
    12 significant digits. ``n = 1`` gives ``(a,)``.

    Raises
    ------
    ConfigError
        Naming ``where``, if there are not three parts, ``a`` or ``b`` is not a number or ``n``
        is not an integer >= 1.
    """
    parts = text.split(":")
    if len(parts) != 3:
        raise ConfigError(f"{where}: {text!r} is not a:b:n (from a to b, n values)")
    a, b = _number(parts[0], where), _number(parts[1], where)
    n_text = parts[2].strip()
    if not n_text.isdigit() or int(n_text) < 1:
        raise ConfigError(f"{where}: n must be an integer >= 1, got {n_text!r}")
    n = int(n_text)
    if n == 1:
        return (a,)
    steps = [a + (b - a) * i / (n - 1) for i in range(n)]
    if isinstance(a, int) and isinstance(b, int) and all(float(v).is_integer() for v in steps):
        return tuple(int(v) for v in steps)
    return tuple(float(f"{v:.12g}") for v in steps)


def parse_axis(text: str) -> Axis:
    """Parse one ``--grid PATH=a:b:n`` or ``--grid PATH=x,y,z``.

    Raises
    ------
    ConfigError
        Naming the argument, if it is not ``PATH=VALUES``, the path is not dotted, a value is
        not YAML or the range is malformed.
    """
    where = f"--grid {text}"
    name, sep, raw = text.partition("=")
    path = name.strip()
    if not sep or not raw.strip():
        raise ConfigError(f"{where}: expected PATH=a:b:n or PATH=x,y,z")
    # the path is checked as --set checks it (a dotted path with no empty segment)
    parse_override(f"{path}=0")
    if ":" in raw and "," not in raw:
        values: tuple[Any, ...] = parse_range(raw, where=where)
    else:
        values = tuple(read_yaml(v, source=f"{where}: {v.strip()!r}") for v in raw.split(","))
    return Axis(text, path, values)


def grid_points(axes: Sequence[Axis]) -> list[tuple[Any, ...]]:
    """The Cartesian product of the axes' values, the last axis varying fastest."""
    return list(itertools.product(*(a.values for a in axes)))


def _overrides(
    base: Sequence[Override], axes: Sequence[Axis], point: Sequence[Any]
) -> list[Override]:
    return [*base, *(axis.override(v) for axis, v in zip(axes, point, strict=True))]


def _reason(err: ConfigError, override: Override) -> str:
    return str(err).removeprefix(f"--set {override.text}: ")


def check_grid(scenario: str | Path, axes: Sequence[Axis], base: Sequence[Override]) -> None:
    """Load every point of the grid as ``wncs run --set`` would, before anything runs.

    Raises
    ------
    ConfigError
        Naming the ``--grid`` argument and the value whose point does not load (or, when only a
        combination of values fails, the point).
    """
    load_scenario(scenario, overrides=base)  # a bad --set is refused as `wncs run` refuses it
    for point in grid_points(axes):
        try:
            load_scenario(scenario, overrides=_overrides(base, axes, point))
        except ConfigError as err:
            for axis, value in zip(axes, point, strict=True):
                one = axis.override(value)
                try:
                    load_scenario(scenario, overrides=[*base, one])
                except ConfigError as alone:
                    reason = _reason(alone, one)
                    raise ConfigError(f"--grid {axis.text}: value {value!r}: {reason}") from alone
            values = ", ".join(f"{a.path}={v!r}" for a, v in zip(axes, point, strict=True))
            raise ConfigError(f"--grid: the point {values}: {err}") from err


def run_point(scenario: str | Path, overrides: Sequence[Override]) -> dict[str, Any]:
    """Run one point on the direct engine; its summary (``summary.json``'s contents)."""
    return summarize(simulate(load_scenario(scenario, overrides=overrides)))


def _row(axes: Sequence[Axis], point: Sequence[Any], summary: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {a.path: v for a, v in zip(axes, point, strict=True)}
    wncsca = summary.get("wncsca")
    assignments = (wncsca or {}).get("assignments") or []
    last = assignments[-1]["control_periods"] if assignments else {}
    for loop, figures in summary["loops"].items():
        for name in FIGURES:
            row[f"{loop}.{name}"] = figures.get(name)
        if wncsca is not None:
            row[f"{loop}.control_period"] = last.get(loop)
    return row


def sweep(
    scenario: str | Path,
    axes: Sequence[Axis],
    out: str | Path,
    *,
    overrides: Sequence[str | Override] = (),
    jobs: int | None = None,
    progress: TextIO | None = None,
) -> list[dict[str, Any]]:
    """Run ``scenario`` at every point of the grid of ``axes``; write ``sweep.csv`` (and the same
    table as ``sweep.parquet``) and ``sweep.png`` to ``out`` and return the rows (a dict per
    point, in grid order).

    Parameters
    ----------
    scenario : str or Path
        The scenario file.
    axes : sequence of Axis
        The grid's axes (:func:`parse_axis`).
    out : str or Path
        Output directory (created).
    overrides : sequence of str or Override
        ``--set`` overrides applied to every point, before the point's values.
    jobs : int, optional
        Worker processes (default ``os.cpu_count()``); 1 runs the points in this process.
    progress : file, optional
        Where ``sweep: k/N`` is written as points finish (default nowhere; the CLI: stderr).

    Raises
    ------
    ConfigError
        If an override or a point does not load (:func:`check_grid`): nothing has run.
    """
    if not axes:
        raise ConfigError("--grid: at least one axis is needed")
    paths = [a.path for a in axes]
    if len(set(paths)) != len(paths):
        raise ConfigError(f"--grid: a path is given twice ({', '.join(paths)})")
    jobs = jobs or os.cpu_count() or 1
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {jobs}")
    base = [o if isinstance(o, Override) else parse_override(o) for o in overrides]
    check_grid(scenario, axes, base)
    points = grid_points(axes)
    todo = [_overrides(base, axes, p) for p in points]
    summaries: list[dict[str, Any] | None] = [None] * len(points)
    show = _progress(progress, len(points))
    if jobs == 1:
        for i, ovr in enumerate(todo):
            summaries[i] = run_point(scenario, ovr)
            show(i + 1)
    else:
        with ProcessPoolExecutor(max_workers=min(jobs, len(points))) as pool:
            futures = {pool.submit(run_point, scenario, ovr): i for i, ovr in enumerate(todo)}
            for done, future in enumerate(as_completed(futures), start=1):
                summaries[futures[future]] = future.result()
                show(done)
    rows = [_row(axes, p, s) for p, s in zip(points, summaries, strict=True) if s is not None]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(rows, out / SWEEP_CSV)
    import pandas as pd  # noqa: PLC0415 - heavy, only for Parquet: kept out of node processes

    pd.DataFrame(rows).to_parquet(out / SWEEP_PARQUET, index=False)
    _write_plot(axes, rows, out / SWEEP_PNG, title=Path(scenario).stem)
    return rows


def _progress(stream: TextIO | None, total: int) -> Callable[[int], None]:
    def show(done: int) -> None:
        if stream is None:
            return
        end = "\n" if done == total or not stream.isatty() else "\r"
        stream.write(f"sweep: {done}/{total}{end}")
        stream.flush()

    return show


def _write_csv(rows: Sequence[dict[str, Any]], path: Path) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else v for k, v in row.items()})


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _write_plot(
    axes: Sequence[Axis], rows: Sequence[dict[str, Any]], path: Path, title: str
) -> None:
    """Each loop's overshoot against the first axis, one line per value of the other axes.

    Drawn on a :class:`matplotlib.figure.Figure` of its own: no pyplot, no backend change.
    """
    from matplotlib.figure import Figure

    first, rest = axes[0], axes[1:]
    xs = list(first.values)
    numeric = all(_is_number(v) for v in xs)
    position = {repr(v): (v if numeric else i) for i, v in enumerate(xs)}
    loops = [k.removesuffix(".overshoot_pct") for k in rows[0] if k.endswith(".overshoot_pct")]
    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    for combo in itertools.product(*(a.values for a in rest)):
        these = [r for r in rows if all(r[a.path] == v for a, v in zip(rest, combo, strict=True))]
        tag = ", ".join(f"{a.path}={v}" for a, v in zip(rest, combo, strict=True))
        for loop in loops:
            pts = [
                (position[repr(r[first.path])], r[f"{loop}.overshoot_pct"])
                for r in these
                if r[f"{loop}.overshoot_pct"] is not None
            ]
            ax.plot(
                [p[0] for p in pts],
                [p[1] for p in pts],
                "o-",
                ms=3,
                label=loop + (f" ({tag})" if tag else ""),
            )
    if not numeric:
        ax.set_xticks(range(len(xs)), [str(v) for v in xs])
    ax.set_xlabel(first.path)
    ax.set_ylabel("overshoot [%]")
    ax.set_title(f"{title}: overshoot against {first.path}")
    ax.grid(True, alpha=0.3)
    if ax.lines:
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
