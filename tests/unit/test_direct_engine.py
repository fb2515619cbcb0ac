"""The direct engine against independent computations.

* The level loop is linear (``dH/dt = (F_in - F_out)/A_B``), so under zero-order hold the level
  is piecewise linear in time and the sampled loop can be computed exactly by hand, with the
  sensor-path delay not a multiple of the sampling period.
* The temperature trace is checked by replaying the recorded control moves into scipy's
  adaptive solver and sampling it at the recorded instants.
* The benchmark overshoots are the paper's (seed 000, section III.C).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from core.record import summarize
from core.time import to_ticks, to_units
from runtime.direct import simulate
from scenario import load_scenario
from tests.conftest import BENCHMARK, PAPER_OS_LEVEL, PAPER_OS_TEMPERATURE

CASES = {"benchmark": {}, "tau_s 0.25, level delay 0.17": {"tau_s": 0.25, "tau_d": 0.17}}


def _scenario(case):
    s = load_scenario(BENCHMARK)
    over = CASES[case]
    if over:
        s = s.with_loops(
            tau_s={"level": over["tau_s"], "temperature": over["tau_s"]},
            tau_d={"level": over["tau_d"]},
        )
    return s


def _level_by_hand(s):
    """Exact event simulation of the sampled level loop (PI with the scenario's integration
    rule, clamping anti-windup)."""
    plant = s.nodes["reactor"]
    p = plant.params
    loop = s.loops["level"]
    law = s.nodes[loop.controller].law
    tau_s, tau_d, end = to_ticks(loop.tau_s), to_ticks(loop.tau_d), to_ticks(s.end_time)
    changes = sorted((to_ticks(c.t), c.value) for c in s.setpoints if c.loop == "level")
    h, t_h, u_held = plant.x0["H"], 0, plant.u0["F_out"]
    applied = []  # (t, u) pending
    samples = []  # (t_deliver, y)
    out_t, out_y, out_u = [], [], []
    integral, t_prev, e_prev = 0.0, None, 0.0
    events = sorted(
        {k * tau_s for k in range(end // tau_s + 1)}
        | {k * tau_s + tau_d for k in range(end // tau_s + 1) if k * tau_s + tau_d <= end}
    )
    for t in events:
        h += (p["F_in"] - u_held) * to_units(t - t_h) / p["A_B"]
        t_h = t
        if t % tau_s == 0:
            samples.append((t + tau_d, h))
        while samples and samples[0][0] == t:
            _, y = samples.pop(0)
            r = loop.setpoint
            for tc, v in changes:
                if tc <= t:
                    r = v
            e = r - y
            e_int = e_prev if law.integration == "forward" else e
            inc = 0.0 if t_prev is None else law.Ki * e_int * (to_units(t) - to_units(t_prev))
            v = p["F_in"] + law.Kp * e + integral + inc
            if (v > law.u_max and inc > 0) or (v < law.u_min and inc < 0):
                inc = 0.0
            integral += inc
            u = min(max(p["F_in"] + law.Kp * e + integral, law.u_min), law.u_max)
            t_prev, e_prev = t, e
            out_t.append(t)
            out_y.append(y)
            out_u.append(u)
            applied.append((t, u))
        while applied and applied[0][0] == t:
            u_held = applied.pop(0)[1]
    return out_t, out_y, out_u


@pytest.mark.parametrize("case", list(CASES))
def test_level_loop_matches_exact_sampled_solution(case):
    s = _scenario(case)
    rec = simulate(s).loops["level"]
    t, y, u = _level_by_hand(s)
    assert rec.t == t
    assert_allclose(rec.y, y, rtol=0, atol=1e-9)
    assert_allclose(rec.u, u, rtol=0, atol=1e-9)


@pytest.mark.parametrize("case", list(CASES))
def test_temperature_trace_matches_adaptive_replay(case):
    s = _scenario(case)
    rec = simulate(s)
    plant_cfg = s.nodes["reactor"]
    model = plant_cfg.build()
    # all input changes from the record: (t, index, value)
    changes = []
    for name, lp in rec.loops.items():
        idx = model.input_names.index(s.loops[name].actuator)
        delay = to_ticks(s.loops[name].tau_a)
        changes += [(t + delay, idx, u) for t, u in zip(lp.t, lp.u, strict=True)]
    changes.sort()
    temp = rec.loops["temperature"]
    sample_times = sorted(set(temp.t_sampled))
    x = np.array([plant_cfg.x0[n] for n in model.state_names])
    u = np.array([plant_cfg.u0[n] for n in model.input_names])
    t_now, got = 0, {}
    stops = sorted({c[0] for c in changes} | set(sample_times))
    for t in stops:
        if t > t_now:
            sol = solve_ivp(
                lambda tt, xx, uu=tuple(u): model.rhs(tt, xx, np.array(uu)),
                (to_units(t_now), to_units(t)),
                x,
                rtol=1e-11,
                atol=1e-11,
            )
            x, t_now = sol.y[:, -1], t
        if t in sample_times:
            got[t] = x[1]
        for tc, idx, val in changes:
            if tc == t:
                u[idx] = val
    # fixed-step RK4 (max_step 0.005 pu) against an adaptive solver at 1e-11: 1e-7 relative
    assert_allclose(temp.y, [got[t] for t in temp.t_sampled], rtol=1e-7)


def test_benchmark_overshoots_match_the_paper():
    summary = summarize(simulate(load_scenario(BENCHMARK)))
    assert summary["loops"]["level"]["overshoot_pct"] == pytest.approx(PAPER_OS_LEVEL, abs=1.0)
    assert summary["loops"]["temperature"]["overshoot_pct"] == pytest.approx(
        PAPER_OS_TEMPERATURE, abs=1.0
    )
    for loop in summary["loops"].values():
        assert loop["settling_time"] is not None
        assert len(loop["steps"]) == 1


def test_trace_contract():
    s = load_scenario(BENCHMARK)
    summary = summarize(simulate(s))
    for name, loop in summary["loops"].items():
        tr = loop["trace"]
        n = round(s.end_time / s.loops[name].tau_s) + 1  # 0, tau_s, ..., end_time
        assert len(tr["t"]) == len(tr["y"]) == len(tr["u"]) == n
        assert tr["t"] == sorted(tr["t"])
