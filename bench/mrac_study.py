"""Seed 003 (MRAC of a distillation column): the column, its reduced model and the MRAC studies.

Prints, from loops of its own (no runtime):

1. the column's steady state against Table 3.2 for the printed model (3.3), the appendix flows
   and the fitted flows (:mod:`plants.column`);
2. the reduced model of section 4.3: eigenvalues and Hankel singular values of the thesis's
   ``A_m``, of the appendix E matrices (balanced truncation and residualization) and of the
   consistent model linearized at the fitted operating point;
3. the thesis's test (sections 4.5, 6.2-6.3): state-error RMS (6.1) for gamma = 1, 10, 100, 1000
   with the discrete law (5.8) and the continuous law (4.22), on the plant of section 6.3.1
   re-drawn at every step (the thesis's C++ program; that is its "random disturbance") and on a
   fixed perturbed plant, beside Table 4.1, section 6.2.3 and Table G.3; the replay of the
   appendix G run;
4. the gamma beyond which the discrete adaptation diverges, for three sampling periods;
5. the same MRAC on the non-linear column around its operating point;

and writes plots like the thesis's Fig. 3.4 and 6.2-6.5 into ``--out`` (default
``runs/mrac_study``)::

    .venv/bin/python bench/mrac_study.py [--out DIR] [--seeds N]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import solve_continuous_lyapunov
from scipy.optimize import fsolve

from controllers.mrac import (
    MRAC,
    THESIS_A0,
    THESIS_B0,
    MRACConfig,
    continuous_loop_rhs,
)
from controllers.mrac_plots import errors_figure, outputs_figure, states_figure
from plants.column import (
    APPENDIX_E_A,
    APPENDIX_E_B,
    APPENDIX_E_C,
    FITTED_PARAMS,
    TABLE_3_2_X,
    THESIS_A_M,
    THESIS_B_M,
    THESIS_C_M,
    THESIS_PARAMS,
    Column,
    PerturbedReducedPlant,
    appendix_g_signs,
    balanced_reduction,
    printed_model_rhs,
)
from plants.integrate import rk4

# -- the thesis's numbers -----------------------------------------------------------------------
T_THESIS = 0.1  # h, Table G.1
N_STEPS = 100  # Table G.1: k = 0 ... 100
UC_THESIS = np.array([0.5, 0.1])  # Fig. 7.26-7.27 (uc = 50000, 10000 x 1e-5); x_m(1) = T B_m u_c
TABLE_4_1 = {1: (5.4304e-5, 7.1399e-5), 10: (5.4284e-5, 7.1062e-5), 100: (5.4076e-5, 7.1003e-5)}
SEC_6_2_3 = (9.4074e-5, 9.6078e-5)  # norms 9.4543e-4, 9.6557e-4 over n = 101
TABLE_G3_RMS = (4.7578e-4, 3.4793e-4)  # RMS of the 101 rows of Table G.3 (norms 4.782e-3, 3.497e-3)
GAMMA_G = 1000.0  # inferred from the increments of Table G.4 (least squares: 950-1000)
# Table G.1 rows k = 10, 50, 100 (x1, x2, xm1, xm2)
TABLE_G1_ROWS = {
    10: (-0.006511, -0.011823, -0.006369, -0.011576),
    50: (-0.003254, -0.030814, -0.003639, -0.030590),
    100: (-0.003393, -0.033212, -0.003197, -0.033668),
}
EIG_THESIS = (-6.5832, -0.4606)


def rms(e: np.ndarray) -> np.ndarray:
    """Eq. (6.1): ``||e_i|| / sqrt(n_i)`` per column."""
    return np.linalg.norm(e, axis=0) / math.sqrt(e.shape[0])


# -- loops --------------------------------------------------------------------------------------
def thesis_config(gamma: float, T: float = T_THESIS, **kw: Any) -> MRACConfig:
    """The thesis's controller: reference (4.9), theta0 from the rounded nominal plant."""
    return MRACConfig(gamma=gamma, T=T, A0=THESIS_A0, B0=THESIS_B0, **kw)


