"""JCSTR model: equilibrium (seed 000 eq. (5)-(7)) and linearization against independent numbers."""

from __future__ import annotations

import control  # noqa: TID253 - not a node: imports what it uses at the top
import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from plants.jcstr import BENCHMARK_PARAMS, JCSTR
from scenario import load_scenario
from tests.conftest import BENCHMARK

PLANT = JCSTR(BENCHMARK_PARAMS)


@pytest.mark.parametrize("h_bar, t_bar", [(0.70, 52.0), (0.75, 52.0), (0.75, 56.0), (0.5, 40.0)])
def test_equilibrium_solves_f_zero(h_bar, t_bar):
    x_bar, u_bar = PLANT.equilibrium({"H": h_bar, "T": t_bar})
    assert_allclose(PLANT.rhs(0.0, x_bar, u_bar), 0.0, atol=1e-9)

    # independent: solve f(x, u) = 0 for (x3, u1, u2) numerically (eq. (3))
    def residual(z):
        return PLANT.rhs(0.0, np.array([h_bar, t_bar, z[0]]), np.array([z[1], z[2]]))

    z = fsolve(residual, [140.0, BENCHMARK_PARAMS.F_in, 0.4], xtol=1e-12)
    assert_allclose([x_bar[2], *u_bar], z, rtol=1e-8)


def test_equilibrium_refuses_unreachable_temperature():
    with pytest.raises(ValueError, match="T_jin"):
        PLANT.equilibrium({"H": 0.7, "T": BENCHMARK_PARAMS.T_jin})


def test_jacobians_match_finite_differences():
    x, u = PLANT.equilibrium({"H": 0.7, "T": 52.0})
    x = x + np.array([0.01, 0.5, -2.0])  # off equilibrium too
    A, B = PLANT.jacobians(x, u)
    eps = 1e-6
    for j in range(3):
        dx = np.zeros(3)
        dx[j] = eps
        fd = (PLANT.rhs(0, x + dx, u) - PLANT.rhs(0, x - dx, u)) / (2 * eps)
        assert_allclose(A[:, j], fd, rtol=1e-6, atol=1e-8)
    for j in range(2):
        du = np.zeros(2)
        du[j] = eps
        fd = (PLANT.rhs(0, x, u + du) - PLANT.rhs(0, x, u - du)) / (2 * eps)
        assert_allclose(B[:, j], fd, rtol=1e-6, atol=1e-8)


def test_linearized_model_predicts_small_steps():
    """control.forced_response of the linear model vs the nonlinear model (solve_ivp)."""
    x_bar, u_bar = PLANT.equilibrium({"H": 0.7, "T": 52.0})
    sys = PLANT.linearize(x_bar, u_bar)
    assert sys.nstates == 3 and sys.ninputs == 2 and sys.noutputs == 2
    du = np.array([0.0, 0.01])  # small jacket-flow step
    t = np.linspace(0, 2.0, 201)
    lin = control.forced_response(sys, t, np.tile(du[:, None], (1, len(t)))).outputs
    sol = solve_ivp(
        lambda tt, x: PLANT.rhs(tt, x, u_bar + du),
        (0, 2.0),
        x_bar,
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
    )
    dy = sol.y[1] - x_bar[1]
    assert_allclose(lin[1], dy, atol=0.02 * np.max(np.abs(dy)))


def test_scenario_states_every_parameter_by_paper_symbol():
    """The benchmark file names A_B, D, U, rho, C_p, V_j, F_in, T_in, T_jin, and Kp/Ki per loop."""
    s = load_scenario(BENCHMARK)
    params = s.nodes["reactor"].params
    assert set(params) == {"A_B", "D", "U", "rho", "C_p", "V_j", "F_in", "T_in", "T_jin"}
    assert s.nodes["reactor"].build().params == BENCHMARK_PARAMS
    for loop in s.loops.values():
        law = s.nodes[loop.controller].law
        assert law.Kp != 0 and law.Ki != 0
