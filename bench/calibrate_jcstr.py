"""Calibration of our JCSTR parameters and PI gains against seed 000, section III.C.

The paper's parameter values (its ref. [9]) are not public, so ``plants/jcstr.py`` and
``scenarios/jcstr_benchmark.yaml`` carry values of our own. This script reproduces how they were
found, on the ``direct`` engine with the scenario's initial state and set-point schedule, and
prints the result; it writes nothing (the printed values were copied into the yaml by hand)::

    python bench/calibrate_jcstr.py [--integration backward|forward] [--end-time 6.0]
                                    [--maxfev 400] [--start F_in T_in V_j T_jin Kp Ti] [--screen N]

The defaults reproduce the shipped values in about 2.5 minutes on 2 cores. The run length is
6 pu, not 4: at the gains the section III.C figures need, both PI loops have a slow tail after
their overshoot and settle (2 %) only 3.6 pu (level) and 2.5 pu (temperature) after their steps;
``--end-time 4`` shows what insisting on 4 pu costs.

Stage 1, level loop. ``dH/dt = (F_in - F_out) / A_B`` with ``F_out = F_in + Kp e + I``: the
loop depends only on ``Kp/A_B``, ``Ki/A_B``, the integration rule and the timing, so there are two
continuous knobs for three figures (benchmark 10.8 %, largest ``tau_s`` 0.25 pu with 24.9 %,
largest ``tau_d`` 0.253 pu). For both integration rules we solve (``fsolve``, from
``(Kp, Ki)/A_B = (-4.8, -2.4)`` forward, ``(-4.4, -2.5)`` backward) for the two sampling
figures, benchmark 10.8 % and 24.9 % at ``tau_s`` = 0.25 pu; if that benchmark step would not
settle within the run, ``Kp/A_B`` is raised along the 10.8 % curve until it does. The table
printed after it is the trade-off along the 10.8 % curve: gentler gains buy delay tolerance
with sampling tolerance and settling, and no gains give both 0.25 pu and 0.253 pu.

Stage 2, temperature loop. Knobs ``F_in, T_in, V_j, T_jin`` and the gains ``Kp``,
``Ti = Kp/Ki``; ``A_B = 1``, ``D = 2 sqrt(A_B/pi)`` (circular base), ``rho = C_p = 1``, and ``U``
follows from requiring the paper's initial jacket temperature 143 C to be the equilibrium jacket
temperature at the first set points (0.70 pu, 52 C), eq. (6). Nelder-Mead, from ``START``,
minimises a weighted least-squares misfit to: benchmark 11.0 %; 28.5 % at ``tau_s`` = 0.3 pu;
the delay figures aimed between the paper's text and its Fig. 8 (25 % at ``tau_d`` = 0.14 pu,
about 23 % at 0.1 pu, 28.9 % at 0.186 pu); 25 % at section III.E's point A; plus penalties for
rough or non-monotone overshoot curves, actuator saturation or a loop already oscillating before
the step, a benchmark step that does not settle, and leaving a plausibility box: F_in 0.5..10,
T_in 0..50 C, V_j 0.05..1, T_jin 180..300 C, Ti 0.05..2 pu, and fastest thermal time constant
at least 0.065 pu, so that the engine's fixed RK4 step (0.005 pu) stays accurate to 1e-8 (the
fit would otherwise run to ever faster thermal dynamics). ``--screen N`` first runs a seeded
random screening of the box and starts from its best point instead.

Stage 3: round the plant values to 3 significant digits (``U`` to 4), re-fit the two temperature
gains on the same misfit, round the gains to 4 significant digits, and print the final values
and the section III.C table (``bench/section3c.py``) of the resulting scenario.

Backward Euler is the default because it fits clearly better: the level loop matches the two
sampling figures with either rule, but with forward Euler the temperature misfit stays several
times larger and runs into the plausibility box (``--integration forward`` shows it).

``--delay-figure`` instead fits only the level PI to section III.C's *delay* figures, the level
gains of ``scenarios/jcstr_wncs.yaml`` (the coordination agent's accept test, III.E step 2, is
the delay bound)::

    python bench/calibrate_jcstr.py --delay-figure [--integration backward] [--end-time 6.0]

On the shipped plant of ``jcstr_benchmark.yaml``, at the scenario's own step times (the fixed
phase, as III.C), ``scipy.optimize.least_squares`` solves benchmark OS = 10.8 % and
OS(``tau_d`` = 0.253 pu) = 25 % for ``(Kp, Ki)/A_B`` from ``DELAY_START`` = ``(-2.5, -0.5)``,
rounds the gains to 5 significant digits (``Kp -1.9142, Ki -0.36631`` with backward Euler),
and prints the overshoots at the rounded gains, the largest ``tau_d`` (0.001 pu grid) and the
largest ``tau_s`` at zero delay (0.005 pu grid, both by ``bench/section3c.py``'s scans). These
gentler gains tolerate much slower sampling than the paper's 0.25 pu (0.59 pu), and their
benchmark step settles (2 %) only about 10.8 pu after it, not within the 6 pu run. It takes
about 5 s.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import brentq, fsolve, least_squares, minimize
from section3c import largest_tau_d, largest_tau_s, markdown, rows  # beside this script

from core.record import loop_metrics
from plants.jcstr import JCSTR, JCSTRParams
from runtime.direct import simulate
from scenario import Scenario, load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "jcstr_benchmark.yaml"
END_TIME = 6.0  # pu; with 4.0 the slow PI tails cannot settle at the gains the figures need
A_B = 1.0
TJ0 = 143.0  # C, the paper's x30, made the equilibrium jacket temperature at (0.70 pu, 52 C)
H1, T1 = 0.70, 52.0  # first set points
U_MAX_T = 5.0  # F_jin limit
LEVEL_START = {"forward": (4.8, 2.4), "backward": (4.4, 2.5)}  # (-Kp, -Ki)/A_B
START = (7.0, 45.0, 0.1, 294.0, 0.03, 0.2)  # F_in, T_in, V_j, T_jin, Kp_T, Ti_T
DELAY_START = (2.5, 0.5)  # (-Kp, -Ki)/A_B, start of --delay-figure
DELAY_FIGURE = (10.8, 0.253, 25.0)  # benchmark OS %, tau_d-LC max pu, OS % there (III.C)
BOX = {
    "F_in": (0.5, 10.0),
    "T_in": (0.0, 50.0),
    "V_j": (0.05, 1.0),
    "T_jin": (180.0, 300.0),
    "Ti": (0.05, 2.0),
}
TAU_FAST_MIN = 0.065  # pu: 13 RK4 steps (max_step 0.005) per time constant, error < 1e-8
TS_GRID = (0.2, 0.25, 0.28, 0.29, 0.3, 0.31)
TD_GRID = (0.05, 0.08, 0.1, 0.12, 0.14, 0.16, 0.186, 0.2)

_BASE: dict[str, Any] = {}


# -- scenario building ---------------------------------------------------------------------------
def plant_params(
    F_in: float, T_in: float, V_j: float, T_jin: float, *, u_digits: int | None = None
) -> dict[str, float]:
    """Our parameter set from the four temperature knobs (``U`` from eq. (6) at x30 = 143 C)."""
    D = 2.0 * math.sqrt(A_B / math.pi)
    a_h = A_B + math.pi * D * H1
    U = F_in * (T1 - T_in) / ((TJ0 - T1) * a_h)
    if u_digits is not None:
        U = sig(U, u_digits)
    return dict(A_B=A_B, D=D, U=U, rho=1.0, C_p=1.0, V_j=V_j, F_in=F_in, T_in=T_in, T_jin=T_jin)


def _law(kp: float, ki: float, u_max: float, integration: str) -> dict[str, Any]:
    return dict(
        type="pi",
        Kp=kp,
        Ki=ki,
        u_min=0.0,
        u_max=u_max,
        integration=integration,
        feedforward="steady_state",
    )


def build(
    base: dict[str, Any],
    plant: dict[str, float],
    level: tuple[float, float],
    temp: tuple[float, float],
    integration: str,
    tau_s: dict[str, float] | None = None,
    tau_d: dict[str, float] | None = None,
) -> Scenario:
    """The benchmark with our plant, gains ``(Kp, Ki)`` per loop and optional timing changes."""
    d = dict(base)
    d["nodes"] = {k: dict(v) for k, v in base["nodes"].items()}
    d["loops"] = {k: dict(v) for k, v in base["loops"].items()}
    reactor = d["nodes"]["reactor"]
    reactor["params"] = dict(plant)
    _, u_bar = JCSTR(JCSTRParams(**plant)).equilibrium({"H": H1, "T": T1})
    reactor["u0"] = {"F_out": float(u_bar[0]), "F_jin": float(u_bar[1])}
    d["nodes"]["level_controller"] = {
        **base["nodes"]["level_controller"],
        "law": _law(*level, level_u_max(plant), integration),
    }
    d["nodes"]["temperature_controller"] = {
        **base["nodes"]["temperature_controller"],
        "law": _law(*temp, U_MAX_T, integration),
    }
    for field, values in (("tau_s", tau_s), ("tau_d", tau_d)):
        for loop, v in (values or {}).items():
            d["loops"][loop][field] = v
    return Scenario.model_validate(d)


def level_u_max(plant: dict[str, float]) -> float:
    """Outflow valve limit: twice the nominal flow ``F_in``, to 2 significant digits."""
    return sig(2.0 * plant["F_in"], 2)


def _init(base: dict[str, Any]) -> None:
    _BASE.clear()
    _BASE.update(base)


def _run(spec: tuple) -> tuple[float, float | None, bool, float, float]:
    """Temperature figures of one run: overshoot, settling, saturated?, deviation before the
    step, and the largest error over the run's last 0.1 pu in units of the 2 % band."""
    plant, level, temp, integration, tau_s, tau_d = spec
    try:
        with np.errstate(all="ignore"):  # a diverging trial run just scores badly
            rec = simulate(build(_BASE, plant, level, temp, integration, tau_s, tau_d))
    except (ValueError, FloatingPointError):
        return math.inf, None, True, math.inf, math.inf
    m = loop_metrics(rec, "temperature")
    u = np.array([v for v in rec.loops["temperature"].u if v is not None])
    t, T = rec.plants["reactor"].signal("T")
    pre = float(np.max(np.abs(T[(t >= 2.0) & (t < 2.4)] - T1)))
    os_pct = m["overshoot_pct"] if math.isfinite(m["overshoot_pct"]) else math.inf
    step = m["steps"][0]
    band = 0.02 * abs(step["to"] - step["from"])
    tail = float(np.max(np.abs(T[t >= t[-1] - 0.1] - step["to"]))) / band
    sat = bool(np.any(u <= 0.0) or np.any(u >= U_MAX_T))
    return os_pct, m["settling_time"], sat, pre, tail