def discrete_run(
    gamma: float,
    seed: int | None,
    *,
    redraw: str = "every_step",
    T: float = T_THESIS,
    t_end: float = T_THESIS * N_STEPS,
    uc: np.ndarray = UC_THESIS,
    signs: np.ndarray | None = None,
    on_divergence: str = "freeze",
) -> dict[str, Any]:
    """The loop of section 6.2 / appendix F: Euler plant (5.1), MRAC (5.3), (5.5), (5.8)."""
    rng = np.random.default_rng(seed)
    plant = PerturbedReducedPlant(rng, redraw="once" if signs is not None else redraw)
    ctrl = MRAC(thesis_config(gamma, T, on_divergence=on_divergence))
    n = int(round(t_end / T))
    x = np.zeros(2)
    rec: dict[str, list[Any]] = {k: [] for k in ("t", "x", "xm", "y", "ym", "u", "theta", "d")}
    for k in range(n + 1):
        t = k * T
        u = ctrl.step(t, x, uc)
        rec["t"].append(t)
        rec["x"].append(x)
        rec["xm"].append(ctrl.x_m.copy())
        rec["y"].append(plant.outputs(x))
        rec["ym"].append(ctrl.y_m)
        rec["u"].append(u)
        rec["theta"].append(ctrl.theta.copy())
        if k == n:
            break
        if signs is not None:
            plant.set_signs(signs[k])
        x_next = plant.euler_step(x, u, T)
        # the disturbance the parameter change makes: x(k+1) minus the nominal plant's step
        rec["d"].append(x_next - x - T * (THESIS_A_M @ x + THESIS_B_M @ u))
        x = x_next
    out = {k: np.array(v) for k, v in rec.items()}
    out["e"] = out["x"] - out["xm"]
    out["diverged"] = ctrl.diverged
    out["divergence_time"] = ctrl.divergence_time
    return out


def continuous_run(
    gamma: float,
    seed: int,
    *,
    redraw: bool = True,
    t_end: float = 10.0,
    dt_sample: float = 0.01,
    t_draw: float = T_THESIS,
    uc: np.ndarray = UC_THESIS,
) -> dict[str, Any]:
    """The analog loop of section 4.5 (law (4.22)), RK4; plant re-drawn every ``t_draw``."""
    rng = np.random.default_rng(seed)
    plant = PerturbedReducedPlant(rng, redraw="once")
    cfg = thesis_config(gamma)
    f = continuous_loop_rhs(lambda t: plant.A, lambda t: plant.B, cfg)
    theta0 = MRAC(cfg).theta0
    z = np.concatenate((np.zeros(4), theta0))
    w = np.concatenate((uc, np.zeros(2)))
    n_draw = int(round(t_end / t_draw))
    per = int(round(t_draw / dt_sample))
    e = [z[:2] - z[2:4]]
    for j in range(n_draw):
        if redraw and j > 0:
            plant.draw()
        for i in range(per):
            t0 = (j * per + i) * dt_sample
            z = rk4(f, t0, z, t0 + dt_sample, w, max_step=dt_sample / 2)
            e.append(z[:2] - z[2:4])
    return {"e": np.array(e), "theta": z[4:]}


def divergence_gamma(seed: int, T: float, redraw: str = "once", t_end: float = 10.0) -> float:
    """Smallest gamma (bisection, 2 % resolution) at which the discrete adaptation diverges."""

    def diverges(g: float) -> bool:
        return bool(discrete_run(g, seed, redraw=redraw, T=T, t_end=t_end)["diverged"])

    lo, hi = 10.0, 10.0
    while not diverges(hi):
        lo, hi = hi, hi * 2.0
        if hi > 1e8:
            return math.inf
    while hi / lo > 1.02:
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if diverges(mid) else (mid, hi)
    return hi


