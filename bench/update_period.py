"""Maximum allowable update period of seed 001 (two CSTRs with recycle) beside the paper's values.

Prints ``h_max`` of the quasi-decentralized output-feedback loop with an exact model and with the
zero-order hold next to the paper's 0.043 h and 0.042 h, the other architectures, ``h_max``
against the model mismatch ``delta1``, and ``h_max`` under the other admissible controller pole
assignments (with two inputs per unit the gains are not fixed by the poles). Writes maps and
profiles in the style of seed 001 Fig. 2(a)-(d), 3(a)-(b) and 4(a)-(b) as PNGs.

    .venv/bin/python bench/update_period.py [--out runs/update_period] [--no-plots]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from agents.update_period.analysis import (
    PAPER_H_MAX,
    PAPER_H_MAX_ZOH,
    CSTRRecycleCase,
    UpdatePeriodConfig,
    rho_curves,
    rho_map,
    rho_map_observer_pole,
)
from controllers.qdc.model import simulate_linear
from controllers.qdc.network import QDCNetwork

ARCH_LABELS = {
    "qdc": "quasi-decentralized, output feedback, models",
    "qdc_zoh": "quasi-decentralized, output feedback, zero-order hold",
    "qdc_state": "quasi-decentralized, state feedback, models",
    "centralized": "centralized output feedback (observer from model, [24])",
    "centralized_plant_observer": "centralized output feedback (observer from true plant)",
}


def _fmt(h: float) -> str:
    return "   inf  " if np.isinf(h) else f"{h:8.5f}"


def print_tables(case: CSTRRecycleCase) -> None:
    cfg = UpdatePeriodConfig(h_hi=0.3, n_grid=600)
    print("Seed 001, two CSTRs with recycle: maximum allowable update period h_max (hours)")
    print(f"operating point x_s = {np.array2string(case.x_s, precision=6)}")
    print()
    print(f"{'architecture (delta1 = 0)':58s} {'h_max':>8s}  {'paper':>6s}  {'diff':>8s}")
    paper = {"qdc": PAPER_H_MAX, "qdc_zoh": PAPER_H_MAX_ZOH}
    for arch, label in ARCH_LABELS.items():
        r = case.h_max(arch, 0.0, cfg)
        ref = paper.get(arch)
        tail = f"  {ref:6.3f}  {r.h_max - ref:+8.5f}" if ref is not None else ""
        print(f"{label:58s} {_fmt(r.h_max)}{tail}")
    print("(centralized / state feedback with an exact model: no crossing up to 0.3 h)")
    print()
    deltas = (-0.5, -0.3, -0.2, -0.1, -0.05, 0.0, 0.05, 0.1, 0.2, 0.3, 0.5)
    print("h_max against the model mismatch delta1 = (dH1_m - dH1) / dH1")
    print(f"{'delta1':>7s} {'qdc':>8s} {'zoh':>8s} {'state':>8s} {'central':>8s} {'c.plant':>8s}")
    for d in deltas:
        row = [
            case.h_max(a, d, cfg).h_max
            for a in ("qdc", "qdc_zoh", "qdc_state", "centralized", "centralized_plant_observer")
        ]
        print(f"{d:7.2f} " + " ".join(_fmt(v) for v in row))
    print("(0.00000: unstable even under continuous communication)")
    print()
    print("Non-uniqueness of the gain design: Abar_i = diag(poles) with other assignments")
    print(f"{'Abar_1 (T1, CA1)':>18s} {'Abar_2 (T2, CA2)':>18s} {'h_max':>8s} {'zoh':>8s}")
    for p1, p2 in (
        ((-5.0, -1.0), (-5.0, -1.0)),
        ((-5.0, -1.0), (-1.0, -5.0)),
        ((-1.0, -5.0), (-5.0, -1.0)),
        ((-1.0, -5.0), (-1.0, -5.0)),
        ((-5.0, -5.0), (-1.0, -1.0)),
        ((-1.0, -1.0), (-5.0, -5.0)),
    ):
        alt = CSTRRecycleCase(controller_poles=(p1, p2))
        a = alt.h_max("qdc", 0.0, cfg).h_max
        z = alt.h_max("qdc_zoh", 0.0, cfg).h_max
        mark = "  <- default (scipy place_poles)" if (p1, p2) == ((-5.0, -1.0),) * 2 else ""
        print(f"{str(p1):>18s} {str(p2):>18s} {_fmt(a)} {_fmt(z)}{mark}")
    print()
    g = case.gains
    with np.printoptions(precision=6):
        for i in range(2):
            j = 1 - i
            print(
                f"K_{i + 1} =\n{g.K[i][i]}\nK_{i + 1}{j + 1} =\n{g.K[i][j]}\nL_{i + 1} =\n{g.L[i]}"
            )


def write_plots(case: CSTRRecycleCase, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    hs = np.linspace(0.001, 0.08, 80)
    ds = np.linspace(-0.5, 0.5, 81)
    # Fig. 2(a)-(c)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), sharey=True)
    for ax, arch, title in zip(
        axes,
        ("qdc", "qdc_state", "centralized"),
        ("(a) quasi-decentralized, output feedback", "(b) state feedback", "(c) centralized"),
        strict=True,
    ):
        rho = np.minimum(rho_map(case, hs, ds, arch), 3.0)
        cs = ax.contourf(hs, ds, rho, levels=np.linspace(0.0, 3.0, 31), cmap="viridis")
        ax.contour(hs, ds, rho, levels=[1.0], colors="r", linewidths=2)
        ax.set_title(title)
        ax.set_xlabel("update period h (hr)")
    axes[0].set_ylabel("delta1")
    fig.colorbar(cs, ax=axes, label="lambda_max = rho(M(h)) (clipped at 3), red: 1")
    fig.savefig(out / "fig2abc_rho_maps.png", dpi=110)
    plt.close(fig)
    # Fig. 2(d) and 3(b): linearized T1 profiles
    x0 = np.array([1.0, 0.0, -1.0, 0.0])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for ax, scheme, periods, title in (
        (axes[0], "model", (0.040, 0.043, 0.044), "(Fig. 2(d)) exact model"),
        (axes[1], "zoh", (0.040, 0.042, 0.044), "(Fig. 3(b)) zero-order hold"),
    ):
        net = QDCNetwork(case.plant, case.gains, scheme=scheme)
        for h in periods:
            run = simulate_linear(case.plant, net, h, x0, int(round(8.0 / h)))
            ax.plot(run.t, run.x[:, 0], label=f"h = {h:.3f} hr")
        ax.set_title(f"T1 deviation (linearized plant), {title}")
        ax.set_xlabel("t (hr)")
        ax.set_ylim(-5, 5)
        ax.legend()
    fig.savefig(out / "fig2d_3b_profiles.png", dpi=110)
    plt.close(fig)
    # Fig. 3(a)
    hs3 = np.linspace(0.001, 0.06, 120)
    curves = rho_curves(case, hs3, (0.0, 0.1, 0.2, 0.3, -0.1))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, vals in curves.items():
        ax.plot(hs3, vals, "k-" if label == "zoh" else "--", label=label)
    ax.axhline(1.0, color="r", lw=0.8)
    ax.set_ylim(0.8, 1.6)
    ax.set_xlabel("update period h (hr)")
    ax.set_ylabel("lambda_max")
    ax.set_title("(Fig. 3(a)) rho(M(h)) for several models and the zero-order hold")
    ax.legend()
    fig.savefig(out / "fig3a_rho_vs_h.png", dpi=110)
    plt.close(fig)
    # Fig. 4(a)-(b)
    lams = np.linspace(-60.0, -10.0, 51)
    ds4 = np.linspace(-0.1, 0.4, 51)
    rho4 = rho_map_observer_pole(case, lams, ds4, h=0.04)
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    cs = axes[0].contourf(lams, ds4, np.minimum(rho4, 2.0), levels=30, cmap="viridis")
    axes[0].contour(lams, ds4, rho4, levels=[1.0], colors="r", linewidths=2)
    axes[0].plot([-25.0, -20.8], [0.1, 0.1], "wo")
    axes[0].set_xlabel("lambda_12 (second pole of A_1 - L_1 C_1)")
    axes[0].set_ylabel("delta1")
    axes[0].set_title("(Fig. 4(a)) rho(M(0.04)), red: 1")
    fig.colorbar(cs, ax=axes[0])
    for d in (0.0, 0.1, 0.2, 0.3):
        axes[1].plot(lams, rho_map_observer_pole(case, lams, [d], h=0.04)[0], "--", label=f"{d}")
    zoh = rho_map_observer_pole(case, lams, [0.0], h=0.04, architecture="qdc_zoh")[0]
    axes[1].plot(lams, zoh, "k-", label="zoh")
    axes[1].axhline(1.0, color="r", lw=0.8)
    axes[1].set_xlabel("lambda_12")
    axes[1].set_ylabel("lambda_max")
    axes[1].set_title("(Fig. 4(b)) h = 0.04 hr")
    axes[1].legend(title="delta1")
    fig.savefig(out / "fig4ab_observer_pole.png", dpi=110)
    plt.close(fig)
    print(f"\nplots written to {out}/")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/update_period"))
    parser.add_argument("--no-plots", action="store_true")
    args = parser.parse_args()
    t0 = time.perf_counter()
    case = CSTRRecycleCase()
    print_tables(case)
    if not args.no_plots:
        write_plots(case, args.out)
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