def level_os(
    base: dict[str, Any],
    plant: dict[str, float],
    level: tuple[float, float],
    integration: str,
    **kw: dict[str, float],
) -> tuple[float, float | None]:
    with np.errstate(all="ignore"):  # unstable trial loops may drain the tank and diverge
        rec = simulate(build(base, plant, level, (0.0, 0.0), integration, **kw))
    m = loop_metrics(rec, "level")
    return m["overshoot_pct"], m["settling_time"]


def _fmt(v: float | None) -> str:
    return "no" if v is None else f"{v:.2f}"


# -- stage 1: level ------------------------------------------------------------------------------
def _level_ki(base: dict[str, Any], plant: dict[str, float], kp: float, integration: str) -> float:
    """``Ki/A_B`` (positive) giving the benchmark 10.8 % at ``Kp/A_B = kp`` (positive)."""

    def f(ki: float) -> float:
        return level_os(base, plant, (-kp * A_B, -ki * A_B), integration)[0] - 10.8

    return brentq(f, 0.05, kp * kp / 4.0, xtol=1e-8)


def _level_row(
    base: dict[str, Any], plant: dict[str, float], lev: tuple[float, float], integration: str
) -> str:
    sc = build(base, plant, lev, (0.0, 0.0), integration)
    os_b, st = level_os(base, plant, lev, integration)
    return (
        f"| {integration} | {-lev[0] / A_B:.4f} | {-lev[1] / A_B:.4f} | {os_b:.2f} | "
        f"{_fmt(st)} | "
        f"{level_os(base, plant, lev, integration, tau_s={'level': 0.25})[0]:.1f} | "
        f"{largest_tau_s(sc, 'level').largest} | {largest_tau_d(sc, 'level').largest} | "
        f"{level_os(base, plant, lev, integration, tau_d={'level': 0.253})[0]:.0f} |"
    )


