"""The notebook API: load a scenario, change it with validation, run it, read its results.

::

    import wncs

    sc = wncs.load("scenarios/jcstr_benchmark.yaml", {"loops.level.tau_s": 0.2})
    result = wncs.run(sc)                      # the direct engine; engine="threads" / "processes"
    result.loops["level"].overshoot_pct        # the figures of summary.json
    result.loops["level"].to_pandas()          # t, t_sampled, y, setpoint, u
    result.plot()                              # into the current matplotlib figure

Every change goes through validation: :func:`load` and :func:`with_values` apply dotted-path
values exactly as ``wncs run --set`` does (:mod:`scenario.overrides`) and validate the result,
so ``loops.level.tau_s = -0.1`` is refused naming the field, as in the file. (A pydantic
``model_copy(update=...)`` would skip validation: use :func:`with_values` instead.)

:func:`run` runs on any engine. The direct engine needs no directory; a bus engine runs in
``out`` (a fresh temporary directory by default) like ``wncs run``, and the :class:`Result` is
read back from its history, so its numbers are the CLI's. :func:`open_run` reads any run
directory ``wncs run`` left.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from core.errors import ConfigError
from core.record import LoopRecord, PlantRecord, RunRecord, summarize
from core.time import to_units
from runtime import export
from runtime.direct import simulate
from runtime.launcher import ENGINES, launch
from runtime.report import SUMMARY_FILE, draw_loop, load_run
from runtime.sweep import Axis
from runtime.sweep import sweep as _sweep
from scenario import Scenario, load_scenario, parse_scenario
from scenario.overrides import Override, apply_overrides, parse_override

__all__ = [
    "load",
    "with_values",
    "run",
    "open_run",
    "sweep",
    "Result",
    "LoopResult",
    "PlantResult",
]

Values = Mapping[str, Any] | Sequence[str]
"""Overrides: ``{"loops.level.tau_s": 0.2}`` (Python values) or ``["loops.level.tau_s=0.2"]``
(``--set`` strings, values parsed as YAML)."""


def _overrides(values: Values) -> list[Override]:
    if isinstance(values, Mapping):
        out = []
        for path, value in values.items():
            segments = tuple(str(path).split("."))
            if not all(segments):
                raise ConfigError(f"{path!r} is not a dotted path (empty segment)")
            out.append(Override(f"{path}={value!r}", segments, value))
        return out
    if isinstance(values, str):
        raise TypeError("overrides: a mapping or a list of 'path=value' strings, not one string")
    return [parse_override(v) for v in values]


def load(path: str | Path, values: Values = ()) -> Scenario:
    """Read and validate a scenario file, with ``values`` applied first (as ``--set``).

    Raises
    ------
    ConfigError
        Naming the file, the line and the dotted field, as ``wncs validate`` does.
    """
    return load_scenario(path, overrides=_overrides(values))


def with_values(scenario: Scenario, values: Values, *, source: str | None = None) -> Scenario:
    """A copy of ``scenario`` with dotted-path ``values`` set, validated like a file.

    Raises
    ------
    ConfigError
        If a path does not exist (naming it) or the result does not validate (naming the field).
    """
    data = apply_overrides(scenario.model_dump(), _overrides(values))
    return parse_scenario(data, source=source or f"scenario {scenario.name!r}")


@dataclass(frozen=True)
class LoopResult:
    """One loop of a run: its record and its figures (``summary.json``'s ``loops.<name>``)."""

    name: str
    record: LoopRecord
    figures: dict[str, Any]
    time_unit: str

    @property
    def overshoot_pct(self) -> float | None:
        return self.figures["overshoot_pct"]

    @property
    def settling_time(self) -> float | None:
        return self.figures["settling_time"]

    @property
    def iae(self) -> float | None:
        return self.figures["iae"]

    def steps(self) -> pd.DataFrame:
        """One row per set-point step: ``t``, ``from``, ``to``, ``overshoot_pct``,
        ``settling_time``, ``iae``."""
        return pd.DataFrame(
            self.figures["steps"],
            columns=["t", "from", "to", "overshoot_pct", "settling_time", "iae"],
        )

    def to_pandas(self) -> pd.DataFrame:
        """Every sample delivered to the controller: ``t`` (delivery and move, in the scenario's
        time unit), ``t_sampled``, ``y``, ``setpoint`` (in force at ``t``), ``u`` (NaN where no
        move was made). The same rows as ``wncs export``'s ``loop_<name>.csv``."""
        header, rows = export.loop_table(self.record)
        return pd.DataFrame(rows, columns=list(header), dtype=float)


@dataclass(frozen=True)
class PlantResult:
    """One plant's true state on its monitoring grid."""

    name: str
    record: PlantRecord

    def to_pandas(self) -> pd.DataFrame:
        """``t`` and one column per state (``wncs export``'s ``plant_<name>.csv``)."""
        header, rows = export.plant_table(self.record)
        return pd.DataFrame(rows, columns=list(header), dtype=float)


@dataclass
class Result:
    """A run: its scenario, record and summary (the figures of ``summary.json``)."""

    scenario: Scenario
    record: RunRecord
    summary: dict[str, Any]
    out: Path | None = None
    loops: dict[str, LoopResult] = field(init=False)
    plants: dict[str, PlantResult] = field(init=False)

    def __post_init__(self) -> None:
        unit = self.record.time_unit
        self.loops = {
            n: LoopResult(n, lp, self.summary["loops"][n], unit)
            for n, lp in self.record.loops.items()
        }
        self.plants = {n: PlantResult(n, p) for n, p in self.record.plants.items()}

    def figures(self) -> pd.DataFrame:
        """One row per loop: ``overshoot_pct``, ``settling_time``, ``iae``."""
        return pd.DataFrame(
            {
                n: {k: lp.figures[k] for k in ("overshoot_pct", "settling_time", "iae")}
                for n, lp in self.loops.items()
            }
        ).T

    def tables(self) -> dict[str, pd.DataFrame]:
        """Every table ``wncs export`` writes, by file stem (``loop_level``, ``network_paths``,
        ``wncsca_decisions``, ...)."""
        return {
            name: pd.DataFrame(rows, columns=list(header))
            for name, (header, rows) in export.tables(self.record, self.summary).items()
        }

    def plot(self, loops: Sequence[str] | None = None, *, fig: Any = None) -> list[Any]:
        """Draw each loop (true output, set point, delivered samples; moves below) into ``fig``
        (default: pyplot's current figure), without changing the backend; returns the axes,
        two per loop."""
        import matplotlib.pyplot as plt

        names = [
            n for n in (loops or sorted(self.loops)) if self.record.loops[n].sensor is not None
        ]
        if not names:
            raise ValueError("no loop with an output to draw")
        fig = fig if fig is not None else plt.gcf()
        grid = fig.subplots(
            2 * len(names), 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.3] * len(names)}
        )
        axes = list(grid)
        for k, name in enumerate(names):
            draw_loop(axes[2 * k], axes[2 * k + 1], self.record, name)
        return axes

    @property
    def end_time(self) -> float:
        return to_units(self.record.end_time)


