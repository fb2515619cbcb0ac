"""Routine data of a loop from a run's messages, live on the bus or from a recorded run (seed 004).

The monitor node (:mod:`agents.monitor.behaviour`) and ``wncs assess RUN_DIR`` both build their
series with :class:`RunSeries` from the same messages in the same order (the node as it handles
them, the command from ``history.sqlite``, where the historian stored them in that order:
:mod:`runtime.run_files`), so they assess exactly the same numbers. The columns are named
as in :mod:`agents.monitor.columns`: ``LOOP``, ``LOOP.sp``, ``PLANT.STATE``.

Bus-free and file-free: messages come in through :meth:`RunSeries.feed` (or, from a direct run's
record in memory, :func:`feed_run_record`); reading a run directory is
:mod:`runtime.run_files`'s (the application layer).

Window
------
Rows are the primary samples **delivered before** ``until`` (a time) and **taken at or after**
``start``, the last ``window`` of them in delivery order (all without a window), sorted by
sampling instant. The node's assessment at time ``T`` is the one of the data delivered before
``T`` (in its first round at ``T`` it has handled exactly those messages); its final assessment is
at the run's end time, which is also ``wncs assess RUN_DIR``'s default ``until``. With a window,
data older than the window are discarded (identically for node and command).
"""

from __future__ import annotations

import bisect
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from agents.monitor.assess import AssessmentResult, assess
from agents.monitor.columns import SP_SUFFIX, Column, RunLoop, RunShape, resolve_column
from agents.monitor.config import MonitorConfig, SecondarySpec, rows_needed
from agents.monitor.errors import DataError
from bus_schemas import PlantState, Sample, Setpoint, keys
from core.time import to_ticks, to_units

__all__ = ["WindowInfo", "RunSeries", "assess_series", "feed_run_record"]


class _Held:
    """Values by time, looked up as the latest at or before an instant."""

    __slots__ = ("t", "v")

    def __init__(self) -> None:
        self.t: list[int] = []
        self.v: list[float] = []

    def add(self, t: int, v: float) -> None:
        if not self.t or t >= self.t[-1]:
            self.t.append(t)
            self.v.append(v)
        else:  # a late sample (out-of-order delivery)
            i = bisect.bisect_right(self.t, t)
            self.t.insert(i, t)
            self.v.insert(i, v)

    def at(self, t: int) -> float | None:
        i = bisect.bisect_right(self.t, t) - 1
        return self.v[i] if i >= 0 else None

    def prune(self, t: int) -> None:
        """Forget what no lookup at or after ``t`` can return."""
        i = bisect.bisect_right(self.t, t) - 1
        if i > 0:
            del self.t[:i], self.v[:i]


@dataclass(frozen=True)
class _Row:
    t_sampled: int
    order: int  # delivery order
    round: int
    value: float


@dataclass(frozen=True)
class WindowInfo:
    """Which samples a series holds (times in ticks)."""

    loop: str
    n: int
    t_first: int | None
    t_last: int | None
    start: int
    window: int | None
    delivered: int
    gaps: int

    def to_dict(self, until: int | None, time_unit: str) -> dict[str, Any]:
        """JSON-ready, times in the run's unit."""

        def units(t: int | None) -> float | None:
            return None if t is None else to_units(t)

        return {
            "loop": self.loop,
            "samples": self.n,
            "first_sampled": units(self.t_first),
            "last_sampled": units(self.t_last),
            "start": units(self.start),
            "until": units(until),
            "window": self.window,
            "delivered": self.delivered,
            "gaps": self.gaps,
            "time_unit": time_unit,
        }


@dataclass(frozen=True)
class _Table:
    columns: dict[str, NDArray[np.float64]]
    info: WindowInfo


def _loop_of(run: RunShape, column: Column) -> RunLoop:
    """The loop a loop's column (``LOOP``, ``LOOP.sp``) belongs to."""
    if column.loop is None:
        raise ValueError(f"column {column.name!r} belongs to no loop")
    return run.loops[column.loop]


def _initial_setpoint(run: RunShape, column: Column) -> float:
    """The set point at t = 0 of the loop of column ``LOOP.sp``."""
    setpoint = _loop_of(run, column).setpoint
    if setpoint is None:
        raise DataError(
            f"{column.name!r}: loop {column.loop!r} has no set point", column=column.name
        )
    return float(setpoint)