def stage_level(
    base: dict[str, Any], plant: dict[str, float], chosen: str
) -> dict[str, tuple[float, float]]:
    """Level gains per integration rule: the two sampling figures if that settles, else the
    gentlest gains on the 10.8 % curve whose benchmark step settles within the run."""
    print("## Stage 1: level loop (depends only on Kp/A_B, Ki/A_B, integration rule, timing)\n")
    print(
        "Solve benchmark OS = 10.8 % and OS(tau_s = 0.25) = 24.9 %; if that step does not "
        f"settle (2 %) by end_time {base['end_time']:g} pu, raise Kp/A_B along the 10.8 % "
        "curve (steps of 0.05) until it does:\n"
    )
    head = (
        "| integration | Kp/A_B | Ki/A_B | bench OS | settling | OS tau_s .25 | "
        "largest tau_s | largest tau_d | OS tau_d .253 | note |\n" + "|---" * 10 + "|"
    )
    print(head)
    solved = {}
    for integration in ("forward", "backward"):

        def eqs(v: Sequence[float], integration: str = integration) -> list[float]:
            lev = (-v[0] * A_B, -v[1] * A_B)
            return [
                level_os(base, plant, lev, integration)[0] - 10.8,
                level_os(base, plant, lev, integration, tau_s={"level": 0.25})[0] - 24.9,
            ]

        kp, ki = fsolve(eqs, LEVEL_START[integration], xtol=1e-10)
        lev = (-kp * A_B, -ki * A_B)
        print(_level_row(base, plant, lev, integration) + " sampling pair |")
        while level_os(base, plant, lev, integration)[1] is None:
            kp += 0.05
            lev = (-kp * A_B, -_level_ki(base, plant, kp, integration) * A_B)
        if lev[0] != -kp * A_B or lev[1] != -ki * A_B:
            print(_level_row(base, plant, lev, integration) + " settles in the run |")
        solved[integration] = lev
    print(f"\nTrade-off along benchmark OS = 10.8 % ({chosen} Euler):\n")
    print(head)
    for kp in (2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0):
        lev = (-kp * A_B, -_level_ki(base, plant, kp, chosen) * A_B)
        print(_level_row(base, plant, lev, chosen) + " |")
    print()
    return solved


