"""Seed 000, III.D-III.E on the coordination agent's model: the sampling-period / largest-delay
curves (Fig. 9 and the reversed study), the paper method's trials in the worked example (Fig. 10)
and the worked example's operating points on their curves (Fig. 11, Fig. 12)::

    python bench/wncsca_figures.py [SCENARIO] [--out bench/out/wncsca] [--phase worst|fixed]
                                   [--resolution 0.001] [--periods 0.05 0.1 ...]

``SCENARIO`` (default ``scenarios/jcstr_wncs.yaml``) must have an agent node; its configuration
(overshoot limit, set-point test, phase handling, search order) is used unless ``--phase``
overrides the phase. Writes ``fig9_level.png``, ``fig9_temperature.png``, ``fig10.png``,
``fig11_temperature.png`` and ``fig12_level.png`` into ``--out`` and prints markdown tables: the
curves, and the worked example (control-path delays level 0.17 pu, temperature 0.10 pu) beside
the paper's numbers.

A curve point is :func:`largest_delay`: the largest delay of the loop, on a grid of
``resolution``, that is *checked* to keep its overshoot within the limit, found by doubling then
bisection as :mod:`agents.wncsca.bounds` does, with the loop at the given period and the other loop
at its operating point ``(tau_s, tau_d)``. The overshoot need not be monotone in the delay, so a
point is a delay where the limit holds with a violation one grid step above it, not necessarily
the largest such delay. In our JCSTR model the level does not depend on the temperature loop
(``dH/dt = (F_in - F_out)/A_B``), so Fig. 9's three level curves coincide; the interaction the
paper reports shows only in the reversed (temperature) study.

With the agent's ``phase: worst`` (4 phases of each step against the sampling instants) the whole
script takes about 45 s (2640 simulations, one core); ``--phase fixed`` (the paper's fixed step
times) about 12 s. The titles say which was used.
"""

from __future__ import annotations

import argparse
import math
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.wncsca import bounds
from agents.wncsca.assignment import Assignment, Trial
from agents.wncsca.config import WncscaConfig
from agents.wncsca.model import LoopModel
from agents.wncsca.paper import successive_approximation
from agents.wncsca.plots import fig10
from runtime.direct import loop_model
from scenario import Scenario, load_scenario

__all__ = [
    "DEFAULT_SCENARIO",
    "EXAMPLE_DELAYS",
    "PAPER_EXAMPLE",
    "Curve",
    "SearchPoint",
    "agent_model",
    "largest_delay",
    "delay_curves",
    "plot_curves",
    "fig9",
    "fig10",
    "search_points",
    "fig_points",
    "curves_markdown",
    "example_markdown",
    "main",
]

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SCENARIO = ROOT / "scenarios" / "jcstr_wncs.yaml"
DEFAULT_OUT = ROOT / "bench" / "out" / "wncsca"
PERIODS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45)
"""Sampling periods of the searched loop on the curves, pu (Fig. 9's range)."""
OPERATING_POINTS = ((0.1, 0.0), (0.15, 0.05), (0.2, 0.1))
"""The other loop's ``(tau_s, tau_d)`` for the three curves, pu."""
EXAMPLE_DELAYS = {"level": 0.17, "temperature": 0.10}
"""The worked example's control-path delays, pu (seed 000, III.E)."""
PAPER_EXAMPLE = {
    "points": (("A", "temperature", 0.185), ("B", "level", 0.11), ("C", "temperature", 0.16),
               ("D", "level", 0.071)),
    "temperature_os_at_B": 27.2,
    "final_periods": {"level": 0.071, "temperature": 0.16},
    "final_overshoot_pct": {"level": 24.3, "temperature": 25.0},
}  # fmt: skip
"""Seed 000, III.E: points A-D (tau_s, pu), temperature OS at B, and the OS at point D, %."""
SYMBOL = {"level": "L", "temperature": "T"}


@dataclass(frozen=True)
class Curve:
    """Largest tolerable delay of ``loop`` against its sampling period, with the other loops at
    fixed operating points ``{loop: (tau_s, tau_d)}``; ``nan`` where even zero delay violates the
    limit."""

    loop: str
    fixed: dict[str, tuple[float, float]]
    periods: tuple[float, ...]
    delays: tuple[float, ...]
    label: str


@dataclass(frozen=True)
class SearchPoint:
    """The result of one single-loop search of the paper's method (A, B, C, ... of Fig. 11-12):
    the period found and the other loops' periods it was searched with."""

    name: str
    alternation: int
    loop: str
    period: float
    overshoot_pct: float
    periods: dict[str, float]


