"""Multi-loop controllers (one law for several loops: seed 003's MRAC) on the direct engine, the
registered plants of seed 003, and what the scenario refuses.

The direct engine's runs are checked against computations that share no code with it: the
thesis's test against a loop integrating the plant with ``solve_ivp`` from the thesis plant's own
draws (:class:`plants.column.PerturbedReducedPlant`), the non-linear column against
``bench/mrac_study.py``'s ``column_run``, and the hold rule against the static law it reduces to
at ``gamma = 0`` (``u = M0 u_c - L0 x``), recomputed from the delivered samples.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from types import ModuleType

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from controllers.mrac import MRAC, THESIS_A0, THESIS_B0, MRACConfig, replay
from core.errors import ConfigError
from core.time import to_ticks, to_units
from plants import registry
from plants.column import FITTED_PARAMS, Column, PerturbedReducedPlant, balanced_reduction
from plants.column_plant import ColumnPlant
from plants.perturbed_reduced import PerturbedReduced, PerturbedReducedParams
from runtime.direct import simulate
from runtime.executions import multi_loop_executions
from scenario import load_scenario
from tests.conftest import ROOT, SCENARIOS, write_variant

THESIS = SCENARIOS / "column_mrac.yaml"
NONLINEAR = SCENARIOS / "column_mrac_nonlinear.yaml"
WSN = SCENARIOS / "column_mrac_wsn.yaml"
T = 0.1  # h, the thesis's sampling period


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    """``bench/mrac_study.py`` (a script beside the package, loaded from its path)."""
    name = "bench_mrac_study"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / "mrac_study.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def _by_loop(rec, loops, field):
    return np.array([getattr(rec.loops[n], field) for n in loops], dtype=float).T


# -- the registered plants ------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 7])
def test_perturbed_reduced_passes_through_the_thesis_plants(seed):
    """At t = k T the plant is the k-th plant PerturbedReducedPlant draws (the plant of step k of
    discrete_run); between draws it ramps; without redraws it is draw 0 throughout."""
    model = PerturbedReduced(PerturbedReducedParams(seed=seed, redraw_period=T))
    fixed = PerturbedReduced(PerturbedReducedParams(seed=seed))
    ref = PerturbedReducedPlant(np.random.default_rng(seed))
    a0, b0 = ref.A.copy(), ref.B.copy()
    prev = None
    for k in range(40):
        a, b = model.matrices(to_units(to_ticks(k * T)))
        assert_allclose(a, ref.A, rtol=1e-15, atol=1e-16)
        assert_allclose(b, ref.B, rtol=1e-15, atol=1e-16)
        if prev is not None:
            am, bm = model.matrices(to_units(to_ticks((k - 0.5) * T)))
            assert_allclose(am, 0.5 * (prev[0] + ref.A), atol=1e-15)
            assert_allclose(bm, 0.5 * (prev[1] + ref.B), atol=1e-15)
        prev = (ref.A.copy(), ref.B.copy())
        assert_allclose(fixed.matrices(k * T + 0.03)[0], a0, atol=0)
        assert_allclose(fixed.matrices(k * T + 0.03)[1], b0, atol=0)
        ref.draw()
    x, u = np.array([0.02, -0.03]), np.array([0.4, -0.2])
    a, b = model.matrices(1.234)
    assert_allclose(model.rhs(1.234, x, u), a @ x + b @ u, atol=1e-16)


def test_perturbed_reduced_is_a_pure_function_of_time():
    """Same derivatives in any evaluation order (what makes the engines agree bit for bit); the
    additive disturbance is continuous and has the configured spread."""
    p = PerturbedReducedParams(seed=3, redraw_period=T, d_std=(0.02, 0.05), d_period=0.05)
    ts = np.linspace(0.0, 30.0, 1501)
    x, u = (0.01, -0.02), (0.3, 0.1)
    fwd = [PerturbedReduced(p).rhs_tuple(t, x, u) for t in ts]
    other = PerturbedReduced(p)
    back = [other.rhs_tuple(t, x, u) for t in ts[::-1]][::-1]
    assert fwd == back
    knots = np.array([other.disturbance(k * p.d_period) for k in range(4000)])
    assert_allclose(knots.std(axis=0), p.d_std, rtol=0.06)
    left = other.disturbance(7 * p.d_period - 1e-9)
    assert_allclose(left, other.disturbance(7 * p.d_period), atol=1e-6)


def test_column_plant_measures_every_stage():
    plant = registry.build("column", FITTED_PARAMS.model_dump())
    col = Column(FITTED_PARAMS)
    assert isinstance(plant, ColumnPlant) and plant.output_names == plant.state_names
    x = col.steady_state()
    u = np.array([76.0, 70.5])
    assert_allclose(plant.rhs(0.0, x, u), col.rhs(0.0, x, u), atol=0)
    assert plant.outputs(x)[-1] == col.outputs(x)[0] and plant.outputs(x)[0] == col.outputs(x)[1]
    xe, ue = plant.equilibrium({"x16": 0.985, "x1": 0.015})
    xc, uc = col.equilibrium({"x_D": 0.985, "x_B": 0.015})
    assert_allclose(xe, xc, atol=0) and assert_allclose(ue, uc, atol=0)
    with pytest.raises(ValueError, match="x16"):
        plant.equilibrium({"x1": 0.015})


# -- the thesis's test and the column on the direct engine ----------------------------------------
def test_thesis_test_on_the_direct_engine_equals_an_independent_loop():
    """column_mrac.yaml on the direct engine against the thesis loop written out here: the MRAC
    executed at k T on the state, the plant integrated between samples by solve_ivp (DOP853,
    rtol 1e-13) through the thesis plant's draws, ramped, with the scenario's reference steps.
    Measured: states within 9.4e-11 (of 0.041), moves within 1.9e-10 (of 0.55), the RK4 error."""
    scenario = load_scenario(THESIS)
    rec = simulate(scenario)
    loops = ("x1", "x2")
    x_direct, u_direct = _by_loop(rec, loops, "y"), _by_loop(rec, loops, "u")
    n = 200
    draws = PerturbedReducedPlant(np.random.default_rng(0))
    knots = []
    for _ in range(n + 2):
        knots.append((draws.A.copy(), draws.B.copy()))
        draws.draw()
    ctrl = MRAC(MRACConfig(gamma=100.0, T=T, A0=THESIS_A0, B0=THESIS_B0))
    x = np.zeros(2)
    xs, us = [], []
    for k in range(n + 1):
        t = k * T
        u_c = np.array([0.5 if k < 100 else -0.5, 0.1])
        u = ctrl.step(t, x, u_c)
        xs.append(x)
        us.append(u)
        if k == n:
            break
        (a0, b0), (a1, b1) = knots[k], knots[k + 1]

        def f(s, z, t=t, a0=a0, a1=a1, b0=b0, b1=b1, u=u):
            r = (s - t) / T
            return (a0 + r * (a1 - a0)) @ z + (b0 + r * (b1 - b0)) @ u

        x = solve_ivp(f, (t, t + T), x, method="DOP853", rtol=1e-13, atol=1e-16).y[:, -1]
    assert rec.loops["x1"].t == rec.loops["x2"].t == [to_ticks(k * T) for k in range(n + 1)]
    assert_allclose(x_direct, np.array(xs), rtol=0, atol=1e-9)
    assert_allclose(u_direct, np.array(us), rtol=0, atol=2e-9)


def test_nonlinear_column_on_the_direct_engine_equals_bench_column_run(bench):
    """column_mrac_nonlinear.yaml on the direct engine against bench/mrac_study.py's own loop
    (amplitude 1, gamma 100, measured outputs): the same moves and measurements to 1e-12
    (measured 2.8e-14 kmol/h: the float difference of k*0.1 h and k*100000 ticks).

    Two checks, kept apart because their tolerances have different grounds:

    - The scenario states the balanced reduction and the steady state; recomputing them is a
      *different* computation (Lyapunov solves, SVDs and a Newton solve, whose last bits depend
      on the BLAS kernels the CPU selects). Rounding perturbs the Gramians of the 16-state
      Jacobian by about ``n kappa(J) eps = 16 * 515 * 2.2e-16 = 1.8e-12`` relative, and the kept
      balanced directions move by that over the relative Hankel gap ``(s2 - s3) / s1 = 0.23``:
      about 8e-12. The reduction is checked at ``rtol=1e-10`` (a decade of margin; measured
      1.8e-16 on one machine, 1.1e-14 on another). The steady state is a root of ``f(x) = 0``
      with ``kappa(J) = 515``: ``kappa eps = 1.1e-13``, checked at ``rtol=1e-12``.
    - The run comparison then hands the bench loop the scenario's own stated matrices, so both
      engines integrate the same numbers and only the time bookkeeping differs (2.8e-14).
    """
    col = Column(FITTED_PARAMS)
    xs, us = col.steady_state(), col.nominal_input()
    jx, ju = col.jacobian(xs, us)
    c = np.zeros((2, 16))
    c[0, 15], c[1, 0] = 1.0, 1.0
    red = balanced_reduction(jx, ju, c, 2, "matchdc")
    scenario = load_scenario(NONLINEAR)
    law = scenario.nodes["mrac"].law
    assert_allclose(np.array(law.A_m), red.A, rtol=1e-10)  # the scenario states the reduction
    assert_allclose(np.array(law.B_m), red.B, rtol=1e-10)
    assert_allclose(np.array(law.C_m), red.C, rtol=1e-10)
    assert_allclose(law.y_bar, col.outputs(xs), rtol=1e-12)
    x0 = scenario.nodes["column"].x0
    assert_allclose([x0[f"x{i}"] for i in range(1, 17)], xs, rtol=1e-12)
    stated = replace(red, A=np.array(law.A_m), B=np.array(law.B_m), C=np.array(law.C_m))
    ref = bench.column_run(col, stated, 100.0, amp=1.0)
    rec = simulate(scenario)
    loops = ("top", "bottom")
    assert not ref["diverged"]
    assert_allclose(_by_loop(rec, loops, "u"), ref["u"], rtol=0, atol=1e-12)
    assert_allclose(_by_loop(rec, loops, "y"), ref["y"] + col.outputs(xs), rtol=0, atol=1e-12)


def test_replayed_law_reproduces_the_moves_of_a_wsn_run():
    """Over the WSN the two samples of a period arrive apart: the law runs at each arrival with
    the other loop's last sample held. Rebuilding the executions from the record and feeding them
    to a fresh MRAC gives every recorded move exactly (adaptation on, losses, jitter)."""
    scenario = load_scenario(WSN)
    rec = simulate(scenario)
    loops = scenario.nodes["mrac"].loops
    execs = multi_loop_executions(scenario, rec, "mrac")
    tr = replay(scenario.nodes["mrac"].law, loops, [(to_units(e.t), e.y, e.r) for e in execs])
    assert len(execs) > 1.8 * 601  # about two executions per sampling period
    assert rec.loops["bottom"].lost > 0
    at = {e.t: k for k, e in enumerate(execs)}
    checked = 0
    for i, name in enumerate(loops):
        lr = rec.loops[name]
        for t, u in zip(lr.t, lr.u, strict=True):
            if u is not None:
                assert tr["u"][at[t], i] == u
                checked += 1
    assert checked > 1000
    assert_allclose(tr["x"] - tr["x_m"], tr["e"], atol=1e-15)


def _static_variant(tmp_path, name, edit):
    """column_mrac.yaml with gamma = 0 (u = M0 u_c - L0 x exactly) and ``edit`` applied."""

    def change(d):
        d["nodes"]["mrac"]["law"]["gamma"] = 0.0
        d["end_time"] = 12.0
        edit(d)

    return load_scenario(write_variant(tmp_path, THESIS, name, change))


def _static_law(scenario):
    m = MRAC(scenario.nodes["mrac"].law)
    return m.L, m.M


def _setpoint(changes, t):
    return [v for tc, v in changes if tc <= t][-1]


def test_hold_rule_over_a_jittery_lossy_network(tmp_path):
    """Samples overtaking each other and lost: the law executes at every arrival once both loops
    have delivered, with each loop's newest sample (by sampling time), a stale one ignored."""

    def wsn(d):
        d["nodes"]["network"] = {
            "kind": "gateway",
            "topology": {
                "nodes": {
                    "s1": {"kind": "sensor"},
                    "s2": {"kind": "sensor"},
                    "gw": {"kind": "gateway"},
                },
                "retry_limit": 0,
                "delay": {"type": "exponential", "base": 0.01, "mean": 0.08},
                "links": [{"a": "s1", "b": "gw", "prr": 0.85}, {"a": "s2", "b": "gw", "prr": 0.9}],
            },
        }
        d["loops"]["x1"]["sensor_node"] = "s1"
        d["loops"]["x2"]["sensor_node"] = "s2"
        d["loops"]["x2"]["tau_s"] = 0.15

    scenario = _static_variant(tmp_path, "jitter.yaml", wsn)
    rec = simulate(scenario)
    big_l, big_m = _static_law(scenario)
    loops = ("x1", "x2")
    arrivals = sorted(
        (t, ts, y, i, n)
        for i, n in enumerate(loops)
        for t, y, ts in zip(rec.loops[n].t, rec.loops[n].y, rec.loops[n].t_sampled, strict=True)
    )
    first_both = max(min(rec.loops[n].t) for n in loops)
    stale = 0
    checked = 0
    for name_i, name in enumerate(loops):
        lr = rec.loops[name]
        for t, u in zip(lr.t, lr.u, strict=True):
            if t < first_both:
                assert u is None  # no move before every loop has delivered
                continue
            held = {}
            for ta, ts, y, i, _ in arrivals:
                if ta <= t and (i not in held or ts >= held[i][0]):
                    held[i] = (ts, y)
            x = np.array([held[0][1], held[1][1]])
            u_c = np.array([_setpoint(rec.loops[n].setpoints, t) for n in loops])
            assert u == pytest.approx((big_m @ u_c - big_l @ x)[name_i], abs=1e-14)
            checked += 1
    for n in loops:
        lr = rec.loops[n]
        newest = -1
        for ts in lr.t_sampled:
            stale += ts < newest
            newest = max(newest, ts)
    assert checked > 150 and stale > 0
    assert rec.loops["x1"].lost > 0 and rec.loops["x2"].lost > 0


