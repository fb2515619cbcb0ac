"""Seed 000, section III.C (and the III.E example): how far each JCSTR loop's sampling period and
sensor-path delay can grow before the set-point step overshoots by more than 25 %.

Runs the scenario (default ``scenarios/jcstr_benchmark.yaml``) on the ``direct`` engine, varying
one loop at a time with the other at its benchmark values, exactly as section III.C does, and
prints a markdown table beside the paper's numbers::

    python bench/section3c.py [SCENARIO]

"Largest ``tau_s`` (``tau_d``) with overshoot <= 25 %" is the last value of a fine grid (0.005 pu
for ``tau_s`` from the benchmark 0.1 pu, 0.001 pu for ``tau_d`` from 0) before the first grid
value that violates the limit. The overshoot is not monotone in ``tau_s`` or ``tau_d`` (the phase
of the set-point step relative to the sampling instants matters), so the scan goes on past the
first violation and reports grid values where the overshoot is back within the limit.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from core.record import loop_metrics
from runtime.direct import simulate
from scenario import Scenario, load_scenario

__all__ = [
    "OS_LIMIT",
    "Scan",
    "overshoot",
    "settling_time",
    "largest_tau_s",
    "largest_tau_d",
    "rows",
    "markdown",
    "main",
]

OS_LIMIT = 25.0
"""Largest acceptable overshoot, % (seed 000, section III.C)."""

DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"


def _variant(
    scenario: Scenario,
    tau_s: Mapping[str, float] | None = None,
    tau_d: Mapping[str, float] | None = None,
) -> Scenario:
    if not tau_s and not tau_d:
        return scenario
    return scenario.with_loops(tau_s=tau_s, tau_d=tau_d)


def overshoot(
    scenario: Scenario,
    loop: str,
    *,
    tau_s: Mapping[str, float] | None = None,
    tau_d: Mapping[str, float] | None = None,
) -> float:
    """Overshoot (%) of ``loop``'s set-point step(s), with some loops' ``tau_s``/``tau_d`` replaced.

    A run that diverges numerically counts as an infinite overshoot.
    """
    rec = simulate(_variant(scenario, tau_s, tau_d))
    value = loop_metrics(rec, loop)["overshoot_pct"]
    if value is None or not math.isfinite(value):
        return math.inf
    return float(value)


def settling_time(
    scenario: Scenario,
    loop: str,
    *,
    tau_s: Mapping[str, float] | None = None,
    tau_d: Mapping[str, float] | None = None,
) -> float | None:
    """2 % settling time of ``loop``'s step(s), ``None`` if it does not settle within the run."""
    return loop_metrics(simulate(_variant(scenario, tau_s, tau_d)), loop)["settling_time"]


@dataclass
class Scan:
    """Result of a scan of one loop's ``tau_s`` or ``tau_d`` against the overshoot limit."""

    loop: str
    quantity: str  # "tau_s" or "tau_d"
    largest: float | None  # last grid value before the first violation (None: first one violates)
    os_at_largest: float | None
    first_violation: float | None  # None: no violation within the scanned range
    os_at_violation: float | None
    back_within: list[float] = field(default_factory=list)  # grid values past the first violation
    # where the overshoot is within the limit again (non-monotone overshoot)


def _scan(
    scenario: Scenario,
    loop: str,
    quantity: str,
    *,
    start: float,
    step: float,
    stop: float,
    limit: float,
    lookahead: float,
) -> Scan:
    n = int(round((stop - start) / step))
    res = Scan(loop, quantity, None, None, None, None)
    end_i = n
    for i in range(n + 1):
        if i > end_i:
            break
        value = round(start + i * step, 9)
        os_pct = overshoot(scenario, loop, **{quantity: {loop: value}})
        if res.first_violation is None:
            if os_pct <= limit:
                res.largest, res.os_at_largest = value, os_pct
            else:
                res.first_violation, res.os_at_violation = value, os_pct
                end_i = min(n, i + int(round(lookahead / step)))
        elif os_pct <= limit:
            res.back_within.append(value)
    return res


def largest_tau_s(
    scenario: Scenario,
    loop: str,
    *,
    limit: float = OS_LIMIT,
    step: float = 0.005,
    start: float | None = None,
    stop: float = 1.0,
    lookahead: float = 0.1,
) -> Scan:
    """Largest sampling period of ``loop`` with overshoot <= ``limit`` (seed 000, section III.C).

    Scans ``tau_s`` from ``start`` (default: the scenario's value) in steps of ``step`` up to the
    first violation, then ``lookahead`` further to detect non-monotone overshoot.
    """
    if start is None:
        start = scenario.loops[loop].tau_s
    return _scan(
        scenario,
        loop,
        "tau_s",
        start=start,
        step=step,
        stop=stop,
        limit=limit,
        lookahead=lookahead,
    )


def largest_tau_d(
    scenario: Scenario,
    loop: str,
    *,
    limit: float = OS_LIMIT,
    step: float = 0.001,
    start: float = 0.0,
    stop: float = 1.0,
    lookahead: float = 0.05,
) -> Scan:
    """Largest sensor-path delay of ``loop`` with overshoot <= ``limit`` (seed 000, section III.C).

    Scans ``tau_d`` at the scenario's sampling periods from ``start`` in steps of ``step`` up to the
    first violation, then ``lookahead`` further to detect non-monotone overshoot.
    """
    return _scan(
        scenario,
        loop,
        "tau_d",
        start=start,
        step=step,
        stop=stop,
        limit=limit,
        lookahead=lookahead,
    )