def agent_model(path: Path = DEFAULT_SCENARIO, *, phase: str | None = None) -> LoopModel:
    """The agent's :class:`LoopModel` of a scenario with an agent node (``phase`` overrides)."""
    scenario = load_scenario(path)
    config = _agent_config(scenario)
    if phase is not None:
        config = config.model_copy(update={"phase": phase})
    return loop_model(scenario, config)


def _agent_config(scenario: Scenario) -> WncscaConfig:
    agents = [cfg for cfg in scenario.nodes.values() if isinstance(cfg, WncscaConfig)]
    if len(agents) != 1:
        raise ValueError(f"{scenario.name}: expected one agent node, found {len(agents)}")
    return agents[0]


def largest_delay(
    model: LoopModel,
    loop: str,
    periods: Mapping[str, float],
    delays: Mapping[str, float],
    resolution: float | None = None,
) -> float:
    """Largest control-path delay of ``loop`` checked to keep its overshoot within the limit.

    Parameters
    ----------
    model : LoopModel
        The agent's model; its ``overshoot_limit`` and ``max_delay`` are used.
    loop : str
        The loop whose delay is searched.
    periods : Mapping[str, float]
        Sampling periods of the loops (time units; a loop not named: benchmark).
    delays : Mapping[str, float]
        Control-path delays of the other loops (``loop``'s own entry is ignored; default 0).
    resolution : float, optional
        Width at which the bisection stops and grid of the delays tried (default: the model's
        ``delay_resolution``).

    Returns
    -------
    float
        A multiple of ``resolution`` within the limit whose next larger trial violated it (or
        ``max_delay``), as :mod:`agents.wncsca.bounds`; ``nan`` when even zero delay violates.

    Notes
    -----
    Seed 000, III.C ("adding time delay elements") and III.D, Fig. 9: ``tau_d-max`` at a given
    sampling period. Doubling starts at the loop's period (at least 16 grid steps).
    """
    bound = bounds.largest_delay(model, loop, periods, delays, resolution)
    return math.nan if bound.overshoot_pct > model.config.overshoot_limit else bound.tau_d_max


def _others(model: LoopModel, loop: str) -> list[str]:
    if loop not in model.loops:
        raise ValueError(f"unknown loop {loop!r} (loops: {list(model.loops)})")
    return [n for n in model.loops if n != loop]


def _label(fixed: Mapping[str, tuple[float, float]]) -> str:
    return ", ".join(
        f"tau_s{SYMBOL.get(n, n)} {p:g}, tau_d{SYMBOL.get(n, n)} {d:g}"
        for n, (p, d) in fixed.items()
    )


def _tex(label: str) -> str:
    return re.sub(r"tau_([sd])([A-Za-z]+)", r"$\\tau_{\1\2}$", label)


def delay_curves(
    model: LoopModel,
    loop: str,
    periods: Sequence[float] = PERIODS,
    operating_points: Sequence[tuple[float, float]] = OPERATING_POINTS,
    resolution: float | None = None,
) -> list[Curve]:
    """One :class:`Curve` of ``loop`` per operating point ``(tau_s, tau_d)`` of the other loop
    (the model must have two loops; seed 000, III.D)."""
    others = _others(model, loop)
    if len(others) != 1:
        raise ValueError(f"operating points fix one other loop; the model has {list(model.loops)}")
    (other,) = others
    curves = []
    for tau_s, tau_d in operating_points:
        fixed = {other: (float(tau_s), float(tau_d))}
        curves.append(_curve(model, loop, periods, fixed, resolution))
    return curves


def _curve(
    model: LoopModel,
    loop: str,
    periods: Sequence[float],
    fixed: Mapping[str, tuple[float, float]],
    resolution: float | None,
    label: str | None = None,
) -> Curve:
    values = []
    for p in periods:
        per = {n: v[0] for n, v in fixed.items()} | {loop: float(p)}
        dly = {n: v[1] for n, v in fixed.items()}
        values.append(largest_delay(model, loop, per, dly, resolution))
    return Curve(
        loop, dict(fixed), tuple(float(p) for p in periods), tuple(values), label or _label(fixed)
    )


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _phase_note(model: LoopModel) -> str:
    cfg = model.config
    if cfg.phase == "worst":
        return f"worst case over {cfg.phases} step phases"
    return "fixed step times (the paper's)"