# -- --delay-figure: level gains for III.C's delay figure -----------------------------------------
def fit_delay_figure(
    base: dict[str, Any],
    plant: dict[str, float],
    integration: str,
    start: tuple[float, float] = DELAY_START,
) -> tuple[tuple[float, float], Any]:
    """Level gains ``(Kp, Ki)`` giving the benchmark 10.8 % and 25 % at ``tau_d`` = 0.253 pu.

    Solves the two overshoot equations (seed 000, III.C) by ``least_squares`` in
    ``(-Kp, -Ki)/A_B`` from ``start``, at the schedule's own step times. Returns the unrounded
    gains and the ``OptimizeResult``.
    """
    os_bench, td_max, os_td = DELAY_FIGURE

    def residuals(v: Sequence[float]) -> list[float]:
        lev = (-v[0] * A_B, -v[1] * A_B)
        return [
            level_os(base, plant, lev, integration)[0] - os_bench,
            level_os(base, plant, lev, integration, tau_d={"level": td_max})[0] - os_td,
        ]

    res = least_squares(
        residuals, start, bounds=([0.1, 0.01], [20.0, 20.0]), x_scale=(1.0, 0.2), xtol=1e-12
    )
    return (-res.x[0] * A_B, -res.x[1] * A_B), res


def delay_figure(base: dict[str, Any], integration: str) -> int:
    """``--delay-figure``: fit, round to 5 significant digits, print the figures at those gains."""
    plant = dict(base["nodes"]["reactor"]["params"])
    os_bench, td_max, os_td = DELAY_FIGURE
    print(
        f"## Level PI for III.C's delay figure ({integration} Euler integral, shipped plant, "
        f"end_time {base['end_time']:g} pu)\n"
    )
    print(
        f"least_squares: benchmark OS = {os_bench} % and OS(tau_d = {td_max} pu) = {os_td} %, "
        f"from (Kp, Ki)/A_B = {tuple(-v for v in DELAY_START)}\n"
    )
    (kp, ki), res = fit_delay_figure(base, plant, integration)
    print(
        f"{res.nfev} evaluations (+ {res.njev} Jacobians), status {res.status}, residuals "
        f"{res.fun[0]:+.2e} / {res.fun[1]:+.2e} pp: Kp {kp:.6f}, Ki {ki:.6f}\n"
    )
    lev = (sig(kp, 5), sig(ki, 5))
    sc = build(base, plant, lev, (0.0, 0.0), integration)
    bench, settle = level_os(base, plant, lev, integration)
    at_td = level_os(base, plant, lev, integration, tau_d={"level": td_max})[0]
    ts = largest_tau_s(sc, "level")
    td = largest_tau_d(sc, "level")
    print("| quantity | paper | ours |\n|---|---|---|")
    print(f"| level Kp, Ki (5 digits) | - | {lev[0]}, {lev[1]} |")
    settled = "not settled (2 %) by the end" if settle is None else f"settles in {settle:.2f} pu"
    print(f"| benchmark OS | {os_bench} % | {bench:.3f} % ({settled}) |")
    print(f"| OS at tau_d {td_max} pu | {os_td} % | {at_td:.3f} % |")
    print(
        f"| largest tau_d (0.001 pu grid) | {td_max} pu | {td.largest} pu "
        f"({td.os_at_largest:.2f} %) |"
    )
    print(
        f"| largest tau_s at zero delay (0.005 pu grid) | 0.25 pu (24.9 %) | "
        f"{ts.largest} pu ({ts.os_at_largest:.2f} %); first violation {ts.first_violation} pu "
        f"({ts.os_at_violation:.2f} %) |"
    )
    print(
        f"\nscenarios/jcstr_wncs.yaml level_controller.law: Kp {lev[0]}, Ki {lev[1]}, "
        f"u_max {level_u_max(plant):g}, integration {integration}"
    )
    return 0