def test_delayed_and_zero_delay_samples_at_one_instant_execute_twice(tmp_path):
    """x2's sample travels one period (delayed), x1's none: both arrive at every k T, x2's in
    the instant's first round, x1's a round later. The law executes twice per instant, first with
    the new x2 and the held x1 (both taken at (k-1) T), then with the new x1. Each sample is
    recorded with the first move of its loop at its instant (as a bus history pairs them)."""

    def delayed(d):
        d["loops"]["x2"]["tau_d"] = 0.1

    scenario = _static_variant(tmp_path, "mixed.yaml", delayed)
    rec = simulate(scenario)
    big_l, big_m = _static_law(scenario)
    execs = multi_loop_executions(scenario, rec, "mrac")
    assert [e.t for e in execs[:5]] == [to_ticks(v) for v in (0.1, 0.1, 0.2, 0.2, 0.3)]
    x1, x2 = rec.loops["x1"], rec.loops["x2"]
    assert x1.u[0] is None  # x1 alone at t = 0: nothing executes
    for k in range(1, 100):
        t = x1.t[k]
        assert x2.t[k - 1] == t and x2.t_sampled[k - 1] == x1.t_sampled[k - 1]
        first = np.array([x1.y[k - 1], x2.y[k - 1]])  # batch 1: x2 of (k-1)T, x1 held
        u_c = np.array([_setpoint(x1.setpoints, t), _setpoint(x2.setpoints, t)])
        u1 = big_m @ u_c - big_l @ first
        assert x2.u[k - 1] == pytest.approx(u1[1], abs=1e-14)
        assert x1.u[k] == pytest.approx(u1[0], abs=1e-14)
        second = np.array([x1.y[k], x2.y[k - 1]])  # batch 2: the new x1
        ex = execs[2 * k - 1]
        assert ex.t == t and [ex.y["x1"], ex.y["x2"]] == second.tolist()


