"""Bench: the monitor on oscillating loops and bad data (issue 16, items 1-2).

Prints, for synthetic limit cycles (sine and stiction-like triangle of period 15 samples, unit
amplitude, white noise 0.2) at N = 751 and 5000 over 10 seeds: the oscillation verdict, the
period, the Harris index against its closed form ``sigma^2 / (var(wave) + sigma^2)`` (the cycle
is predictable d samples ahead, the noise is not); then how random walks and linear drifts are
refused (40 seeds each, counts by kind), and the bad-data cases of the issue (a frozen PV, a
spike, offline rows, a PV far from SP) with and without screening.

    .venv/bin/python bench/monitor_oscillation.py
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from scipy.signal import lfilter  # noqa: TID253 - not a node: imports what it uses at the top

from agents.monitor.assess import assess
from agents.monitor.config import MonitorConfig, ScreeningConfig
from agents.monitor.errors import IdentificationError, QualityError
from agents.monitor.harris import harris_index
from agents.monitor.oscillation import detect_oscillation

PERIOD, NOISE, DELAY = 15, 0.2, 3


def limit_cycles() -> None:
    print("== limit cycles: period 15, amplitude 1, noise 0.2, d = 3 (10 seeds)")
    print(f"{'wave':<9}{'N':>6}{'flagged':>9}{'period':>14}{'index':>16}{'closed':>8}")
    for kind, var in (("sine", 0.5), ("triangle", 1 / 3)):
        for n in (751, 5000):
            t = np.arange(n)
            wave = (
                np.sin(2 * np.pi * t / PERIOD)
                if kind == "sine"
                else 2 / np.pi * np.arcsin(np.sin(2 * np.pi * t / PERIOD))
            )
            flags, periods, idx = 0, [], []
            for seed in range(10):
                y = wave + NOISE * np.random.default_rng(seed).standard_normal(n)
                osc = detect_oscillation(y)
                flags += osc.oscillating
                periods.append(osc.period)
                idx.append(harris_index(y, DELAY).index)
            print(
                f"{kind:<9}{n:>6}{flags:>6}/10{min(periods):>7.2f}-{max(periods):<6.2f}"
                f"{min(idx):>8.3f}-{max(idx):<7.3f}{NOISE**2 / (var + NOISE**2):>8.3f}"
            )


def refusals() -> None:
    print("== non-stationary records refused, by kind (40 seeds)")
    for n in (751, 5000):
        for name in ("random walk", "drift + AR(1) 0.5"):
            kinds: Counter[str] = Counter()
            for seed in range(40):
                e = np.random.default_rng(seed).standard_normal(n)
                y = (
                    np.cumsum(e)
                    if name == "random walk"
                    else 0.01 * np.arange(n) + lfilter([1.0], [1.0, -0.5], e)
                )
                try:
                    harris_index(y, DELAY)
                    kinds["assessed"] += 1
                except IdentificationError as exc:
                    kinds[str(exc.kind)] += 1
            print(f"  N = {n:>5} {name:<18} {dict(kinds)}")


def bad_data() -> None:
    print("== bad data (AR(1) PV, pole 0.9, 1.22 +- 0.004; closed-form index 0.469 at d = 3)")
    rng = np.random.default_rng(2)
    pv = 1.22 + 0.004 * lfilter([1.0], [1.0, -0.9], rng.standard_normal(951))[200:]
    warn = MonitorConfig(screening=ScreeningConfig(spike="warn", frozen="warn"))
    spiky = pv.copy()
    spiky[400] = 1000.0
    for label, cfg in (("spike, screening off (warn)", warn), ("spike, default", None)):
        r = assess({"PV": spiky}, "PV", DELAY, config=cfg)
        print(f"  {label:<34} index {r.harris.index:.3f}  flags {r.screening.flags}")
    frozen = pv.copy()
    frozen[150:] = frozen[150]
    r = assess({"PV": frozen}, "PV", DELAY, config=warn)
    print(f"  {'frozen 80 %, warn':<34} index {r.harris.index:.3f}  flags {r.screening.flags}")
    try:
        assess({"PV": frozen}, "PV", DELAY)
    except QualityError as err:
        print(f"  {'frozen 80 %, default':<34} refused: {err}")
    low = 0.01 + pv - pv.mean()
    r = assess({"PV": low, "SP": np.full(low.size, 2.5)}, "PV", DELAY, setpoint="SP")
    print(f"  {'PV 0.01 against SP 2.5':<34} {r.screening.findings[0].text}")


if __name__ == "__main__":
    limit_cycles()
    refusals()
    bad_data()