# -- stage 2: temperature ------------------------------------------------------------------------
def _unpack(z: Sequence[float]) -> tuple[float, float, float, float, float, float]:
    return (
        math.exp(z[0]),
        z[1],
        math.exp(z[2]),
        TJ0 + math.exp(z[3]),
        math.exp(z[4]),
        math.exp(z[5]),
    )


def _pack(x: Sequence[float]) -> list[float]:
    return [
        math.log(x[0]),
        x[1],
        math.log(x[2]),
        math.log(x[3] - TJ0),
        math.log(x[4]),
        math.log(x[5]),
    ]


def fast_time_constant(plant: dict[str, float]) -> float:
    """Fastest time constant (pu) of the linearised (T, T_j) subsystem at (0.75 pu, 56 C)."""
    m = JCSTR(JCSTRParams(**plant))
    x, u = m.equilibrium({"H": 0.75, "T": 56.0})
    A, _ = m.jacobians(x, u)
    return float(min(-1.0 / np.linalg.eigvals(A[1:, 1:]).real))


def _box_penalty(x: Sequence[float], plant: dict[str, float]) -> float:
    F_in, T_in, V_j, T_jin, _, Ti = x
    pen = 0.0
    for name, v, scale in (
        ("F_in", F_in, 0.01),
        ("T_in", T_in, 0.1),
        ("V_j", V_j, 0.0005),
        ("T_jin", T_jin, 0.2),
        ("Ti", Ti, 0.001),
    ):
        lo, hi = BOX[name]
        pen += (max(0.0, lo - v, v - hi) / scale) ** 2
    pen += (max(0.0, TAU_FAST_MIN - fast_time_constant(plant)) / 0.0002) ** 2
    return pen