def column_run(
    col: Column,
    red: Any,
    gamma: float,
    *,
    amp: float,
    measurement: str = "output",
    T: float = T_THESIS,
    t_end: float = 60.0,
    t_second: float = 20.0,
) -> dict[str, Any]:
    """MRAC on the non-linear column; reference = balanced reduced model at the operating point.

    ``u = u* + M u_c - L x_r`` with ``x_r = W (x - x*)`` (all 16 compositions measured) or
    ``x_r = C_r^-1 (y - y*)`` (only ``x_D, x_B``). Inputs are held between samples (RK4 at
    0.01 h) and clipped to keep ``D, B >= 5 kmol/h`` and ``L, V`` within 50 % of nominal.
    """
    xs = col.steady_state()
    us = col.nominal_input()
    ys = col.outputs(xs)
    cfg = MRACConfig(
        gamma=gamma,
        T=T,
        A_m=red.A,
        B_m=red.B,
        C_m=red.C,
        u_bar=tuple(us),
        y_bar=tuple(ys),
        measurement=measurement,
        reference_discretization="zoh",
        on_divergence="freeze",
    )
    ctrl = MRAC(cfg)
    p = col.params
    x = xs.copy()
    rec: dict[str, list[Any]] = {k: [] for k in ("t", "y", "ym", "u", "e", "drift")}
    n = int(round(t_end / T))
    for k in range(n + 1):
        t = k * T
        uc = np.array([amp, 0.0]) if t < t_second else np.array([amp, amp])
        meas = red.W @ (x - xs) if measurement == "state" else col.outputs(x)
        u = ctrl.step(t, meas, uc)
        lr = float(np.clip(u[0], 0.5 * us[0], 1.5 * us[0]))
        vb = float(np.clip(u[1], 0.5 * us[1], 1.5 * us[1]))
        lr = min(lr, vb + p.V_F - 5.0)  # D >= 5
        vb = min(vb, lr + p.L_F - 5.0)  # B >= 5
        u = np.array((lr, vb))
        rec["t"].append(t)
        rec["y"].append(col.outputs(x) - ys)
        rec["ym"].append(ctrl.y_m)
        rec["u"].append(u)
        rec["e"].append(ctrl.e.copy())
        rec["drift"].append(ctrl.theta_drift)
        if k < n:
            x = rk4(col.rhs, t, x, t + T, u, max_step=0.01)
    out = {k: np.array(v) for k, v in rec.items()}
    out["diverged"] = ctrl.diverged
    out["divergence_time"] = ctrl.divergence_time
    return out


# -- reports ------------------------------------------------------------------------------------
def _fmt(v: float) -> str:
    return f"{v:.3e}" if np.isfinite(v) else "   inf   "


def report_column() -> dict[str, Any]:
    print("\n1. Column steady state vs Table 3.2 (max |x_n - x_n*| over the 16 stages)")
    tab = np.array(TABLE_3_2_X)
    x_pr = fsolve(lambda z: printed_model_rhs(0.0, z), tab, xtol=1e-13)
    rows = [("eq. (3.3) as printed", x_pr, None)]
    for name, params in (
        ("appendix C flows (consistent)", THESIS_PARAMS),
        ("fitted L, V (FITTED_PARAMS)", FITTED_PARAMS),
    ):
        col = Column(params)
        rows.append((name, col.steady_state(), params))
    print(
        f"   {'model':32s} {'L':>8s} {'V':>8s} {'D':>8s} {'B':>9s} {'max dev':>8s} "
        f"{'x_D':>7s} {'x_B':>7s}"
    )
    for name, x, params in rows:
        if params is None:
            lv = "  75.638   66.114   92.760  110.924"
        else:
            d, b = params.V + params.V_F - params.L, params.L + params.L_F - params.V
            lv = f"{params.L:8.3f} {params.V:8.3f} {d:8.3f} {b:9.3f}"
        print(f"   {name:32s} {lv} {np.max(np.abs(x - tab)):8.4f} {x[-1]:7.4f} {x[0]:7.4f}")
    col = Column(FITTED_PARAMS)
    xs = col.steady_state()
    diff = np.array2string(xs - tab, precision=4, max_line_width=200)
    print("   fitted profile - Table 3.2:", diff)
    return {"x_fit": xs, "x_printed": x_pr, "x_app": rows[1][1]}