class RunSeries:
    """Routine data of loop ``loop`` and further ``columns``, fed message by message.

    Parameters
    ----------
    run : RunShape
        The run's loops, plant states and set-point keys (:func:`scenario.views.run_shape`).
    loop : str
        The primary: this loop's delivered samples.
    columns : sequence of str
        Further columns (``LOOP.sp``, secondaries), named as in the module docstring.
    start : int
        Samples taken before this (ticks) are ignored.
    window : int, optional
        Keep only the last ``window`` primary samples delivered.

    Raises
    ------
    DataError
        An unknown column (naming it).
    """

    def __init__(
        self,
        run: RunShape,
        loop: str,
        columns: Sequence[str] = (),
        *,
        start: int = 0,
        window: int | None = None,
    ) -> None:
        if loop not in run.loops:
            raise DataError(
                f"{loop!r} is not a loop of this run (loops: {sorted(run.loops)}); the "
                "primary is a loop's delivered measurement",
                column=loop,
            )
        if window is not None and window < 1:
            raise ValueError(f"window must be >= 1 samples, got {window}")
        self.loop = loop
        self.start = start
        self.window = window
        tau_s = run.loops[loop].tau_s
        if tau_s is None:
            raise DataError(f"{loop!r} samples nothing (no sensor)", column=loop)
        self.tau_s = to_ticks(tau_s)
        cols: list[Column] = []
        for name in columns:
            try:
                col = resolve_column(run, name)
            except ValueError as err:
                raise DataError(str(err), column=name) from None
            if col.kind == "meas" and col.loop == loop:
                raise DataError(f"{name!r} is the primary itself", column=name)
            if any(c.name == name for c in cols):
                raise DataError(f"column {name!r} requested twice", column=name)
            cols.append(col)
        self.columns: tuple[Column, ...] = tuple(cols)
        self._rows: deque[_Row] = deque(maxlen=window)
        self._delivered = 0
        self._held: dict[str, _Held] = {c.name: _Held() for c in cols if c.kind != "sp"}
        self._sp: dict[str, tuple[list[int], list[float]]] = {
            c.name: ([-1], [_initial_setpoint(run, c)]) for c in cols if c.kind == "sp"
        }
        self._routes: dict[str, tuple[type[BaseModel], list[Callable[..., None]]]] = {}
        self._route(keys.meas(loop), Sample, self._on_primary)
        for c in cols:
            if c.kind == "meas":
                self._route(keys.meas(c.loop), Sample, self._meas_of(c.name))
            elif c.kind == "sp":
                self._route(_loop_of(run, c).setpoint_key, Setpoint, self._sp_of(c.name))
            else:
                self._route(keys.plant_state(c.plant), PlantState, self._state_of(c))

    def _route(self, key: str, body: type[BaseModel], handler: Callable[..., None]) -> None:
        self._routes.setdefault(key, (body, []))[1].append(handler)

    # -- feeding ---------------------------------------------------------------------------------
    def subscriptions(self) -> list[tuple[str, type[BaseModel]]]:
        """Run-relative keys to read and their body types."""
        return [(k, body) for k, (body, _) in sorted(self._routes.items())]

    def feed(self, key: str, rnd: int, t: int, body: BaseModel) -> None:
        """One message (run-relative ``key``, round, time, validated body), in handling order."""
        for handler in self._routes[key][1]:
            handler(rnd, t, body)

    def _on_primary(self, rnd: int, t: int, body: Sample) -> None:
        if body.t_sampled < self.start:
            return
        self._rows.append(_Row(body.t_sampled, self._delivered, rnd, body.value))
        self._delivered += 1
        if self.window is not None and self._delivered % self.window == 0:
            self._prune()

    def _meas_of(self, name: str) -> Callable[[int, int, Sample], None]:
        held = self._held[name]

        def handle(rnd: int, t: int, body: Sample) -> None:
            held.add(body.t_sampled, body.value)

        return handle

    def _sp_of(self, name: str) -> Callable[[int, int, Setpoint], None]:
        rounds, values = self._sp[name]

        def handle(rnd: int, t: int, body: Setpoint) -> None:
            rounds.append(rnd)
            values.append(body.value)

        return handle

    def _state_of(self, col: Column) -> Callable[[int, int, PlantState], None]:
        held = self._held[col.name]

        def handle(rnd: int, t: int, body: PlantState) -> None:
            for tg, v in zip(body.t, body.values.get(col.state, ()), strict=False):
                held.add(tg, v)

        return handle

    def _prune(self) -> None:
        """Forget what no row of this or a later window can need."""
        t0 = min(r.t_sampled for r in self._rows)
        r0 = min(r.round for r in self._rows)
        for held in self._held.values():
            held.prune(t0)
        for rounds, values in self._sp.values():
            i = bisect.bisect_right(rounds, r0) - 1
            if i > 0:
                del rounds[:i], values[:i]

    # -- the table -------------------------------------------------------------------------------
    def info(self) -> WindowInfo:
        """The window as it stands."""
        rows = sorted(self._rows, key=lambda r: (r.t_sampled, r.order))
        ts = [r.t_sampled for r in rows]
        gaps = sum(1 for a, b in zip(ts, ts[1:], strict=False) if b - a != self.tau_s)
        return WindowInfo(
            loop=self.loop,
            n=len(rows),
            t_first=ts[0] if ts else None,
            t_last=ts[-1] if ts else None,
            start=self.start,
            window=self.window,
            delivered=self._delivered,
            gaps=gaps,
        )

    def table(self, *, min_rows: int = 1) -> tuple[dict[str, NDArray[np.float64]], WindowInfo]:
        """The aligned columns (primary under the loop's name) and the window.

        Raises
        ------
        DataError
            A missing value (naming column and row), fewer than ``min_rows`` rows, or a constant
            column other than a set point, as for CSV files
            (:func:`agents.monitor.routine_data.load_routine_csv`).
        """
        rows = sorted(self._rows, key=lambda r: (r.t_sampled, r.order))
        info = self.info()
        n = len(rows)
        out: dict[str, NDArray[np.float64]] = {
            self.loop: np.array([r.value for r in rows], dtype=float)
        }
        for c in self.columns:
            values = np.empty(n)
            if c.kind == "sp":
                rounds, sps = self._sp[c.name]
                for i, r in enumerate(rows):
                    values[i] = sps[bisect.bisect_right(rounds, r.round) - 1]
            else:
                held = self._held[c.name]
                for i, r in enumerate(rows):
                    v = held.at(r.t_sampled)
                    if v is None:
                        what = "sample of that loop" if c.kind == "meas" else "grid point"
                        raise DataError(
                            f"column {c.name!r}, row {i + 1} (sampled at t = "
                            f"{to_units(r.t_sampled):g}): missing value (no {what} at or "
                            "before that instant)",
                            column=c.name,
                            row=i + 1,
                        )
                    values[i] = v
            out[c.name] = values
        if n < max(min_rows, 1):
            raise DataError(
                f"loop {self.loop!r}: {n} samples in the window; the model needs at least "
                f"{max(min_rows, 1)}",
                column=self.loop,
                row=n,
            )
        for name, arr in out.items():
            if name.endswith(SP_SUFFIX) and any(c.name == name for c in self.columns):
                continue
            if np.ptp(arr) == 0.0:
                raise DataError(
                    f"column {name!r} is constant ({arr[0]:g} in all {n} rows, rows 1-{n}): no "
                    "variability to analyse",
                    column=name,
                    row=1,
                )
        return out, info