def plot_curves(
    model: LoopModel,
    curves: Sequence[Curve],
    path: Path,
    *,
    title: str,
    hline: float | None = None,
    points: Sequence[tuple[str, float, float]] = (),
) -> Path:
    """Draw ``curves`` (delay against period) into ``path``; optionally a delay line and
    labelled points ``(name, period, delay)``."""
    plt = _pyplot()
    loop = curves[0].loop
    s = SYMBOL.get(loop, loop)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for c, marker in zip(curves, "osd^v<>", strict=False):
        ax.plot(c.periods, c.delays, marker=marker, label=_tex(c.label))
    if hline is not None:
        ax.axhline(hline, color="k", ls="--", lw=0.8, label=f"$\\tau_{{d{s}}}$ = {hline:g}")
    for name, p, d in points:
        ax.plot([p], [d], "k*", ms=10)
        ax.annotate(name, (p, d), textcoords="offset points", xytext=(6, 6))
    ax.set_xlabel(f"$\\tau_{{s{s}}}$ ({loop} sampling period), pu")
    ax.set_ylabel(f"$\\tau_{{d{s}-max}}$ ({loop} delay), pu")
    limit = model.config.overshoot_limit
    ax.set_title(f"{title}\nOS <= {limit:g} %, {_phase_note(model)}", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def fig9(
    model: LoopModel,
    loop: str,
    path: Path,
    *,
    periods: Sequence[float] = PERIODS,
    operating_points: Sequence[tuple[float, float]] = OPERATING_POINTS,
    resolution: float | None = None,
) -> list[Curve]:
    """Seed 000, Fig. 9 (``loop="level"``) or its reversed study (``"temperature"``): the curves
    and their plot in ``path``."""
    curves = delay_curves(model, loop, periods, operating_points, resolution)
    other = _others(model, loop)[0]
    same = len({c.delays for c in curves}) == 1 and len(curves) > 1
    plot_curves(
        model,
        curves,
        path,
        title=f"Largest {loop} delay vs {loop} sampling period; {other} loop fixed"
        + (f" (the curves coincide: {loop} does not depend on {other})" if same else ""),
    )
    return curves


def search_points(assignment: Assignment) -> list[SearchPoint]:
    """The result of each single-loop search in the trace, named A, B, C, ... (Fig. 11-12): the
    last acceptable trial of the search (the period the search returned)."""
    groups: list[list[Trial]] = []
    for t in assignment.trace:
        if t.loop is None:
            continue
        if groups and (groups[-1][0].alternation, groups[-1][0].loop) == (t.alternation, t.loop):
            groups[-1].append(t)
        else:
            groups.append([t])
    points = []
    for group in groups:
        ok = [t for t in group if t.ok]
        if not ok:
            break  # the search failed; the method stops
        t = ok[-1]
        if t.loop is None or t.period is None:  # searched trials always have both
            continue
        name = chr(ord("A") + len(points))
        points.append(
            SearchPoint(
                name, t.alternation, t.loop, t.period, t.overshoot_pct[t.loop], dict(t.periods)
            )
        )
    return points


def fig_points(
    model: LoopModel,
    assignment: Assignment,
    loop: str,
    path: Path,
    *,
    periods: Sequence[float] = PERIODS,
    resolution: float | None = None,
) -> list[tuple[SearchPoint, Curve]]:
    """Seed 000, Fig. 11 (temperature) / Fig. 12 (level): for each search point of ``loop``, the
    curve of its largest delay against its period under the conditions the point was searched
    in (the other loops at their periods then, i.e. the previous point's, and at their delays:
    the paper's "point A conditions" curve carries point B), the loop's delay line, and the
    point, which lies near where the curve crosses the line."""
    out = []
    previous = "benchmark"
    for pt in search_points(assignment):
        if pt.loop == loop:
            fixed = {
                n: (pt.periods[n], assignment.delays.get(n, 0.0)) for n in _others(model, loop)
            }
            label = f"{previous} conditions ({_label(fixed)})"
            out.append((pt, _curve(model, loop, periods, fixed, resolution, label)))
        previous = f"point {pt.name}"
    if out:
        delay = assignment.delays.get(loop, 0.0)
        plot_curves(
            model,
            [c for _, c in out],
            path,
            title=f"Largest {loop} delay vs {loop} sampling period at the worked example's points",
            hline=delay,
            points=[(pt.name, pt.period, delay) for pt, _ in out],
        )
    return out


def curves_markdown(curves: Sequence[Curve]) -> str:
    """The curves as a markdown table: one row per period, one column per curve (pu)."""
    s = SYMBOL.get(curves[0].loop, curves[0].loop)
    head = f"| tau_s{s} | " + " | ".join(c.label for c in curves) + " |"
    lines = [head, "|---" * (len(curves) + 1) + "|"]
    for i, p in enumerate(curves[0].periods):
        cells = ["none" if math.isnan(c.delays[i]) else f"{c.delays[i]:.3f}" for c in curves]
        lines.append(f"| {p:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def example_markdown(assignment: Assignment, model: LoopModel) -> str:
    """The worked example beside the paper's: search points, final periods and overshoots, and
    every trial of the trace."""
    points = search_points(assignment)
    lines = ["| step | paper | ours |", "|---|---|---|"]
    for i, (name, loop, paper_p) in enumerate(PAPER_EXAMPLE["points"]):
        s = SYMBOL.get(loop, loop)
        ours = "-"
        if i < len(points):
            pt = points[i]
            ours = f"{pt.loop} {pt.period:g} pu ({pt.overshoot_pct:.1f} %)"
        elif i == len(points) and assignment.converged:
            ours = "- (stopped: every loop searched and all within the limit)"
        lines.append(f"| point {name}: tau_s{s} | {paper_p:g} pu | {ours} |")
        if name == "B" and len(points) > 1:
            joint = model.evaluate(points[1].periods, assignment.delays).overshoot_pct
            lines.append(
                f"| temperature OS at point B | {PAPER_EXAMPLE['temperature_os_at_B']:g} % | "
                f"{joint['temperature']:.1f} % |"
            )
    for loop in model.loops:
        lines.append(
            f"| final tau_s{SYMBOL.get(loop, loop)} | {PAPER_EXAMPLE['final_periods'][loop]:g} pu "
            f"| {assignment.periods[loop]:g} pu |"
        )
    for loop in model.loops:
        lines.append(
            f"| final OS {loop} | {PAPER_EXAMPLE['final_overshoot_pct'][loop]:g} % "
            f"| {assignment.overshoot_pct[loop]:.1f} % |"
        )
    lines.append(
        f"| searches / trials / simulations | 4 / - / - | {len(points)} / "
        f"{sum(t.loop is not None for t in assignment.trace)} / {assignment.simulations} |"
    )
    lines += ["", "| trial | alternation | loop | step | period, pu | OS level | OS temperature "
              "| ok |", "|---" * 8 + "|"]  # fmt: skip
    n = 0
    for t in assignment.trace:
        n += t.loop is not None
        idx = str(n) if t.loop is not None else "-"
        os_cells = " | ".join(f"{t.overshoot_pct[lp]:.1f}" for lp in ("level", "temperature"))
        period = "-" if t.period is None else f"{t.period:g}"
        lines.append(
            f"| {idx} | {t.alternation} | {t.loop or 'all'} | {t.step} | {period} | {os_cells} "
            f"| {'yes' if t.ok else 'no'} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", type=Path, default=DEFAULT_SCENARIO)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="directory for the PNGs")
    parser.add_argument(
        "--phase",
        choices=("worst", "fixed"),
        default=None,
        help="overshoot of a trial: worst over step phases or at the test's step times "
        "(default: the agent's configuration)",
    )
    parser.add_argument(
        "--resolution", type=float, default=None, help="delay grid, pu (default: the agent's)"
    )
    parser.add_argument("--periods", type=float, nargs="+", default=list(PERIODS))
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    model = agent_model(args.scenario, phase=args.phase)
    if set(model.loops) != set(EXAMPLE_DELAYS):
        parser.error(f"{args.scenario}: expected loops {sorted(EXAMPLE_DELAYS)}, got {model.loops}")
    print(
        f"# WNCSCA figures: {args.scenario.name}, overshoot limit "
        f"{model.config.overshoot_limit:g} %, {_phase_note(model)}\n"
    )
    for loop, fig in (("level", "Fig. 9"), ("temperature", "Fig. 9 reversed")):
        t = time.perf_counter()
        curves = fig9(
            model,
            loop,
            args.out / f"fig9_{loop}.png",
            periods=args.periods,
            resolution=args.resolution,
        )
        print(f"## {fig}: largest {loop} delay (pu) ({time.perf_counter() - t:.1f} s)\n")
        print(curves_markdown(curves) + "\n")

    t = time.perf_counter()
    assignment = successive_approximation(model, EXAMPLE_DELAYS)
    fig10(assignment, args.out / "fig10.png", limit=model.config.overshoot_limit)
    print(
        f"## Worked example (III.E): delays level 0.17, temperature 0.10 pu "
        f"({time.perf_counter() - t:.1f} s)\n"
    )
    print(example_markdown(assignment, model) + "\n")
    for loop, name in (("temperature", "fig11"), ("level", "fig12")):
        t = time.perf_counter()
        pairs = fig_points(
            model,
            assignment,
            loop,
            args.out / f"{name}_{loop}.png",
            periods=args.periods,
            resolution=args.resolution,
        )
        if pairs:
            print(
                f"## {name}: {loop} curves at the search points ({time.perf_counter() - t:.1f} s)\n"
            )
            print(curves_markdown([c for _, c in pairs]) + "\n")
    print(f"PNGs in {args.out}; {model.simulations} simulations, {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