def report_reduction() -> dict[str, Any]:
    print("\n2. Reduced model of section 4.3 (eigenvalues 1/h; Hankel singular values)")
    wc = _gram(THESIS_A_M, THESIS_B_M)
    print(
        f"   thesis A_m, B_m, C_m               eig {np.sort(np.linalg.eigvals(THESIS_A_M).real)}"
        f"   Gramian diag {np.diag(wc)}"
    )
    out: dict[str, Any] = {}
    for method in ("matchdc", "truncate"):
        r = balanced_reduction(APPENDIX_E_A, APPENDIX_E_B, APPENDIX_E_C, 2, method)
        ev = np.sort(r.eigenvalues().real)
        dev = np.max(np.abs(ev / np.array(EIG_THESIS) - 1.0)) * 100
        print(
            f"   appendix E, balanced {method:9s}     eig {ev}   hsv {r.hsv[:3]}   "
            f"max dev {dev:.1f} %"
        )
        out[f"E_{method}"] = r
    r = out["E_matchdc"]
    s = np.sign(np.array([r.C[1, 0] * THESIS_C_M[1, 0], r.C[0, 1] * THESIS_C_M[0, 1]]))
    sm = np.diag(s)
    print("   appendix E residualized (states signed like the thesis):")
    print("     A_m", np.array2string(sm @ r.A @ sm, precision=4), " thesis", THESIS_A_M.tolist())
    print("     B_m", np.array2string(sm @ r.B, precision=4), " thesis", THESIS_B_M.tolist())
    print("     C_m", np.array2string(r.C @ sm, precision=4), " thesis", THESIS_C_M.tolist())
    col = Column(FITTED_PARAMS)
    xs, us = col.steady_state(), col.nominal_input()
    jx, ju = col.jacobian(xs, us)
    c = np.zeros((2, 16))
    c[0, 0], c[1, 15] = 1.0, 1.0  # appendix E order (x_B, x_D)
    print(
        f"   consistent model, fitted point:    slowest eig of the 16 "
        f"{np.sort(np.linalg.eigvals(jx).real)[::-1][:3]}"
    )
    for method in ("matchdc", "truncate"):
        r = balanced_reduction(jx, ju, c, 2, method)
        ev = np.sort(r.eigenvalues().real)
        dev = np.max(np.abs(ev / np.array(EIG_THESIS) - 1.0)) * 100
        print(
            f"   consistent model, {method:9s}        eig {ev}   hsv {r.hsv[:3]}   "
            f"max dev {dev:.0f} %"
        )
        out[f"ours_{method}"] = r
    print("   DC gains (rows x_B, x_D; columns L, V):")
    dc_e = _dc(APPENDIX_E_A, APPENDIX_E_B, APPENDIX_E_C)
    print("     appendix E full   ", dc_e.round(5).tolist())
    print("     thesis A_m..C_m   ", _dc(THESIS_A_M, THESIS_B_M, THESIS_C_M).round(5).tolist())
    print("     consistent, fitted", _dc(jx, ju, c).round(5).tolist())
    return out


def _at(t: float | None) -> str:
    return "-" if t is None else f"{t:.1f} h"