# -- what the scenario refuses --------------------------------------------------------------------
def _law(**kw):
    return lambda d: d["nodes"]["mrac"]["law"].update(kw)


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (_law(gamma=-1.0), "nodes.mrac.controller.law.mrac.gamma: Input should be greater than "),
        (_law(T=0.0), "nodes.mrac.controller.law.mrac.T: Input should be greater than 0"),
        (_law(T=-0.1), "nodes.mrac.controller.law.mrac.T: Input should be greater than 0"),
        (
            _law(B0=[[-0.14, 0.2], [0.07, -0.1]]),
            "nodes.mrac.controller.law.mrac: B0: compatibility condition (4.13)-(4.14): B is "
            "singular",
        ),
        (
            lambda d: (
                d["nodes"]["mrac"]["law"].pop("B0"),
                d["nodes"]["mrac"]["law"].update(B_m=[[1.0, 2.0], [2.0, 4.0]]),
            ),
            "law.mrac: B_m (B0 not given: the nominal B is B_m): compatibility condition",
        ),
        (
            lambda d: d["loops"]["x2"].update(tau_s=0.0),
            "loops.x2.tau_s: Input should be greater than 0",
        ),
        (
            lambda d: d["nodes"]["plant"]["params"].update(redraw_period=-0.1),
            "nodes.plant.plant: params.redraw_period: Input should be greater than 0",
        ),
    ],
)
def test_bad_mrac_input_is_refused_naming_file_and_field(tmp_path, edit, expected):
    path = write_variant(tmp_path, THESIS, "bad.yaml", edit)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert f"{path}: " in str(err.value) and expected in str(err.value), str(err.value)


