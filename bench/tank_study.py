"""Seed 002 (Short & Selvakumar 2020) tank-level studies: NL PI vs the fixed-gain baseline, EW-RLS.

Prints, from a closed loop of its own (fixed-step RK4 of ``plants.integrate``, zero-order hold
between samples; no runtime):

1. the simulation study of section 4.1 (eq. (22), h in mm, samples every 0.05 s): per set-point
   step, overshoot % and 1 % settling time of the non-linear PI and of the 2-DOF PI tuned by
   eq. (7) at 100 mm, and the peak deviation after equal disturbance-flow steps;
2. small steps at levels from 2 to 400 mm against the reference model eq. (23);
3. the rig study of section 4.2 (eq. (24), h in m, samples every 1 s) with a drive range of
   [0, 2] (our assumption) and of [0, 1];
4. the EW-RLS self-tuning law: convergence from 50 % wrong guesses, with measurement noise, at
   rest, and after a change of the plant mid-run.

    .venv/bin/python bench/tank_study.py
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import control  # noqa: TID253 - not a node: imports what it uses at the top
import numpy as np

from controllers.ewrls import SelfTuningNLPI, STNLPIConfig
from controllers.nlpi import NLPIConfig, NonlinearPI, PI2DOFConfig, TwoDofPI
from plants.integrate import rk4
from plants.tank import RIG_PARAMS, SIM_PARAMS, Tank, TankParams

SIM = Tank(SIM_PARAMS)
OS = 4.321
TS_SIM = 0.05


def closed_loop(
    plant: Tank | Callable[[float], Tank],
    law: Any,
    *,
    ts: float,
    t_end: float,
    r: Callable[[float], float],
    q_d: Callable[[float], float] = lambda t: 0.0,
    h0: float = 0.0,
    noise: float = 0.0,
    seed: int = 0,
    max_step: float | None = None,
) -> dict[str, np.ndarray]:
    """Sample every ``ts``, run the law, hold its command (RK4 in between); record the estimates."""
    rng = np.random.default_rng(seed)
    plant_at = plant if callable(plant) and not isinstance(plant, Tank) else (lambda t: plant)
    times = np.arange(0.0, t_end + 0.5 * ts, ts)
    x = np.array([h0])
    rec: dict[str, list] = {"t": [], "h": [], "u": [], "est": []}
    for k, t in enumerate(times):
        p = plant_at(t)
        y = float(p.outputs(x)[0]) + (noise * rng.standard_normal() if noise else 0.0)
        u = law.step(float(t), y, r(t))
        rec["t"].append(t)
        rec["h"].append(float(x[0]))
        rec["u"].append(u)
        rec["est"].append((getattr(law, "b", math.nan), getattr(law, "a_prime", math.nan)))
        if k + 1 < len(times):
            x = rk4(p.rhs, t, x, times[k + 1], np.array([u, q_d(t)]), max_step=max_step or ts)
    return {k: np.asarray(v) for k, v in rec.items()}


def figures(run: dict[str, np.ndarray], t0: float, t1: float, r0: float, r1: float):
    """Overshoot % and settling time in the 1 % band (eq. (14)) of a step in [t0, t1)."""
    m = (run["t"] >= t0) & (run["t"] < t1)
    tw, hw = run["t"][m], run["h"][m]
    size = r1 - r0
    overshoot = max(0.0, float(np.max(np.sign(size) * (hw - r1)))) / abs(size) * 100.0
    out = np.nonzero(np.abs(hw - r1) > 0.01 * abs(size))[0]
    if len(out) == 0:
        return overshoot, 0.0
    return overshoot, (math.inf if out[-1] == len(tw) - 1 else float(tw[out[-1] + 1] - t0))


def staircase(levels: Sequence[float], times: Sequence[float]) -> Callable[[float], float]:
    def r(t: float) -> float:
        value = levels[0]
        for lv, tt in zip(levels, times, strict=True):
            if t >= tt - 1e-9:
                value = lv
        return value

    return r


def nl(plant: Tank = SIM, settling: float = 13.0, **kw: Any) -> NonlinearPI:
    return NonlinearPI.from_config(
        NLPIConfig(overshoot_pct=OS, settling_time=settling, **kw), plant=plant
    )


def base(**kw: Any) -> TwoDofPI:
    cfg = PI2DOFConfig(overshoot_pct=OS, settling_time=13.0, h_design=100.0, **kw)
    return TwoDofPI.from_config(cfg, plant=SIM)


def st(plant: Tank = SIM, tau_s: float = TS_SIM, settling: float = 13.0, **kw: Any):
    cfg = STNLPIConfig(overshoot_pct=OS, settling_time=settling, **kw)
    return SelfTuningNLPI.from_config(cfg, plant=plant, tau_s=tau_s)


def rule(title: str) -> None:
    print(f"\n{title}\n{'-' * len(title)}")


# -- 1. simulation study ------------------------------------------------------------------------
LEVELS, TIMES = (50.0, 100.0, 150.0), (0.0, 50.0, 100.0)


def q_alternating(size: float) -> Callable[[float], float]:
    def q(t: float) -> float:
        if 25.0 <= t < 50.0 or t >= 125.0:
            return size
        return -size if 75.0 <= t < 100.0 else 0.0

    return q


def simulation_study() -> None:
    rule("1. Simulation study, seed 002 section 4.1 (eq. (22), h in mm, Ts = 0.05 s, 1 % band)")
    laws = {
        "NL PI (eq. 20-21)": lambda: nl(),
        "NL PI trapezoidal": lambda: nl(integration="trapezoidal"),
        "2-DOF PI @100 mm, tangent": lambda: base(),
        "2-DOF PI @100 mm, secant": lambda: base(linearization="secant"),
    }
    r = staircase(LEVELS, TIMES)
    print(
        f"{'law':28s}"
        + "".join(
            f"  {f'{a:.0f}->{b:.0f} mm':>18s}" for a, b in zip((0, 50, 100), LEVELS, strict=True)
        )
        + "   spread OS / ts"
    )
    print(f"{'':28s}" + "   OS %   settle s" * 3)
    for name, make in laws.items():
        run = closed_loop(SIM, make(), ts=TS_SIM, t_end=150.0, r=r)
        figs = [
            figures(run, t0, t0 + 50, r0, r1)
            for t0, r0, r1 in zip(TIMES, (0.0, 50.0, 100.0), LEVELS, strict=True)
        ]
        cells = "".join(f"  {o:6.2f} {s:9.2f}" for o, s in figs)
        spread = np.ptp(np.array(figs), axis=0)
        print(f"{name:28s}{cells}   {spread[0]:.2f} pp / {spread[1]:.2f} s")
    print("(paper: 4.321 % and 13 s at every level; continuous-time reference: 4.32 %, 13.16 s)")

    d = 1.0
    print(f"\nDisturbance outflow steps of {d} mm/s at 25 s (+), 75 s (-), 125 s (+):")
    print(f"{'law':28s}  peak |h - r| at 50 / 100 / 150 mm      max/min - 1")
    for name in ("NL PI (eq. 20-21)", "2-DOF PI @100 mm, tangent"):
        run = closed_loop(SIM, laws[name](), ts=TS_SIM, t_end=150.0, r=r, q_d=q_alternating(d))
        peaks = []
        for t0, lv in zip((25.0, 75.0, 125.0), LEVELS, strict=True):
            m = (run["t"] >= t0) & (run["t"] < t0 + 25.0)
            peaks.append(float(np.max(np.abs(run["h"][m] - lv))))
        print(
            f"{name:28s}  {peaks[0]:.3f} / {peaks[1]:.3f} / {peaks[2]:.3f} mm"
            f"            {max(peaks) / min(peaks) - 1:6.2%}"
        )
    print(
        "(linear prediction: 0.912 mm = d x peak impulse response of 1/(s^2 + 0.7076 s + 0.2504))"
    )


# -- 2. small steps against eq. (23) ------------------------------------------------------------
def reference_model() -> None:
    rule("2. Small steps (+5 % of the level) against eq. (23), 0.25/(s^2 + 0.7071 s + 0.25)")
    print(
        f"{'level mm':>9s}  {'NL PI: max dev % of step, OS %':>32s}"
        f"  {'2-DOF PI @100: max dev %, OS %':>32s}"
    )
    ref_sys = control.tf([0.25], [1, 0.7071, 0.25])
    for level in (2.0, 5.0, 20.0, 50.0, 100.0, 150.0, 400.0):
        step = 0.05 * level
        row = []
        for law in (nl(), base()):
            run = closed_loop(
                SIM, law, ts=TS_SIM, t_end=40.0, r=lambda t, s=step, lv=level: lv + s, h0=level
            )
            ref = control.step_response(ref_sys, run["t"]).outputs
            dev = np.max(np.abs((run["h"] - level) - step * ref)) / step * 100
            row.append((dev, figures(run, 0.0, 40.0, level, level + step)[0]))
        print(
            f"{level:9.0f}  {row[0][0]:21.2f} {row[0][1]:10.2f}  {row[1][0]:21.2f}"
            f" {row[1][1]:10.2f}"
        )


# -- 3. rig study -------------------------------------------------------------------------------
def rig_study() -> None:
    rule("3. Rig study, seed 002 section 4.2 (eq. (24), h in m, Ts = 1 s, t_s = 100 s, 1 % band)")
    print(
        f"{'drive range':12s}  {'0 -> 0.5 m: OS %, settle s':>28s}  "
        f"{'0.5 -> 1.0 m: OS %, settle s':>30s}  {'peak u':>7s}  {'s at limit':>10s}"
    )
    for u_max in (2.0, 1.0):
        plant = Tank(RIG_PARAMS.model_copy(update={"u_max": u_max}))
        run = closed_loop(
            plant,
            nl(plant, 100.0),
            ts=1.0,
            t_end=500.0,
            r=staircase((0.5, 1.0), (0.0, 250.0)),
            max_step=0.25,
        )
        f1 = figures(run, 0.0, 250.0, 0.0, 0.5)
        f2 = figures(run, 250.0, 501.0, 0.5, 1.0)
        at_limit = int(np.sum(run["u"] >= u_max - 1e-12))
        print(
            f"[0, {u_max:.0f}]{'':6s}  {f1[0]:16.2f} {f1[1]:10.1f}  {f2[0]:18.2f} {f2[1]:10.1f}"
            f"  {np.max(run['u']):7.3f}  {at_limit:10d}"
        )
    print("(paper: 4.321 % and 100 s, 'approximately achieved'; eq. (25) misprinted, see nlpi.py)")


# -- 4. EW-RLS ----------------------------------------------------------------------------------
def ewrls_study() -> None:
    rule("4. EW-RLS self-tuning NL PI (section 3.3), simulated tank, Ts = 0.05 s")
    true = np.array((2.0, 0.5))
    r = staircase(LEVELS, TIMES)
    print("Convergence from 50 % wrong guesses (set points of section 4.1), defaults:")
    print(
        f"{'noise mm':>8s}  {'b0':>4s} {'a0':>5s}  {'within 2 % from':>15s}  "
        f"{'final error b, a %':>18s}  {'b/a err %':>9s}  {'changes':>7s}"
    )
    for noise in (0.0, 0.5):
        for b0, a0 in ((3.0, 0.25), (1.0, 0.75), (3.0, 0.75), (1.0, 0.25)):
            law = st(b0=b0, a_prime0=a0)
            run = closed_loop(SIM, law, ts=TS_SIM, t_end=150.0, r=r, noise=noise, seed=11)
            err = np.abs(run["est"] / true - 1.0)
            ok = np.all(err < 0.02, axis=1)
            bad = np.nonzero(~ok)[0]
            since = run["t"][bad[-1] + 1] if len(bad) and bad[-1] + 1 < len(ok) else 0.0
            ratio = run["est"][-1, 0] / run["est"][-1, 1] / 4.0 - 1.0
            print(
                f"{noise:8.1f}  {b0:4.1f} {a0:5.2f}  {since:13.2f} s  "
                f"{err[-1, 0] * 100:8.3f} {err[-1, 1] * 100:8.3f}  {ratio * 100:9.3f}  "
                f"{law.estimator.n_changes:7d}"
            )

    print("\n500 s at rest at 100 mm with 0.5 mm noise (what is identifiable without transients):")
    for label, kw in (
        ("hold (default)", {}),
        ("no hold (excitation_min=0)", {"excitation_min": 0}),
    ):
        law = st(**kw)
        run = closed_loop(
            SIM, law, ts=TS_SIM, t_end=500.0, r=lambda t: 100.0, h0=100.0, noise=0.5, seed=2
        )
        b, a = run["est"][:, 0], run["est"][:, 1]
        print(
            f"  {label:28s} b in [{b.min():.3f}, {b.max():.3f}], a' in [{a.min():.3f}, "
            f"{a.max():.3f}], b/a' in [{(b / a).min():.3f}, {(b / a).max():.3f}] (true 4), "
            f"max |h - r| {np.max(np.abs(run['h'] - 100)):.2f} mm"
        )

    print(
        "\nPlant change at 75 s (at rest, 100 mm), then 150 (100 s), 50 (150 s), 100 (200 s), "
        "150 mm (250 s):"
    )
    print(
        f"{'change':>20s}  {'law':>26s}  {'steps 100->150, 50->100, 100->150: OS % / ts s':>48s}"
        f"  {'final b, a':>14s}  {'min b, a after':>14s}  changes"
    )
    rc = staircase((50.0, 100.0, 150.0, 50.0, 100.0, 150.0), (0, 50, 100, 150, 200, 250))
    for new in (TankParams(b=2.0, a_prime=0.75), TankParams(b=1.2, a_prime=0.5)):
        after = Tank(new)
        for label, make in (
            ("self-tuning", lambda: st(b0=3.0, a_prime0=0.25)),
            ("self-tuning, no detection", lambda: st(b0=3.0, a_prime0=0.25, change_error=None)),
            ("fixed NL PI (old model)", lambda: nl()),
        ):
            law = make()
            run = closed_loop(
                lambda t, a=after: SIM if t < 75.0 else a, law, ts=TS_SIM, t_end=300.0, r=rc
            )
            steps = [
                figures(run, t0, t0 + 50, r0, r1)
                for t0, r0, r1 in (
                    (100.0, 100.0, 150.0),
                    (200.0, 50.0, 100.0),
                    (250.0, 100.0, 150.0),
                )
            ]
            cells = ", ".join(f"{o:5.2f}/{s:5.2f}" for o, s in steps)
            m = run["t"] >= 75.0
            mins = run["est"][m].min(axis=0)
            n = getattr(getattr(law, "estimator", None), "n_changes", "-")
            print(
                f"{f'b={new.b}, a={new.a_prime}':>20s}  {label:>26s}  {cells:>48s}  "
                f"{run['est'][-1, 0]:6.3f},{run['est'][-1, 1]:6.3f}  "
                f"{mins[0]:6.3f},{mins[1]:6.3f}  {n}"
            )

    print(
        "\nUnmeasured draw-off steps (section 4.1 scenario, alternating +d/-d/+d), self-tuning law:"
    )
    print(f"{'d mm/s':>7s}  {'b range':>15s}  {'a range':>15s}  {'OS % per step':>20s}  changes")
    for d in (0.2, 0.5, 1.0):
        law = st()
        run = closed_loop(SIM, law, ts=TS_SIM, t_end=150.0, r=r, q_d=q_alternating(d))
        os_ = [
            figures(run, t0, t0 + 25, r0, r1)[0]
            for t0, r0, r1 in zip(TIMES, (0.0, 50.0, 100.0), LEVELS, strict=True)
        ]
        lo, hi = run["est"].min(axis=0), run["est"].max(axis=0)
        print(
            f"{d:7.1f}  [{lo[0]:5.3f}, {hi[0]:5.3f}]  [{lo[1]:5.3f}, {hi[1]:5.3f}]  "
            + " ".join(f"{o:6.2f}" for o in os_)
            + f"  {law.estimator.n_changes:7d}"
        )

    rule("EW-RLS on the rig (eq. (24), Ts = 1 s, guesses +50 % / -50 %)")
    rig = Tank(RIG_PARAMS)
    law = st(rig, 1.0, 100.0, b0=0.0183, a_prime0=0.002485)
    run = closed_loop(
        rig,
        law,
        ts=1.0,
        t_end=1000.0,
        max_step=0.25,
        r=staircase((0.5, 1.0, 0.5, 1.0), (0.0, 250.0, 500.0, 750.0)),
    )
    err = run["est"][-1] / np.array((0.0122, 0.00497)) - 1
    steps = [
        figures(run, t0, t0 + 250, r0, r1)
        for t0, r0, r1 in ((0.0, 0.0, 0.5), (250.0, 0.5, 1.0), (750.0, 0.5, 1.0))
    ]
    print(
        "final error b, a': "
        + ", ".join(f"{e * 100:.3f} %" for e in err)
        + "; steps 0->0.5, 0.5->1.0, (again) 0.5->1.0: "
        + ", ".join(f"{o:.2f} % / {s:.0f} s" for o, s in steps)
    )


def main() -> None:
    t0 = time.perf_counter()
    simulation_study()
    reference_model()
    rig_study()
    ewrls_study()
    print(f"\n({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