def _gram(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return solve_continuous_lyapunov(a, -b @ b.T)


def _dc(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return -c @ np.linalg.solve(a, b)


def report_thesis_test(seeds: int) -> dict[str, Any]:
    print(
        f"\n3. The thesis's test: u_c = {UC_THESIS.tolist()} (steps at t = 0), T = {T_THESIS} h, "
        f"t = 0 ... 10 h, RMS (6.1) over n = 101 samples (continuous: 1001)"
    )
    print(
        f"   mean +- sd over {seeds} seeds (np.random.default_rng(seed)); theta0 from (5.7) with "
        "the rounded nominal plant"
    )
    replay = discrete_run(GAMMA_G, None, signs=appendix_g_signs())
    r_rep = rms(replay["e"])
    print(
        f"   {'gamma':>6s} | {'discrete, re-drawn plant':^27s} | "
        f"{'discrete, fixed plant':^27s} | {'continuous, re-drawn 0.1 h':^27s} | thesis"
    )
    print(
        f"   {'':>6s} | {'e1':^13s} {'e2':^13s} | {'e1':^13s} {'e2':^13s} | "
        f"{'e1':^13s} {'e2':^13s} |"
    )
    table: dict[float, dict[str, np.ndarray]] = {}
    for g in (1.0, 10.0, 100.0, 1000.0):
        d_re = np.array([rms(discrete_run(g, s)["e"]) for s in range(seeds)])
        d_fx = np.array([rms(discrete_run(g, s, redraw="once")["e"]) for s in range(seeds)])
        c_re = np.array([rms(continuous_run(g, s)["e"]) for s in range(seeds)])
        table[g] = {"re": d_re, "fx": d_fx, "cont": c_re}
        cells = []
        for arr in (d_re, d_fx, c_re):
            m, sd = arr.mean(0), arr.std(0)
            cells.append(f"{m[0]:.2e}±{sd[0]:.0e} {m[1]:.2e}±{sd[1]:.0e}")
        th = TABLE_4_1.get(int(g))
        ths = (
            f"Table 4.1: {th[0]:.4e}, {th[1]:.4e}"
            if th
            else "Table G.3 (gamma ~1000): " + (f"{TABLE_G3_RMS[0]:.4e}, {TABLE_G3_RMS[1]:.4e}")
        )
        print(f"   {g:6.0f} | {cells[0]} | {cells[1]} | {cells[2]} | {ths}")
    scale = TABLE_4_1[1][0] / table[1.0]["cont"].mean(0)[0]
    print(
        f"   Table 4.1 hypothesis: the same continuous run with u_c x {scale:.3f} (the one "
        "factor that matches e1 at gamma = 1; errors scale with |u_c|, adaptation speed with "
        "gamma |u_c|^2):"
    )
    for g in (1.0, 10.0, 100.0):
        arr = np.array([rms(continuous_run(g, s, uc=UC_THESIS * scale)["e"]) for s in range(seeds)])
        m = arr.mean(0)
        th = TABLE_4_1[int(g)]
        print(f"   {g:6.0f} | e1 {m[0]:.4e} e2 {m[1]:.4e}   thesis e1 {th[0]:.4e} e2 {th[1]:.4e}")
    print(
        f"   section 6.2.3 (gamma not given): e1 {SEC_6_2_3[0]:.4e}, e2 {SEC_6_2_3[1]:.4e} "
        f"(n = 101)"
    )
    print(
        f"   replay of appendix G (gamma {GAMMA_G:.0f}, plant signs inferred from Table G.1): "
        f"e1 {r_rep[0]:.4e}, e2 {r_rep[1]:.4e}; Table G.3 gives {TABLE_G3_RMS[0]:.4e}, "
        f"{TABLE_G3_RMS[1]:.4e}"
    )
    dev = max(abs(replay["x"][k][i] - TABLE_G1_ROWS[k][i]) for k in TABLE_G1_ROWS for i in range(2))
    print(f"     replay vs Table G.1 rows k = 10, 50, 100: max |x - x_table| = {dev:.1e}")
    print(
        f"   section 6.2.3 / Table G.3 = {SEC_6_2_3[0] / TABLE_G3_RMS[0]:.3f} (e1), "
        f"{SEC_6_2_3[1] / TABLE_G3_RMS[1]:.3f} (e2): the summary is not the RMS of the table "
        "it summarizes"
    )
    return {"table": table, "replay": replay}


def report_divergence(seeds: int) -> dict[str, Any]:
    print(
        "\n4. Divergence of the discrete law (5.8): smallest gamma with max|theta - theta0| > "
        f"{MRACConfig(gamma=0, T=1e-3).theta_bound:g} within 10 h (bisection, 2 %)"
    )
    print(
        f"   {'T (h)':>6s} {'plant':>10s} {'min':>10s} {'median':>10s} {'max':>10s} "
        f"{'gamma* T (median)':>18s}"
    )
    out = {}
    for T in (0.05, 0.1, 0.2):
        for redraw in ("once", "every_step"):
            gs = np.array([divergence_gamma(s, T, redraw) for s in range(seeds)])
            out[(T, redraw)] = gs
            print(
                f"   {T:6.2f} {redraw:>10s} {gs.min():10.0f} {np.median(gs):10.0f} "
                f"{gs.max():10.0f} {np.median(gs) * T:18.0f}"
            )
    return out


def report_column_mrac(red: Any) -> dict[str, Any]:
    print(
        "\n5. MRAC on the non-linear column (reference: balanced residualization at the fitted "
        "point, T = 0.1 h, u_c = (a, 0) kmol/h from 0 h, (a, a) from 20 h, 60 h)"
    )
    print(
        f"   reduced model eig {np.sort(red.eigenvalues().real)}, C_r condition number "
        f"{np.linalg.cond(red.C):.2f}"
    )
    col = Column(FITTED_PARAMS)
    print(
        f"   {'a':>4s} {'measure':>7s} {'gamma':>7s} {'RMS(y-y_m) x_D':>15s} {'x_B':>10s} "
        f"{'RMS e1':>10s} {'e2':>10s} {'max drift':>9s} {'diverged at':>11s}"
    )
    runs = {}
    for amp in (1.0, 3.0):
        for meas in ("output", "state"):
            for g in (0.0, 100.0, 1000.0, 10000.0):
                r = column_run(col, red, g, amp=amp, measurement=meas)
                runs[(amp, meas, g)] = r
                ey = rms(r["y"] - r["ym"])
                ee = rms(r["e"])
                print(
                    f"   {amp:4.1f} {meas:>7s} {g:7.0f} {ey[0]:15.2e} {ey[1]:10.2e} "
                    f"{ee[0]:10.2e} {ee[1]:10.2e} {r['drift'].max():9.3g} "
                    f"{_at(r['divergence_time']):>11s}"
                )
    return runs


# -- plots --------------------------------------------------------------------------------------
def plots(out: Path, col_res: dict, test: dict, column_runs: dict) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    files = []

    def save(fig: Any, name: str) -> None:
        p = out / name
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        files.append(p)

    # Fig. 3.4: the steady-state profile
    fig, ax = plt.subplots(figsize=(6, 4))
    n = np.arange(1, 17)
    ax.plot(n, TABLE_3_2_X, "ko", label="Table 3.2")
    ax.plot(n, col_res["x_fit"], "-", label="fitted L, V")
    ax.plot(n, col_res["x_app"], "--", label="appendix C flows")
    ax.plot(n, col_res["x_printed"], ":", label="eq. (3.3) as printed")
    ax.set_xlabel("stage n (1 = reboiler, 16 = condenser)")
    ax.set_ylabel("x_n")
    ax.legend()
    save(fig, "fig3_4_profile.png")

    rep = test["replay"]
    runs = {"replay": rep, "seed0": discrete_run(GAMMA_G, 0)}
    for tag, r in runs.items():
        t = r["t"]
        # Fig. 6.2: the disturbance (what the re-drawn parameters add per step)
        fig, ax = plt.subplots(2, 1, figsize=(6, 4.5), sharex=True)
        for i in range(2):
            ax[i].step(t[:-1], r["d"][:, i], where="post")
            ax[i].set_ylabel(f"d{i + 1}")
        ax[1].set_xlabel("t (h)")
        ax[0].set_title(f"disturbance of the re-drawn plant ({tag})")
        save(fig, f"fig6_2_disturbance_{tag}.png")
        # Fig. 6.3-6.5: states, outputs, errors (drawn as for platform runs: controllers.mrac_plots)
        fig = states_figure(t, r["x"], r["xm"], title=f"states ({tag})")
        if tag == "replay":
            ax = fig.axes
            for k, row in TABLE_G1_ROWS.items():
                ax[0].plot(k * T_THESIS, row[0], "kx")
                ax[1].plot(k * T_THESIS, row[1], "kx")
        save(fig, f"fig6_3_states_{tag}.png")
        save(
            outputs_figure(t, r["y"], r["ym"], title=f"outputs ({tag})"),
            f"fig6_4_outputs_{tag}.png",
        )
        save(errors_figure(t, r["e"], title=f"state errors ({tag})"), f"fig6_5_errors_{tag}.png")

    # error RMS against gamma
    fig, ax = plt.subplots(figsize=(6, 4))
    gam = sorted(test["table"])
    for key, lab in (
        ("re", "discrete, re-drawn"),
        ("fx", "discrete, fixed"),
        ("cont", "continuous, re-drawn"),
    ):
        m = np.array([test["table"][g][key].mean(0) for g in gam])
        ax.loglog(gam, m[:, 0], "o-", label=f"e1 {lab}")
        ax.loglog(gam, m[:, 1], "s--", label=f"e2 {lab}")
    ax.set_xlabel("gamma")
    ax.set_ylabel("RMS (6.1)")
    ax.legend(fontsize=7)
    save(fig, "rms_vs_gamma.png")

    # the column
    for amp in (1.0, 3.0):
        fig, ax = plt.subplots(3, 1, figsize=(6.5, 7), sharex=True)
        for g, style in ((0.0, ":"), (100.0, "-"), (1000.0, "--")):
            r = column_runs[(amp, "output", g)]
            t = r["t"]
            ax[0].plot(t, r["y"][:, 0], style, label=f"x_D - x_D*, gamma {g:g}")
            ax[1].plot(t, r["y"][:, 1], style, label=f"x_B - x_B*, gamma {g:g}")
            ax[2].plot(t, r["u"][:, 0], style, label=f"L, gamma {g:g}")
            ax[2].plot(t, r["u"][:, 1], style, label=f"V, gamma {g:g}")
        ax[0].plot(t, r["ym"][:, 0], "k--", lw=0.8, label="y_m1")
        ax[1].plot(t, r["ym"][:, 1], "k--", lw=0.8, label="y_m2")
        for a in ax:
            a.legend(fontsize=7)
        ax[2].set_xlabel("t (h)")
        save(fig, f"column_mrac_a{amp:g}.png")
    return files


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("runs/mrac_study"), help="plot directory")
    ap.add_argument("--seeds", type=int, default=20, help="random plants per case")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    col_res = report_column()
    red = report_reduction()
    test = report_thesis_test(args.seeds)
    report_divergence(args.seeds)
    col = Column(FITTED_PARAMS)
    xs, us = col.steady_state(), col.nominal_input()
    jx, ju = col.jacobian(xs, us)
    c = np.zeros((2, 16))
    c[0, 15], c[1, 0] = 1.0, 1.0  # outputs (x_D, x_B)
    red_col = balanced_reduction(jx, ju, c, 2, "matchdc")
    column_runs = report_column_mrac(red_col)
    files = plots(args.out, col_res, test, column_runs)
    print(f"\nplots: {len(files)} files in {args.out}   ({time.perf_counter() - t0:.0f} s)")
    del red


if __name__ == "__main__":
    main()