def _ctrl(**kw):
    def edit(d):
        node = d["nodes"]["mrac"]
        for k, v in kw.items():
            if v is None:
                node.pop(k)
            else:
                node[k] = v

    return edit


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (_ctrl(loop="x1"), "nodes.mrac.controller: loops: give either loop: (one loop) or loops:"),
        (_ctrl(loops=None), "nodes.mrac.controller: loops: a controller names its loop"),
        (
            _ctrl(loops=None, loop="x1"),
            "nodes.mrac.controller: loop: law 'mrac' controls several loops at once",
        ),
        (_ctrl(loops=["x1"]), "controls exactly 2 loops (x_i measured, u_i moved, u_c,i the"),
        (_ctrl(loops=["x1", "x1"]), "loops: a loop is named twice"),
        (_ctrl(loops=["x1", "x3"]), "nodes.mrac.loops[1]: unknown loop 'x3' (loops: ['x1', 'x2'])"),
        (
            _ctrl(law={"type": "pi", "Kp": 1.0, "Ki": 1.0}),
            "nodes.mrac.controller: loops: law 'pi' controls one loop; name it with loop:",
        ),
        (
            lambda d: d["nodes"].update(
                other={"kind": "controller", "loop": "x2", "law": {"type": "pi", "Kp": 1, "Ki": 1}}
            ),
            "nodes.other.loop: no loop names 'other' as its controller",
        ),
        (
            lambda d: (
                d["loops"]["x2"].update(controller="other")
                or d["nodes"].update(
                    other={
                        "kind": "controller",
                        "loop": "x2",
                        "law": {"type": "pi", "Kp": 1, "Ki": 1},
                    }
                )
            ),
            "nodes.mrac.loops[1]: loop 'x2' names 'other' as its controller",
        ),
    ],
)
def test_controller_loop_lists_are_checked(tmp_path, edit, expected):
    path = write_variant(tmp_path, THESIS, "bad.yaml", edit)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert expected in str(err.value), str(err.value)


