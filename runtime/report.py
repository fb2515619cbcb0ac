"""Run artefacts: ``summary.json`` and the PNG plots (seed 000, Fig. 3 and 4 style)."""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np

from agents.wncsca.plots import run_plots
from controllers.law_plots import figures_of
from core.errors import ConfigError
from core.record import LoopRecord, PlantRecord, RunRecord, summarize, wncsca_summary
from core.time import to_units
from runtime.artefacts import HISTORY_FILE, RUN_FILE, SCENARIO_FILE
from runtime.executions import multi_loop_executions
from runtime.history import load_record
from scenario import ControllerNodeConfig, Scenario, load_scenario

__all__ = [
    "SUMMARY_FILE",
    "RECORD_FILE",
    "write_summary",
    "write_plots",
    "PLOTS",
    "AUTO_LOOPS",
    "SUMMARY_FIGURE",
    "summary_figure",
    "draw_loop",
    "law_figures",
    "save_record",
    "load_saved_record",
    "load_run",
]

SUMMARY_FILE = "summary.json"
RECORD_FILE = "record.json"


def _json_safe(x: Any) -> Any:
    """``x`` with every non-finite float as ``None`` (JSON has no NaN or infinity)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v) for v in x]
    return x


def write_summary(rec: RunRecord, out: Path, **extra: Any) -> dict[str, Any]:
    """Write ``summary.json`` and return it (a figure that is not finite, e.g. the IAE of a loop
    that diverged, is written ``null``)."""
    summary = _json_safe({**summarize(rec), **extra})
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
    return summary


def save_record(rec: RunRecord, out: Path) -> None:
    """Keep a direct run's record (bus runs have ``history.sqlite`` instead)."""
    data = {
        "scenario": rec.scenario,
        "seed": rec.seed,
        "engine": rec.engine,
        "end_time": rec.end_time,
        "time_unit": rec.time_unit,
        "loops": {n: vars(lp) for n, lp in rec.loops.items()},
        "disturbances": rec.disturbances,
        "hops": rec.hops,
        "configurations": rec.configurations,
        "net_nodes": rec.net_nodes,
        "wncsca": rec.wncsca,
        "monitor": rec.monitor,
        "plants": {
            n: {"state_names": p.state_names, "t": p.t, "x": p.x} for n, p in rec.plants.items()
        },
    }
    (out / RECORD_FILE).write_text(json.dumps(data))


def load_saved_record(out: Path) -> RunRecord:
    """Inverse of :func:`save_record`."""
    data = json.loads((out / RECORD_FILE).read_text())
    rec = RunRecord(
        data["scenario"], data["seed"], data["engine"], data["end_time"], data["time_unit"]
    )
    rec.disturbances = data.get("disturbances", {})
    rec.hops = data.get("hops", {})
    rec.configurations = data.get("configurations", [])
    rec.net_nodes = data.get("net_nodes", {})
    rec.wncsca = data.get("wncsca", {})
    rec.monitor = data.get("monitor", {})
    for n, lp in data["loops"].items():
        lp["setpoints"] = [tuple(v) for v in lp["setpoints"]]
        rec.loops[n] = LoopRecord(**lp)
    for n, p in data["plants"].items():
        rec.plants[n] = PlantRecord(tuple(p["state_names"]), p["t"], p["x"])
    return rec


