"""Maximum update period of seed 001's loop as the platform runs it, against the sampling period.

For each sampling period ``tau_s`` of the temperatures, prints the sampled-data ``h_max``
(:mod:`agents.update_period.sampled`: largest multiple of ``tau_s`` with every shorter multiple
stabilizing, and the interpolated crossing) with embedded models and with the zero-order hold,
beside the continuous test's (seed 001 eq. (8), :func:`agents.update_period.analysis.find_h_max`),
and ``rho`` at ``h = 0.9 h_max`` (continuous) rounded to the grid. Then, at the bus scenario's
``tau_s``, ``h_max`` against a link delay of ``D`` sample periods. Markdown tables.

    .venv/bin/python bench/update_period_sampled.py [--tau-s 0.0001 0.00025 ...]
"""

from __future__ import annotations

import argparse
import time

from agents.update_period.analysis import CSTRRecycleCase, UpdatePeriodConfig, find_h_max
from agents.update_period.sampled import SampledQDC, find_h_max_sampled, h_max_vs_tau_s
from controllers.qdc.network import QDCNetwork

TAU_S = (0.0001, 0.00025, 0.0005, 0.001, 0.002)
DELAYS = (0, 2, 4, 8, 12)
SCHEMES = {"model": "qdc", "zoh": "qdc_zoh"}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tau-s", type=float, nargs="+", default=TAU_S, help="hours")
    parser.add_argument("--delay-tau-s", type=float, default=0.0005, help="hours")
    args = parser.parse_args(argv)
    wall0 = time.perf_counter()
    case = CSTRRecycleCase()
    nets = {s: QDCNetwork(case.plant, case.gains, scheme=s) for s in SCHEMES}
    h_c = {
        s: find_h_max(case.system(a), UpdatePeriodConfig(h_hi=0.1)).h_max
        for s, a in SCHEMES.items()
    }
    rows = {s: h_max_vs_tau_s(case.plant, nets[s], args.tau_s, h_hi=0.08) for s in SCHEMES}
    print("Seed 001, two CSTRs: sampled-data h_max (hours) against the sampling period tau_s")
    print(f"continuous test: models {h_c['model']:.5f}, zero-order hold {h_c['zoh']:.5f}")
    print()
    print(
        "| tau_s (h) | h_max models (crossing) | h_max hold (crossing) "
        "| rho at 0.9 h_max, models (N) | rho at 0.9 h_max, hold (N) |"
    )
    print("|---:|---:|---:|---:|---:|")
    for k, tau_s in enumerate(args.tau_s):
        cells = [f"{tau_s:g}"]
        for s in SCHEMES:
            r = rows[s][k]
            cells.append(f"{r.h_max:.5f} ({r.crossings[0]:.5f})" if r.bounded else "none")
        for s in SCHEMES:
            n = max(1, round(0.9 * h_c[s] / tau_s))
            rho = SampledQDC.from_law_parts(case.plant, nets[s], tau_s).spectral_radius(n)
            cells.append(f"{rho:.4f} ({n})")
        print("| " + " | ".join(cells) + " |")
    print(f"| continuous | {h_c['model']:.5f} | {h_c['zoh']:.5f} | | |")
    print()
    tau_s = args.delay_tau_s
    print(f"h_max against the link delay D tau_s, tau_s = {tau_s:g} h (models / hold)")
    print()
    print("| D | delay (h) | h_max models | h_max hold |")
    print("|---:|---:|---:|---:|")
    systems = {s: SampledQDC.from_law_parts(case.plant, nets[s], tau_s) for s in SCHEMES}
    for d in DELAYS:
        res = [find_h_max_sampled(systems[s], n_delay=d, h_hi=0.08) for s in SCHEMES]
        cells = [f"{r.h_max:.5f}" + ("" if r.n_max else " (N = 1 unstable)") for r in res]
        print(f"| {d} | {d * tau_s:g} | " + " | ".join(cells) + " |")
    print()
    print(f"wall {time.perf_counter() - wall0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
