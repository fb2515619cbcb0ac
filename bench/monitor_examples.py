"""Seed 004 cascade-opportunity monitor on Examples 1-3: prediction against the implemented cascade.

For each example process of :mod:`plants.cascade.examples` (ours, in the spirit of the paper's
Examples 1-3, 5 % measurement noise):

1. simulate routine operation under the simple-feedback PI
   (:data:`controllers.cascade.tuning.EXAMPLE_SFB`);
2. run the monitor on the measured data and the delays alone (:func:`agents.monitor.assess.assess`):
   Harris index +- standard error, the four components 1a/1b/2a/2b per candidate secondary, the
   predicted cascade variance band ``[1a + 2a/2, 1a + 2a]`` and the ranking;
3. switch the same process, with the same noise sequences, to the PI-P cascade on each candidate
   (:data:`controllers.cascade.tuning.EXAMPLE_CASCADE`) and measure the variance of ``y1``;
4. print two exact references beside the estimates: ``population``, the decomposition of the
   VAR(80) fitted by Yule-Walker to the exact autocovariances of the measured ``(y1, y2)`` (what
   the estimator converges to with unlimited data), and ``per source``, eq. (7)/(8) and
   (11)-(15) applied to each noise source's exact closed-loop response with the sources at or
   upstream of the secondary as ``a2``. They coincide for the paper's two-stage structure
   without measurement noise; with a third source the candidate does not see (Example 3, ``y3``:
   ``a2`` enters between ``y3`` and ``y1``), the per-source 1a assumes that source is known where
   it enters and is lower than any controller using ``(y1, y3)`` can achieve.

    .venv/bin/python bench/monitor_examples.py [--n 20000] [--seed 1] [--boot 0] [--json FILE]
    .venv/bin/python bench/monitor_examples.py --retune      # recompute the example settings

``net removed`` is the fraction of 2a the implemented cascade removed net of what it leaves of
1b and 2b: ``(1a + 2a - var_cascade) / 2a``; the band assumes it lies in [0, 0.5].
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from agents.monitor.assess import MonitorConfig, SecondarySpec, assess
from agents.monitor.decomposition import decomposition_from_model
from agents.monitor.timeseries import var_from_autocovariance
from controllers.cascade.model import SFBPI, PIPCascade
from controllers.cascade.tuning import EXAMPLE_CASCADE, EXAMPLE_SFB, tune_pi_p, tune_sfb_pi
from plants.cascade.examples import EXAMPLES
from plants.cascade.model import delays
from plants.cascade.routine import simulate
from plants.cascade.variance import (
    autocovariance,
    output_variance,
    true_components,
    with_measurement_noise,
)

POP_ORDER = 80
"""VAR order of the population reference (Yule-Walker on the exact autocovariances)."""


def run_example(name: str, n: int, seed: int, boot: int) -> dict[str, Any]:
    """Monitor prediction and implemented cascades for one example."""
    proc = EXAMPLES[name]
    sfb = EXAMPLE_SFB[name]
    run = simulate(proc, SFBPI(sfb), n, np.random.default_rng(seed))
    secs = [n_ for n_ in proc.names[:-1]]
    specs = [SecondarySpec(name=s, d1=delays(proc, s)[0], d2=delays(proc, s)[1]) for s in secs]
    d = specs[0].d1 + specs[0].d2
    cfg = MonitorConfig(decomposition_boot=boot, seed=seed)
    t0 = time.perf_counter()
    res = assess(run.measured, proc.primary, d, specs, config=cfg)
    t_assess = time.perf_counter() - t0
    out: dict[str, Any] = {
        "example": name,
        "description": proc.description,
        "n": n,
        "seed": seed,
        "delay": d,
        "sfb": sfb.model_dump(),
        "var_sfb": run.variance(proc.primary),
        "var_sfb_analytic": output_variance(proc, sfb.feedback()),
        "assessment": res.to_dict(),
        "assess_seconds": t_assess,
        "cascades": {},
    }
    for s in secs:
        cas = EXAMPLE_CASCADE[name][s]
        crun = simulate(proc, PIPCascade(cas), n, np.random.default_rng(seed))
        tc = true_components(proc, sfb.feedback(), s)
        gam = autocovariance(proc, sfb.feedback(), [proc.primary, s], POP_ORDER)
        pop = decomposition_from_model(var_from_autocovariance(gam, POP_ORDER), *delays(proc, s))
        under = true_components(proc, cas.feedback(), s)
        out["cascades"][s] = {
            "pi_p": cas.model_dump(),
            "var": crun.variance(proc.primary),
            "var_analytic": output_variance(proc, cas.feedback()),
            "true_components": {"1a": tc.c1a, "1b": tc.c1b, "2a": tc.c2a, "2b": tc.c2b},
            "population_components": pop.components.to_dict(),
            "components_under_cascade": {
                "1a": under.c1a,
                "1b": under.c1b,
                "2a": under.c2a,
                "2b": under.c2b,
            },
        }
    actual = sorted(secs, key=lambda s: out["cascades"][s]["var"])
    out["actual_ranking"] = actual
    return out


def _f(x: float | None, w: int = 8) -> str:
    return f"{'-':>{w}s}" if x is None else f"{x:{w}.4f}"


def print_example(r: dict[str, Any]) -> list[list[str]]:
    a = r["assessment"]
    h = a["harris"]
    print(f"== {r['example']}: {r['description']}")
    s = r["sfb"]
    print(
        f"   SFB PI Kc={s['Kc']:g} Ti={s['Ti']:g}; N={r['n']} seed={r['seed']}; d={r['delay']}; "
        f"var(y1) {r['var_sfb']:.4f} (analytic {r['var_sfb_analytic']:.4f}); "
        f"monitor {r['assess_seconds']:.2f} s"
    )
    if h["status"] == "ok":
        print(
            f"   Harris index {h['index']:.3f} +- {h['std']:.3f} (95 % CI {h['ci'][0]:.3f}-"
            f"{h['ci'][1]:.3f}, AR({h['order']}), sigma2_mv {h['sigma2_mv']:.4f})"
        )
    else:
        print(f"   Harris index: {h['status']} ({h['reason']}: {h['detail']})")
    rows = []
    for c in a["candidates"]:
        nm = c["name"]
        cas = r["cascades"][nm]
        print(f"   secondary {nm} (d1={c['d1']}, d2={c['d2']}):")
        if c["status"] != "ok":
            print(f"      unidentifiable: {c['reason']}: {c['detail']}")
            continue
        est, tru, pop = c["components"], cas["true_components"], cas["population_components"]
        print(f"      {'':12s}{'1a':>8s}{'1b':>8s}{'2a':>8s}{'2b':>8s}{'sum':>8s}{'var':>8s}")
        print(
            f"      {'estimated':12s}"
            + "".join(_f(est[k]) for k in ("1a", "1b", "2a", "2b"))
            + _f(sum(est.values()))
            + _f(c["variance"])
        )
        if c["std"]:
            print(
                f"      {'+- (boot)':12s}"
                + "".join(_f(c["std"][k]) for k in ("1a", "1b", "2a", "2b"))
            )
        print(
            f"      {'population':12s}"
            + "".join(_f(pop[k]) for k in ("1a", "1b", "2a", "2b"))
            + _f(sum(pop.values()))
            + _f(r["var_sfb_analytic"])
        )
        print(
            f"      {'per source':12s}"
            + "".join(_f(tru[k]) for k in ("1a", "1b", "2a", "2b"))
            + _f(sum(tru.values()))
            + _f(r["var_sfb_analytic"])
        )
        pr = c["prediction"]
        lo, hi = pr["band"]
        v, va = cas["var"], cas["var_analytic"]
        inside = lo <= v <= hi
        removed = (est["1a"] + est["2a"] - v) / est["2a"] if est["2a"] > 0 else float("nan")
        p = cas["pi_p"]
        print(
            f"      predicted cascade variance: band [{lo:.4f}, {hi:.4f}], point {pr['point']:.4f}"
            f", minimum (1a) {pr['minimum']:.4f}"
        )
        print(
            f"      PI-P (Kc1={p['Kc1']:g}, Ti1={p['Ti1']:g}, Kc2={p['Kc2']:g}): var(y1) {v:.4f} "
            f"(analytic {va:.4f}) -> {'INSIDE' if inside else 'OUTSIDE'} the band; "
            f"net removed {removed:.2f} of 2a"
        )
        u = cas["components_under_cascade"]
        print(
            "      exact components under the cascade: "
            + ", ".join(f"{k} {u[k]:.4f}" for k in ("1a", "1b", "2a", "2b"))
        )
        rows.append(
            [
                r["example"],
                nm,
                f"{h['index']:.3f}+-{h['std']:.3f}" if h["status"] == "ok" else "-",
                *(f"{est[k]:.4f}" for k in ("1a", "1b", "2a", "2b")),
                f"{c['variance']:.4f}",
                f"[{lo:.4f}, {hi:.4f}]",
                f"{v:.4f}",
                "yes" if inside else "NO",
            ]
        )
    print(
        f"   ranking (monitor): {' > '.join(a['ranking']) or '-'}; by implemented cascade: "
        f"{' > '.join(r['actual_ranking'])}"
    )
    print(f"   {a['recommendation']['text']}")
    print()
    return rows


def retune() -> None:
    """Recompute the example settings (measurement noise, SFB PI, PI-P) from scratch."""
    for name, proc in EXAMPLES.items():
        clean = proc.model_copy(
            update={
                "stages": tuple(s.model_copy(update={"meas_noise_std": 0.0}) for s in proc.stages)
            }
        )
        sfb0, _ = tune_sfb_pi(clean)
        noisy = with_measurement_noise(clean, sfb0.feedback(), 0.05)
        print(
            name,
            "meas_noise_std:",
            {s.name: float(f"{s.meas_noise_std:.3g}") for s in noisy.stages},
        )
        sfb, v = tune_sfb_pi(noisy)
        print(f"  SFB PI Kc={sfb.Kc:.3g} Ti={sfb.Ti:.3g}  (variance {v:.4f})")
        for s in noisy.names[:-1]:
            cas, vc = tune_pi_p(noisy, s)
            print(
                f"  PI-P on {s}: Kc1={cas.Kc1:.3g} Ti1={cas.Ti1:.3g} Kc2={cas.Kc2:.3g}"
                f"  (variance {vc:.4f})"
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20000, help="samples per run")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--boot", type=int, default=0, help="bootstrap replicates, components")
    parser.add_argument(
        "--seeds", type=int, default=1, help="also repeat on this many seeds and count successes"
    )
    parser.add_argument("--json", help="write the results to this file")
    parser.add_argument("--retune", action="store_true", help="recompute the example settings")
    args = parser.parse_args(argv)
    if args.retune:
        retune()
        return 0
    results, rows = [], []
    for name in EXAMPLES:
        r = run_example(name, args.n, args.seed, args.boot)
        results.append(r)
        rows += print_example(r)
    head = ["example", "sec", "Harris", "1a", "1b", "2a", "2b", "var SFB", "band", "var CAS", "in"]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
    print("Summary (band = [1a + 2a/2, 1a + 2a] from the estimated components)")
    print("  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)))
    for row in rows:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)))
    if args.seeds > 1:
        robustness(args.n, range(args.seed, args.seed + args.seeds))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0


def robustness(n: int, seeds: range) -> None:
    """How often the band contains the implemented cascade's variance, and the ranking is right."""
    inside: dict[tuple[str, str], int] = {}
    ranked: dict[str, int] = {}
    removed: dict[tuple[str, str], list[float]] = {}
    for seed in seeds:
        for name in EXAMPLES:
            r = run_example(name, n, seed, 0)
            a = r["assessment"]
            ranked[name] = ranked.get(name, 0) + (a["ranking"] == r["actual_ranking"])
            for c in a["candidates"]:
                key = (name, c["name"])
                if c["status"] != "ok":
                    continue
                lo, hi = c["prediction"]["band"]
                v = r["cascades"][c["name"]]["var"]
                inside[key] = inside.get(key, 0) + (lo <= v <= hi)
                est = c["components"]
                removed.setdefault(key, []).append((est["1a"] + est["2a"] - v) / est["2a"])
    k = len(seeds)
    print(f"Robustness over seeds {seeds.start}-{seeds.stop - 1} (N={n}):")
    for key, cnt in inside.items():
        rem = np.array(removed[key])
        print(
            f"  {key[0]} {key[1]}: cascade variance inside the band in {cnt}/{k} runs; net removed "
            f"fraction of 2a {rem.mean():.2f} (min {rem.min():.2f}, max {rem.max():.2f})"
        )
    for name, cnt in ranked.items():
        print(f"  {name}: ranking equal to the implemented cascades' order in {cnt}/{k} runs")


if __name__ == "__main__":
    raise SystemExit(main())