def _rough(v: Sequence[float]) -> float:
    return float(np.sum(np.diff(np.asarray(v), 2) ** 2))


class TemperatureFit:
    """Misfit of the temperature figures; runs are spread over a process pool."""

    def __init__(self, pool: ProcessPoolExecutor, level: tuple[float, float], integration: str):
        self.pool, self.level, self.integration = pool, level, integration
        self.evaluations = 0
        self.u_digits: int | None = None  # round U (stage 3)

    def figures(self, x: Sequence[float]) -> dict[str, Any] | None:
        F_in, T_in, V_j, T_jin, kp, Ti = x
        plant = plant_params(F_in, T_in, V_j, T_jin, u_digits=self.u_digits)
        try:
            JCSTR(JCSTRParams(**plant)).equilibrium({"H": 0.75, "T": 56.0})
            if fast_time_constant(plant) < 0.5 * TAU_FAST_MIN:
                return None  # too stiff for the RK4 step of the engine
        except ValueError:
            return None
        temp = (kp, kp / Ti)
        specs = [(plant, self.level, temp, self.integration, None, None)]
        specs += [
            (plant, self.level, temp, self.integration, {"temperature": v}, None) for v in TS_GRID
        ]
        specs += [
            (plant, self.level, temp, self.integration, None, {"temperature": v}) for v in TD_GRID
        ]
        specs.append(
            (
                plant,
                self.level,
                temp,
                self.integration,
                {"temperature": 0.185},
                {"temperature": 0.1},
            )
        )
        res = list(self.pool.map(_run, specs))
        self.evaluations += 1
        return dict(
            plant=plant,
            bench=res[0],
            ts=res[1 : 1 + len(TS_GRID)],
            td=res[1 + len(TS_GRID) : -1],
            A=res[-1],
        )

    def cost(self, x: Sequence[float]) -> float:
        f = self.figures(x)
        if f is None:
            return 1e6
        ts = [r[0] for r in f["ts"]]
        td = [r[0] for r in f["td"]]
        if not all(map(math.isfinite, [f["bench"][0], f["A"][0], *ts, *td])):
            return 1e5
        ots, otd = dict(zip(TS_GRID, ts, strict=True)), dict(zip(TD_GRID, td, strict=True))
        c = ((f["bench"][0] - 11.0) / 0.1) ** 2 + ((ots[0.3] - 28.5) / 1.5) ** 2
        c += ((otd[0.14] - 25.0) / 2.0) ** 2 + ((otd[0.1] - 23.0) / 3.0) ** 2
        c += ((otd[0.186] - 28.9) / 3.0) ** 2 + ((f["A"][0] - 25.0) / 3.0) ** 2
        c += 0.05 * (_rough(ts) + _rough(td))
        for seq in (ts, td):  # monotone in tau_s and tau_d
            c += sum(max(0.0, a - b) ** 2 for a, b in zip(seq, seq[1:], strict=False))
        c += 5.0 * sum(r[2] for r in (f["bench"], *f["ts"][:5]))  # saturation up to tau_s 0.3
        c += 5.0 * sum(max(0.0, r[3] - 0.5) for r in (f["bench"], *f["ts"][:5]))  # cycling
        if f["bench"][1] is None:  # must settle within the run; the tail error guides there
            c += 10.0 + 50.0 * max(0.0, f["bench"][4] - 0.8) ** 2
        return c + _box_penalty(x, f["plant"])

    def report(self, x: Sequence[float]) -> str:
        f = self.figures(x)
        if f is None:
            return "infeasible"
        return (
            f"bench {f['bench'][0]:.2f} % (settles {_fmt(f['bench'][1])}); tau_s "
            + ", ".join(f"{v:g}: {r[0]:.1f}" for v, r in zip(TS_GRID, f["ts"], strict=True))
            + "; tau_d "
            + ", ".join(f"{v:g}: {r[0]:.1f}" for v, r in zip(TD_GRID, f["td"], strict=True))
            + f"; point A {f['A'][0]:.1f}"
        )


