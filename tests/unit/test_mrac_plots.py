"""What the MRAC figures of a platform run draw (seed 003, Fig. 6.3-6.5 and theta's drift).

The thesis scenario, cut at 12 h (its 10 h step of u_c1 included), runs on the direct engine;
:func:`controllers.mrac_plots.series` replays the law over the executions rebuilt from the
record. Its signals are checked against the record itself (samples and moves) and against the
reference model integrated here from the scenario's set-point schedule, and the figures are
checked to draw exactly those arrays.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from controllers.law_plots import figures_of
from controllers.mrac import compatibility_theta
from controllers.mrac_plots import figures, series
from core.time import to_units
from runtime.direct import simulate
from runtime.executions import multi_loop_executions
from scenario import load_scenario
from tests.conftest import BENCHMARK, SCENARIOS, write_variant

THESIS = SCENARIOS / "column_mrac.yaml"
END_H = 12.0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The thesis scenario to 12 h on the direct engine: (scenario, record, law config, loops,
    executions with the time in hours)."""

    def shorten(d):
        d["end_time"] = END_H

    path = write_variant(tmp_path_factory.mktemp("mrac"), THESIS, "short.yaml", shorten)
    scenario = load_scenario(path)
    rec = simulate(scenario)
    cfg = scenario.nodes["mrac"]
    executions = [
        (to_units(ex.t), ex.y, ex.r) for ex in multi_loop_executions(scenario, rec, "mrac")
    ]
    return scenario, rec, cfg.law, list(cfg.loops), executions


def _uc(scenario, loops, t):
    """The reference command u_c in force at ``t`` (h), from the scenario's schedule."""
    value = {n: scenario.loops[n].setpoint for n in loops}
    for change in sorted(scenario.setpoints, key=lambda c: c.t):
        if change.t <= t:
            value[change.loop] = change.value
    return np.array([value[n] for n in loops])


def test_series_is_the_law_over_the_recorded_run(run):
    scenario, rec, law, loops, executions = run
    s = series(law, loops, executions)
    k = len(s["t"])
    assert k == round(END_H / law.T) + 1  # one execution per period, from t = 0 to 12 h
    # x: the delivered samples, at their delivery times; u: the recorded moves
    for i, n in enumerate(loops):
        lr = rec.loops[n]
        assert_array_equal(s["t"], [to_units(t) for t in lr.t])
        assert_allclose(s["x"][:, i], lr.y, rtol=0, atol=1e-16)  # replay's x is e + x_m
        assert_array_equal(s["u"][:, i], lr.u)
    # x_m: the Euler reference model (5.3) driven by the schedule's u_c, held between executions
    a_m, b_m, c_m = (np.array(m) for m in (law.A_m, law.B_m, law.C_m))
    x_m = np.zeros((k, 2))
    for j in range(1, k):
        dt = s["t"][j] - s["t"][j - 1]
        steps = max(1, math.ceil(dt / law.T - 1e-9))
        uc = _uc(scenario, loops, s["t"][j - 1])
        xm = x_m[j - 1]
        for _ in range(steps):
            xm = xm + dt / steps * (a_m @ xm + b_m @ uc)
        x_m[j] = xm
    assert_allclose(s["x_m"], x_m, rtol=0, atol=1e-15)
    assert np.ptp(s["x_m"][:, 0]) > 0.01  # the 10 h step of u_c1 moves x_m1
    assert_array_equal(s["u_c"], [_uc(scenario, loops, t) for t in s["t"]])
    assert_allclose(s["e"], s["x"] - s["x_m"], rtol=0, atol=1e-15)
    assert_allclose(s["y"], s["x"] @ c_m.T, rtol=0, atol=1e-15)
    assert_allclose(s["y_m"], s["x_m"] @ c_m.T, rtol=0, atol=1e-15)
    theta0 = compatibility_theta(np.array(law.A0), np.array(law.B0), a_m, b_m)
    assert_allclose(s["drift"], s["theta"] - theta0, rtol=0, atol=1e-15)
    assert_array_equal(s["drift"][0], 0.0)  # no adaptation before the second execution
    assert 1e-3 < np.max(np.abs(s["drift"])) < law.theta_bound  # it adapts, boundedly


def test_a_diverging_law_is_drawn_not_raised(run, caplog):
    """The replay for the figures freezes a divergence (the run's law would have raised): every
    execution is drawn, theta held from the divergence on."""
    _, _, law, loops, executions = run
    wild = law.model_copy(update={"gamma": 3e5})  # this run diverges beyond about 1e5
    assert wild.on_divergence == "raise"
    s = series(wild, loops, executions)
    assert len(s["t"]) == len(executions)
    assert "adaptation diverged" in caplog.text
    peak = np.max(np.abs(s["drift"]), axis=1)
    assert np.all(peak <= wild.theta_bound) and peak[-1] > 0.0
    frozen = int(np.argmax(peak == peak[-1]))
    assert frozen < len(peak) - 1  # frozen before the end
    assert_array_equal(
        s["theta"][frozen:], np.broadcast_to(s["theta"][-1], s["theta"][frozen:].shape)
    )


def test_figures_draw_the_series(run):
    _, _, law, loops, executions = run
    s = series(law, loops, executions)
    figs = figures(law, loops, executions, title="t", unit="h")
    assert set(figs) == {"states", "outputs", "errors", "theta"}
    try:
        for i in range(2):
            states = figs["states"].axes[i].lines
            assert_array_equal(states[0].get_xdata(), s["t"])
            assert_array_equal(states[0].get_ydata(), s["x_m"][:, i])
            assert_array_equal(states[1].get_ydata(), s["x"][:, i])
            outputs = figs["outputs"].axes[i].lines
            assert_array_equal(outputs[0].get_ydata(), s["y_m"][:, i])
            assert_array_equal(outputs[1].get_ydata(), s["y"][:, i])
            assert_array_equal(figs["errors"].axes[i].lines[0].get_ydata(), s["e"][:, i])
        drift = figs["theta"].axes[0].lines
        assert len(drift) == 8
        for j, line in enumerate(drift):
            assert_array_equal(line.get_ydata(), s["drift"][:, j])
    finally:
        import matplotlib.pyplot as plt

        for fig in figs.values():
            plt.close(fig)


def test_only_laws_that_register_figures_are_drawn():
    scenario = load_scenario(BENCHMARK)
    controllers = [c for c in scenario.nodes.values() if c.kind == "controller"]
    assert controllers and all(figures_of(c.law) is None for c in controllers)
    assert figures_of(load_scenario(THESIS).nodes["mrac"].law) is figures