def run(
    scenario: Scenario | str | Path,
    values: Values = (),
    *,
    engine: str = "direct",
    out: str | Path | None = None,
    seed: int | None = None,
    realtime: float | None = None,
    force: bool = False,
) -> Result:
    """Run a scenario (a validated :class:`Scenario` or a file) on ``engine`` and return its
    :class:`Result`.

    ``values`` are applied first (as :func:`with_values`). The direct engine with no ``out``
    simulates in memory; with ``out``, or on a bus engine (``threads``, ``processes``), the run
    goes through the launcher exactly as ``wncs run --out DIR`` (``out`` default: a new
    temporary directory; one holding a run already is refused unless ``force``) and the result
    is read back from the directory.

    Raises
    ------
    ConfigError
        If the scenario or a value does not validate (nothing has run).
    RuntimeError
        If a bus run fails (the launcher's error: a node fault, a timeout).
    """
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
    sc = scenario if isinstance(scenario, Scenario) else load(scenario)
    if values:
        sc = with_values(sc, values)
    if seed is not None:
        sc = with_values(sc, {"seed": seed})
    if engine == "direct" and out is None:
        rec = simulate(sc)
        return Result(sc, rec, summarize(rec))
    target = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="wncs-"))
    if (target / "run.json").exists():
        if not force:
            raise ConfigError(f"out {target}: holds a run already; pass force=True to replace it")
        shutil.rmtree(target)
    target.mkdir(parents=True, exist_ok=True)
    path = target / "input.yaml"  # what the nodes load; scenario.yaml is the launcher's copy
    path.write_text(yaml.safe_dump(sc.model_dump(mode="json"), sort_keys=False))
    res = launch(path, target, engine=engine, realtime=realtime)
    if res.code != 0:
        raise RuntimeError(f"the {engine} run failed (exit {res.code}): {res.error}")
    return open_run(target)


def open_run(out: str | Path) -> Result:
    """The :class:`Result` of a run directory left by ``wncs run`` (any engine).

    Raises
    ------
    ConfigError
        If ``out`` is not a run directory.
    """
    out = Path(out)
    sc, rec = load_run(out)
    try:
        summary = json.loads((out / SUMMARY_FILE).read_text())
    except (OSError, ValueError):  # a run cut short: the figures from its record
        summary = summarize(rec)
    return Result(sc, rec, summary, out)


def sweep(
    scenario: str | Path,
    grid: Mapping[str, Sequence[Any]],
    values: Values = (),
    *,
    out: str | Path | None = None,
    jobs: int | None = None,
) -> pd.DataFrame:
    """``wncs sweep`` from Python: the scenario file run on the direct engine at every point of
    ``grid`` (dotted path -> values; the Cartesian product, the last path varying fastest), with
    ``values`` applied to every point first. Returns the table of ``sweep.csv`` (one row per
    point: the grid values, then per loop ``LOOP.overshoot_pct``, ``LOOP.settling_time``,
    ``LOOP.iae``); ``out`` (default a new temporary directory) also gets ``sweep.csv``,
    ``sweep.parquet`` and ``sweep.png``.

    Raises
    ------
    ConfigError
        If a value or a point does not validate (nothing has run).
    """
    axes = [
        Axis(f"{path}={','.join(map(repr, vals))}", path, tuple(vals))
        for path, vals in grid.items()
    ]
    target = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="wncs-sweep-"))
    rows = _sweep(scenario, axes, target, overrides=_overrides(values), jobs=jobs)
    return pd.DataFrame(rows)