def assess_series(
    series: RunSeries,
    delay: int,
    secondaries: Iterable[SecondarySpec] = (),
    *,
    setpoint: bool = False,
    config: MonitorConfig | None = None,
    source: str | None = None,
) -> tuple[AssessmentResult, WindowInfo]:
    """:func:`agents.monitor.assess.assess` on a run's series (the node's and the CLI's path).

    With ``setpoint`` the primary is the control error ``LOOP.sp - LOOP`` (the series must hold
    the ``LOOP.sp`` column).

    Raises
    ------
    DataError
        From :meth:`RunSeries.table`.
    ValueError
        Inconsistent delays.
    """
    cfg = config or MonitorConfig()
    specs = list(secondaries)
    data, info = series.table(min_rows=rows_needed(cfg, 2 if specs else 1))
    sp = series.loop + SP_SUFFIX if setpoint else None
    result = assess(data, series.loop, delay, specs, setpoint=sp, config=cfg, source=source)
    return result, info


def feed_run_record(rec: Any, series: RunSeries, *, until: int) -> int:
    """Feed ``series`` from a direct run's :class:`core.record.RunRecord` in memory: its messages
    stamped before ``until`` (ticks), by time (no bus, no rounds: the time stands for the round, so
    a set point applies to the samples handled at its instant). Returns the messages fed."""
    events: list[tuple[int, int, str, BaseModel]] = []
    subs = dict(series.subscriptions())
    for name, plant in rec.plants.items():
        key = keys.plant_state(name)
        if key in subs:
            for t, x in zip(plant.t, plant.x, strict=True):
                if t < until:
                    values = {s: (float(v),) for s, v in zip(plant.state_names, x, strict=True)}
                    events.append((t, 0, key, PlantState(t=(t,), values=values)))
    for name, loop in rec.loops.items():
        for t, value in loop.setpoints:
            for key in (keys.setpoint(name), keys.loop_setpoint(name)):
                if key in subs and t < until:
                    events.append((t, 1, key, Setpoint(value=value)))
        key = keys.meas(name)
        if key in subs:
            for t, ts, y in zip(loop.t, loop.t_sampled, loop.y, strict=True):
                if t < until:
                    events.append((t, 2, key, Sample(value=y, t_sampled=ts)))
    events.sort(key=lambda e: (e[0], e[1], e[2]))
    for t, _, key, body in events:
        series.feed(key, t, t, body)
    return len(events)