def screen(fit: TemperatureFit, n: int, seed: int = 0) -> tuple[float, ...]:
    """Seeded random screening of the box: per point, Kp for the 11 % benchmark, then the misfit."""
    rng = np.random.default_rng(seed)
    best, best_x = math.inf, START
    for _ in range(n):
        F_in = math.exp(rng.uniform(*np.log(BOX["F_in"])))
        T_in = rng.uniform(*BOX["T_in"])
        V_j = math.exp(rng.uniform(*np.log(BOX["V_j"])))
        T_jin = rng.uniform(*BOX["T_jin"])
        Ti = math.exp(rng.uniform(*np.log(BOX["Ti"])))
        plant = plant_params(F_in, T_in, V_j, T_jin)
        try:
            if fast_time_constant(plant) < TAU_FAST_MIN:
                continue
        except ValueError:
            continue

        def b(kp: float, plant: dict[str, float] = plant, Ti: float = Ti) -> float:
            return _run((plant, fit.level, (kp, kp / Ti), fit.integration, None, None))[0] - 11.0

        kps = np.geomspace(0.002, 3.0, 16)
        vals = list(
            fit.pool.map(
                _run, [(plant, fit.level, (k, k / Ti), fit.integration, None, None) for k in kps]
            )
        )
        for k0, k1, v0, v1 in zip(kps, kps[1:], vals, vals[1:], strict=False):
            if v0[0] < 11.0 <= v1[0]:
                x = (F_in, T_in, V_j, T_jin, brentq(b, k0, k1, xtol=1e-5), Ti)
                c = fit.cost(x)
                if c < best:
                    best, best_x = c, x
                    print(f"  screen: cost {c:.2f} at {tuple(round(v, 4) for v in x)}")
                break
    return best_x