def load_run(out: Path) -> tuple[Scenario, RunRecord]:
    """A run directory's scenario as run and its record: from ``history.sqlite`` (bus engines)
    or ``record.json`` (direct engine).

    Raises
    ------
    ConfigError
        If ``out`` has no ``run.json`` (it is not a run directory) or its scenario does not load.
    """
    try:
        info = json.loads((out / RUN_FILE).read_text())
        if not isinstance(info, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as err:
        raise ConfigError(f"{out / RUN_FILE}: not a run directory ({err})") from err
    scenario = load_scenario(out / SCENARIO_FILE)
    if (out / HISTORY_FILE).exists():
        try:
            return scenario, load_record(
                out / HISTORY_FILE, scenario, engine=str(info.get("engine", "processes"))
            )
        except sqlite3.DatabaseError as err:
            raise ConfigError(f"{out / HISTORY_FILE}: not a readable history ({err})") from err
    try:
        return scenario, load_saved_record(out)
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ConfigError(f"{out / RECORD_FILE}: not a readable record ({err})") from err


def draw_loop(ax: Any, ax_u: Any, rec: RunRecord, name: str) -> None:
    """Draw loop ``name`` of ``rec`` on two matplotlib axes: the plant's true output with the set
    point and the delivered samples on ``ax``, the control moves on ``ax_u``."""
    loop = rec.loops[name]
    assert loop.sensor is not None  # an actuator-only loop has no output to draw
    t, y = rec.plants[loop.plant].signal(loop.sensor)
    sp_t = [to_units(v) for v, _ in loop.setpoints] + [to_units(rec.end_time)]
    sp_v = [v for _, v in loop.setpoints]
    ax.plot(t, y, label=f"{loop.sensor} (plant)")
    ax.step(sp_t, [*sp_v, sp_v[-1]], where="post", ls="--", color="k", label="set point")
    if loop.t:
        ax.plot([to_units(v) for v in loop.t], loop.y, ".", ms=3, label="delivered samples")
        moves = [(to_units(t), u) for t, u in zip(loop.t, loop.u, strict=True) if u is not None]
        if moves:
            ax_u.step(*zip(*moves, strict=True), where="post", color="C2")
    ax.set_ylabel(loop.sensor)
    ax.set_title(f"{rec.scenario}: loop {name} ({rec.engine} engine)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax_u.set_ylabel("u")
    ax_u.set_xlabel(f"time [{rec.time_unit}]")
    ax_u.grid(True, alpha=0.3)


PLOTS = ("auto", "all", "summary", "none")
"""``wncs run --plots``: which figures a run draws."""

AUTO_LOOPS = 10
"""``auto`` draws every loop's figure up to this many loops, the summary figure beyond."""


def write_plots(
    rec: RunRecord,
    out: Path,
    *,
    scenario: Scenario | None = None,
    plots: str = "auto",
    summary: dict[str, Any] | None = None,
) -> list[Path]:
    """Write the run's plots and return their paths.

    ``plots`` (``wncs run --plots``): ``all``, one PNG per loop (the true output and its set
    point against time, and the control moves), the coordination agent's figures when it ran,
    and, given the ``scenario``, the figures of every multi-loop controller whose law registers
    some (:func:`law_figures`); ``summary``, one figure of every loop at once
    (:func:`summary_figure`, from ``summary`` when the run's is at hand) and the agent's;
    ``none``; ``auto`` (the default), ``all`` up to :data:`AUTO_LOOPS` loops, ``summary``
    beyond (a hundred loops' figures took longer to draw than the run: issue 41, item 3).
    Drawn on :class:`matplotlib.figure.Figure` objects of their own: no pyplot, so a notebook's
    backend and current figure are left alone.
    """
    from matplotlib.figure import Figure

    if plots not in PLOTS:
        raise ConfigError(f"--plots: one of {', '.join(PLOTS)}, got {plots!r}")
    loops = [n for n, lp in sorted(rec.loops.items()) if lp.sensor is not None]
    if plots == "auto":
        plots = "all" if len(loops) <= AUTO_LOOPS else "summary"
    if plots == "none":
        return []
    paths = []
    if plots == "summary":
        paths.append(summary_figure(rec, out, summary or summarize(rec)))
    for name in loops if plots == "all" else ():  # an actuator-only loop has no output
        fig = Figure(figsize=(7, 5))
        ax, ax_u = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
        draw_loop(ax, ax_u, rec, name)
        fig.tight_layout()
        path = out / f"{name}.png"
        fig.savefig(path, dpi=110)
        paths.append(path)
    if rec.wncsca:
        paths += run_plots(
            wncsca_summary(rec.wncsca), out, unit=rec.time_unit, end_time=to_units(rec.end_time)
        )
    if scenario is not None and plots == "all":
        paths += law_figures(rec, scenario, out)
    return paths


SUMMARY_FIGURE = "loops.png"


def summary_figure(rec: RunRecord, out: Path, summary: dict[str, Any]) -> Path:
    """Every loop of the run in one figure (``loops.png``): each loop's tracking error
    ``y - r`` over its largest set-point step (or over its set point's magnitude when it has
    none) against time, all loops on one axes; each step's overshoot and each loop's IAE by
    loop. ``summary``: the run's ``summary.json`` (its loops' steps and IAE)."""
    from matplotlib.figure import Figure

    names = [n for n, lp in sorted(rec.loops.items()) if lp.sensor is not None]
    fig = Figure(figsize=(9, 8))
    ax_e, ax_os, ax_iae = fig.subplots(3, 1, gridspec_kw={"height_ratios": [2, 1, 1]})
    for name in names:
        loop = rec.loops[name]
        assert loop.sensor is not None
        t, y = rec.plants[loop.plant].signal(loop.sensor)
        sp_t = np.asarray([to_units(v) for v, _ in loop.setpoints])
        sp_v = np.asarray([v for _, v in loop.setpoints], dtype=float)
        r = sp_v[np.clip(np.searchsorted(sp_t, t, side="right") - 1, 0, len(sp_v) - 1)]
        steps = np.abs(np.diff(sp_v))
        scale = float(steps.max()) if steps.size and steps.max() > 0 else abs(sp_v[0]) or 1.0
        ax_e.plot(t, (y - r) / scale, lw=0.6, alpha=0.5)
    ax_e.set_ylabel("(y - r) / largest step")
    ax_e.set_xlabel(f"time [{rec.time_unit}]")
    ax_e.set_title(f"{rec.scenario}: {len(names)} loops ({rec.engine} engine)")
    ax_e.grid(True, alpha=0.3)
    loops = summary["loops"]
    for i, name in enumerate(names):
        os_ = [s["overshoot_pct"] for s in loops[name].get("steps", [])]
        ax_os.plot([i] * len(os_), [v if v is not None else np.nan for v in os_], ".", color="C0")
    ax_os.set_ylabel("overshoot %")
    ax_os.grid(True, alpha=0.3)
    iae = [loops[n]["iae"] if loops[n]["iae"] is not None else np.nan for n in names]
    ax_iae.bar(range(len(names)), iae, color="C1")
    ax_iae.set_ylabel("IAE")
    ax_iae.set_xlabel("loop")
    ticks = range(0, len(names), max(1, len(names) // 20))
    for ax in (ax_os, ax_iae):
        ax.set_xticks(list(ticks), [names[i] for i in ticks], rotation=90, fontsize=6)
    fig.tight_layout()
    path = out / SUMMARY_FIGURE
    fig.savefig(path, dpi=100)
    return path


def law_figures(rec: RunRecord, scenario: Scenario, out: Path) -> list[Path]:
    """The figures of the laws of ``scenario``'s multi-loop controllers, from the run's record.

    For every multi-loop controller whose law registers a figure function
    (:data:`controllers.law_plots.LAW_FIGURES`), its executions are rebuilt from ``rec``
    (:func:`runtime.executions.multi_loop_executions`) and the law draws its own signals over them;
    figure ``key`` of controller ``name`` is saved as ``<law type>_<name>_<key>.png`` (for the
    MRAC: ``mrac_<name>_states.png``, ``_outputs``, ``_errors``, ``_theta``).
    """
    paths = []
    for name, cfg in sorted(scenario.nodes_of(ControllerNodeConfig).items()):
        if cfg.loops is None:
            continue
        draw = figures_of(cfg.law)
        if draw is None:
            continue
        executions = [
            (to_units(ex.t), ex.y, ex.r) for ex in multi_loop_executions(scenario, rec, name)
        ]
        figs = draw(
            cfg.law,
            list(cfg.loops),
            executions,
            title=f"{rec.scenario}: {name} ({rec.engine} engine)",
            unit=rec.time_unit,
        )
        for key, fig in figs.items():
            path = out / f"{cfg.law.type}_{name}_{key}.png"
            fig.savefig(path, dpi=110)
            paths.append(path)
    return paths