def test_a_coordination_agent_does_not_govern_a_multi_loop_controller(tmp_path):
    def one_mrac(d):
        for name in ("level_controller", "temperature_controller"):
            del d["nodes"][name]
        d["nodes"]["mrac"] = {"kind": "controller", "loops": ["level", "temperature"],
                              "law": {"type": "mrac", "gamma": 1.0, "T": 0.1}}  # fmt: skip
        for loop in d["loops"].values():
            loop["controller"] = "mrac"

    path = write_variant(tmp_path, SCENARIOS / "jcstr_wncs.yaml", "agent.yaml", one_mrac)
    with pytest.raises(ConfigError, match=r"nodes.mrac.loops: the coordination agent simulates"):
        load_scenario(path)


def test_single_and_multi_loop_controllers_survive_a_dump(tmp_path):
    """What the launcher writes (scenario.yaml) and Scenario.with_loops re-validate."""
    bench = load_scenario(SCENARIOS / "jcstr_benchmark.yaml")
    assert bench.nodes["level_controller"].loop_names == ("level",)
    again = bench.with_loops(tau_s={"level": 0.2})
    assert again.nodes["level_controller"].loops is None
    mrac = load_scenario(THESIS).with_loops(tau_s={"x1": 0.2})
    assert mrac.nodes["mrac"].loop_names == ("x1", "x2") and mrac.nodes["mrac"].loop is None