def sig(v: float, n: int) -> float:
    """``v`` rounded to ``n`` significant digits."""
    return float(f"{v:.{n - 1}e}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--integration",
        choices=("forward", "backward"),
        default="backward",
        help="PI integral rule of both loops (backward fits better, see docstring)",
    )
    parser.add_argument("--maxfev", type=int, default=400, help="Nelder-Mead evaluations, stage 2")
    parser.add_argument("--screen", type=int, default=0, help="random screening points first")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--end-time",
        type=float,
        default=END_TIME,
        help="run length, pu (default 6.0, as the scenario)",
    )
    parser.add_argument(
        "--start",
        type=float,
        nargs=6,
        default=None,
        metavar=("F_in", "T_in", "V_j", "T_jin", "Kp", "Ti"),
        help="stage-2 starting point (default START)",
    )
    parser.add_argument(
        "--delay-figure",
        action="store_true",
        help="only fit the level PI to III.C's delay figure (10.8 %% at the benchmark, 25 %% at "
        "tau_d 0.253 pu), the gains of scenarios/jcstr_wncs.yaml; see docstring",
    )
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    base = load_scenario(SCENARIO).model_dump()
    base["end_time"] = args.end_time
    if args.delay_figure:
        code = delay_figure(base, args.integration)
        print(f"\n({time.perf_counter() - t0:.0f} s)")
        return code
    _init(base)  # the screening's root finding also runs here
    integration = args.integration

    start_plant = plant_params(*START[:4])
    solved = stage_level(base, start_plant, integration)
    level = tuple(sig(v, 4) for v in solved[integration])

    print(f"## Stage 2: temperature loop ({integration} Euler integral), level gains {level}\n")
    with ProcessPoolExecutor(args.workers, initializer=_init, initargs=(base,)) as pool:
        fit = TemperatureFit(pool, level, integration)
        x0 = tuple(args.start) if args.start else START
        x0 = screen(fit, args.screen) if args.screen else x0
        print(f"start {x0}: cost {fit.cost(x0):.3f}")
        res = minimize(
            lambda z: fit.cost(_unpack(z)),
            _pack(x0),
            method="Nelder-Mead",
            options=dict(maxfev=args.maxfev, xatol=1e-4, fatol=1e-3, adaptive=True),
        )
        x = _unpack(res.x)
        print(
            f"Nelder-Mead ({fit.evaluations} evaluations): cost {res.fun:.3f} at "
            f"F_in {x[0]:.4f}, T_in {x[1]:.3f}, V_j {x[2]:.4f}, T_jin {x[3]:.2f}, "
            f"Kp {x[4]:.5f}, Ti {x[5]:.4f}"
        )
        print("  " + fit.report(x) + "\n")

        print("## Stage 3: round the plant (3 digits), re-fit and round the gains (4 digits)\n")
        xr = [sig(v, 3) for v in x[:4]]
        fit.u_digits = 4

        def gain_cost(g: Sequence[float]) -> float:
            return fit.cost((*xr, math.exp(g[0]), math.exp(g[1])))

        res_g = minimize(
            gain_cost,
            [math.log(x[4]), math.log(x[5])],
            method="Nelder-Mead",
            options=dict(maxfev=80, xatol=1e-5, fatol=1e-4),
        )
        kp_t = sig(math.exp(res_g.x[0]), 4)
        ki_t = sig(kp_t / math.exp(res_g.x[1]), 4)
        final = (*xr, kp_t, kp_t / ki_t)
        print(f"cost {fit.cost(final):.3f}: " + fit.report(final) + "\n")

    plant = plant_params(*xr, u_digits=4)
    sc = build(base, plant, level, (kp_t, ki_t), integration)
    reactor = sc.nodes["reactor"]
    print("Final values (scenarios/jcstr_benchmark.yaml):\n")
    for k, v in plant.items():
        print(f"  {k}: {v!r}")
    print(f"  u0: F_out {reactor.u0['F_out']:.4g}, F_jin {reactor.u0['F_jin']:.4g}")
    print(
        f"  level law: Kp {level[0]}, Ki {level[1]}, u_max {level_u_max(plant):g}, "
        f"integration {integration}"
    )
    print(f"  temperature law: Kp {kp_t}, Ki {ki_t}, u_max {U_MAX_T:g}, integration {integration}")
    print(f"  end_time: {args.end_time}")
    print(f"  fastest time constant at (0.75, 56): {fast_time_constant(plant):.4f} pu\n")
    table, notes = rows(sc)
    print(markdown(table) + "\n")
    for note in notes:
        print(f"- {note}")
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
