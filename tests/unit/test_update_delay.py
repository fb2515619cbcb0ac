"""Delayed model updates (agents/update_period/delay.py) vs the paper's test and brute force."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from agents.update_period.analysis import CSTRRecycleCase, spectral_radius
from agents.update_period.delay import DelayedUpdates, find_h_range
from controllers.qdc.model import closed_loop_matrices
from controllers.qdc.network import QDCNetwork

CASE = CSTRRecycleCase()


def _system(scheme: str = "model", delta1: float = 0.0) -> DelayedUpdates:
    net = QDCNetwork(CASE.plant, CASE.gains, model=CASE.model(delta1), scheme=scheme)
    return DelayedUpdates(*closed_loop_matrices(CASE.plant, net))


@pytest.mark.parametrize(("scheme", "arch"), [("model", "qdc"), ("zoh", "qdc_zoh")])
def test_no_delay_is_the_papers_test(scheme, arch):
    system = _system(scheme, 0.1)
    hs = np.array([0.01, 0.03, 0.043, 0.06])
    assert_allclose(
        system.spectral_radius(hs, 0.0), spectral_radius(CASE.system(arch, 0.1), hs), rtol=1e-8
    )
    r = find_h_range(system, 0.0, h_hi=0.1, n_grid=100)
    assert r.h_min == 0.0
    assert r.h_max == pytest.approx(CASE.h_max(arch, 0.1).h_max, abs=1e-7)


def _growth(system: DelayedUpdates, h: float, d: float, n_periods: int = 400) -> float:
    """Brute force, independent of the monodromy: integrate dw/dt = Acl w with solve_ivp, capture
    the state at each send instant and reset the reset rows from it d later; the mean log-growth
    of |w| per period over the second half (renormalised every period)."""
    n = system.Acl.shape[0]
    rows = system.reset_rows
    rng = np.random.default_rng(3)
    w = rng.standard_normal(n)
    logs = []

    def flow(w0, dt):
        if dt == 0.0:
            return w0
        sol = solve_ivp(lambda t, y: system.Acl @ y, (0.0, dt), w0, rtol=1e-10, atol=1e-12)
        return sol.y[:, -1]

    for _ in range(n_periods):
        captured = w.copy()
        w = flow(w, d)
        w = np.where(rows, system.Rcl @ captured, w)
        w = flow(w, h - d)
        norm = np.linalg.norm(w)
        logs.append(np.log(norm))
        w = w / norm
    return float(np.mean(logs[n_periods // 2 :]))


def test_brute_force_agrees_on_both_sides_of_the_delayed_h_max():
    system = _system()
    d = 0.01
    r = find_h_range(system, d, h_hi=0.1, n_grid=100)
    assert r.feasible and np.isfinite(r.h_max)
    checks = 0
    for f in (0.5, 0.8, 0.95, 1.05, 1.2, 1.5):
        h = f * r.h_max
        if h <= d:
            continue
        rho = system.spectral_radius(h, d)
        long = abs(f - 1) > 0.4  # far from h_max: long enough for the rate to be rho's
        rate = _growth(system, h, d, 400 if long else 150)
        assert (rate < 0) == (rho < 1), (h, rho, rate)
        if long:
            assert rate == pytest.approx(np.log(rho), rel=0.15, abs=2e-3)
        checks += 1
    assert checks >= 5


def test_a_delay_shortens_the_allowable_period():
    system = _system()
    h0 = find_h_range(system, 0.0, h_hi=0.1, n_grid=100).h_max
    prev = h0
    for d in (0.002, 0.005, 0.01):
        r = find_h_range(system, d, h_hi=0.1, n_grid=100)
        assert r.feasible
        assert r.h_max < prev
        prev = r.h_max
    # a delay the loop cannot live with: no stabilizing period at all
    assert not find_h_range(system, 0.06, h_hi=0.2, n_grid=100).feasible


@pytest.mark.parametrize(("h", "d"), [(0.0, 0.0), (-0.1, 0.0), (0.02, -0.001), (0.02, 0.02)])
def test_bad_periods_and_delays_are_refused(h, d):
    with pytest.raises(ValueError, match="h:|delay"):
        _system().monodromy(h, d)