def _fmt(v: float | None, digits: int = 1) -> str:
    if v is None:
        return "n/a"
    if math.isinf(v):
        return "diverges"
    return f"{v:.{digits}f}"


def _pu(v: float | None) -> str:
    return "none" if v is None else f"{v:g} pu"


def rows(scenario: Scenario) -> tuple[list[tuple[str, str, str, str]], list[str]]:
    """The section III.C/III.E table: ``(quantity, paper, ours, overshoot at ours)`` and notes."""
    L, T = "level", "temperature"
    out: list[tuple[str, str, str, str]] = []
    notes: list[str] = []

    def os_row(quantity: str, paper: str, loop: str, **kw: Mapping[str, float]) -> None:
        out.append((quantity, paper, _fmt(overshoot(scenario, loop, **kw)) + " %", "-"))

    def scan_row(quantity: str, paper: str, scan: Scan) -> None:
        os_txt = "-" if scan.os_at_largest is None else _fmt(scan.os_at_largest) + " %"
        out.append((quantity, paper, _pu(scan.largest), os_txt))
        what = f"{scan.loop} {scan.quantity}"
        if scan.first_violation is None:
            notes.append(f"{what}: no violation up to the end of the scanned range")
        else:
            notes.append(
                f"{what}: first violation at {scan.first_violation:g} pu "
                f"({_fmt(scan.os_at_violation)} %)"
                + (
                    f"; non-monotone: within {OS_LIMIT:g} % again at "
                    + ", ".join(f"{v:g}" for v in scan.back_within[:6])
                    + (" ..." if len(scan.back_within) > 6 else "")
                    + " pu"
                    if scan.back_within
                    else ""
                )
            )

    st_l = settling_time(scenario, L)
    st_t = settling_time(scenario, T)
    out.append(("benchmark OS, level", "10.8 %", _fmt(overshoot(scenario, L), 2) + " %", "-"))
    out.append(("benchmark OS, temperature", "11.0 %", _fmt(overshoot(scenario, T), 2) + " %", "-"))
    notes.append(
        "benchmark 2 % settling times after the steps: "
        + ", ".join(
            f"{name} " + ("does not settle" if st is None else f"{st:.2f} pu")
            for name, st in ((L, st_l), (T, st_t))
        )
        + f" (end_time {scenario.end_time:g} pu)"
    )
    scan_row("largest tau_s, level (OS <= 25 %)", "0.25 pu (24.9 %)", largest_tau_s(scenario, L))
    os_row("OS level at tau_s = 0.25", "24.9 %", L, tau_s={L: 0.25})
    scan_row(
        "largest tau_s, temperature (OS <= 25 %)", "0.3 pu (28.5 %)", largest_tau_s(scenario, T)
    )
    os_row("OS temperature at tau_s = 0.3", "28.5 %", T, tau_s={T: 0.3})
    scan_row(
        "largest tau_d, level (tau_s = 0.1, OS <= 25 %)",
        "0.253 pu (25 %)",
        largest_tau_d(scenario, L),
    )
    os_row("OS level at tau_d = 0.253", "25 %", L, tau_d={L: 0.253})
    scan_row(
        "largest tau_d, temperature (tau_s = 0.1, OS <= 25 %)",
        "0.1 pu (text) / 0.186 pu (Fig. 8)",
        largest_tau_d(scenario, T),
    )
    os_row("OS temperature at tau_d = 0.1", "slightly > 25 %", T, tau_d={T: 0.1})
    os_row("OS temperature at tau_d = 0.186", "28.9 %", T, tau_d={T: 0.186})
    # Section III.E, points A, B and D (the other loop's values as stated there).
    os_row(
        "III.E point A: OS temperature (tau_sT 0.185, tau_dT 0.1; level benchmark)",
        "25 %",
        T,
        tau_s={T: 0.185},
        tau_d={T: 0.1},
    )
    point_b = dict(tau_s={L: 0.11, T: 0.185}, tau_d={L: 0.17, T: 0.1})
    os_row(
        "III.E point B: OS temperature (tau_sL 0.11, tau_dL 0.17, tau_sT 0.185, tau_dT 0.1)",
        "27.2 %",
        T,
        **point_b,
    )
    point_d = dict(tau_s={L: 0.071, T: 0.16}, tau_d={L: 0.17, T: 0.1})
    os_row(
        "III.E point D: OS level (tau_sL 0.071, tau_dL 0.17, tau_sT 0.16, tau_dT 0.1)",
        "24.3 %",
        L,
        **point_d,
    )
    os_row("III.E point D: OS temperature (same point)", "25 %", T, **point_d)
    return out, notes


def markdown(table: list[tuple[str, str, str, str]]) -> str:
    """The rows as a markdown table."""
    head = ("quantity", "paper", "ours", "OS at ours")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in table]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Print the section III.C table of a scenario (default: the JCSTR benchmark)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(DEFAULT_SCENARIO))
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    t0 = time.perf_counter()
    table, notes = rows(scenario)
    print(f"Seed 000, section III.C / III.E on {args.scenario} (direct engine)\n")
    print(markdown(table))
    print()
    for note in notes:
        print(f"- {note}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
