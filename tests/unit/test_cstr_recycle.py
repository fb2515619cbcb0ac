"""Two CSTRs with recycle (seed 001 eq. (10)-(11)): steady states, eigenvalues, linearization."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from scipy.integrate import solve_ivp
from scipy.optimize import root

from plants.cstr_recycle import PAPER_PARAMS, CSTRRecycle, CSTRRecycleParams

PLANT = CSTRRecycle()

# Unrounded unstable steady state (issue text); the paper prints (457.9, 1.77, 415.5, 1.75).
X_UNSTABLE = np.array([457.94284, 1.770164, 415.45847, 1.752205])
EIG_UNSTABLE = np.array([32.1, -54.8, -17.2, -8.5])


def _independent_rhs(x, u, p=PAPER_PARAMS):
    """Eq. (10) written out again, term by term, without the class."""
    t1, ca1, t2, ca2 = x
    q1, ca0, q2, ca03 = u
    k = [(p.k10, p.E1, p.dH1), (p.k20, p.E2, p.dH2), (p.k30, p.E3, p.dH3)]

    def r_sum(t):
        return sum(k0 * np.exp(-e / (p.R * t)) for k0, e, _ in k)

    def g_sum(t):
        return sum(-dh / (p.rho * p.cp) * k0 * np.exp(-e / (p.R * t)) for k0, e, dh in k)

    return np.array(
        [
            p.F0 / p.V1 * (p.T0 - t1)
            + p.Fr / p.V1 * (t2 - t1)
            + g_sum(t1) * ca1
            + q1 / (p.rho * p.cp * p.V1),
            p.F0 / p.V1 * (ca0 - ca1) + p.Fr / p.V1 * (ca2 - ca1) - r_sum(t1) * ca1,
            p.F1 / p.V2 * (t1 - t2)
            + p.F3 / p.V2 * (p.T03 - t2)
            + g_sum(t2) * ca2
            + q2 / (p.rho * p.cp * p.V2),
            p.F1 / p.V2 * (ca1 - ca2) + p.F3 / p.V2 * (ca03 - ca2) - r_sum(t2) * ca2,
        ]
    )


def test_rhs_matches_eq_10_written_out():
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = X_UNSTABLE + rng.normal(size=4) * [20.0, 0.3, 20.0, 0.3]
        u = PLANT.nominal_input() + rng.normal(size=4) * [1e4, 0.5, 1e4, 0.5]
        assert_allclose(PLANT.rhs(0.0, x, u), _independent_rhs(x, u), rtol=1e-12, atol=1e-9)


def test_unstable_steady_state_matches_issue_values():
    x_s, u_s = PLANT.unstable_steady_state()
    assert_allclose(u_s, [0.0, 4.0, 0.0, 2.0])
    assert_allclose(x_s, X_UNSTABLE, rtol=1e-4)
    assert_allclose(PLANT.rhs(0.0, x_s, u_s), 0.0, atol=1e-8)
    # rounded values printed in the paper
    assert np.all(np.abs(x_s - [457.9, 1.77, 415.5, 1.75]) <= [0.05, 0.005, 0.05, 0.005])
    # independent solve (Levenberg-Marquardt on the written-out equations, from the rounded point)
    sol = root(
        lambda z: _independent_rhs(z, u_s), [457.9, 1.77, 415.5, 1.75], method="lm", tol=1e-14
    )
    assert sol.success
    assert_allclose(x_s, sol.x, rtol=1e-9)


def test_three_steady_states_two_stable_one_unstable():
    states = PLANT.steady_states()
    assert len(states) == 3
    u = PLANT.nominal_input()
    stable = [np.max(np.linalg.eigvals(PLANT.jacobians(x, u)[0]).real) < 0 for x in states]
    assert stable == [True, False, True]  # sorted by T1: low, middle (operating point), high
    assert_allclose(states[1], X_UNSTABLE, rtol=1e-4)
    for x in states:
        assert_allclose(PLANT.rhs(0.0, x, u), 0.0, atol=1e-7)


def test_jacobian_eigenvalues_at_the_operating_point():
    x_s, u_s = PLANT.unstable_steady_state()
    ev = np.sort(np.linalg.eigvals(PLANT.jacobians(x_s, u_s)[0]).real)
    assert_allclose(ev, np.sort(EIG_UNSTABLE), rtol=0.01)


def test_jacobians_match_finite_differences():
    x_s, u_s = PLANT.unstable_steady_state()
    x = x_s + np.array([3.0, -0.1, -2.0, 0.05])  # off the steady state too
    u = u_s + np.array([500.0, 0.2, -300.0, 0.1])
    A, B = PLANT.jacobians(x, u)
    for j in range(4):
        dx = np.zeros(4)
        dx[j] = 1e-6 * max(1.0, abs(x[j]))
        fd = (_independent_rhs(x + dx, u) - _independent_rhs(x - dx, u)) / (2 * dx[j])
        assert_allclose(A[:, j], fd, rtol=1e-6, atol=1e-6)
        du = np.zeros(4)
        du[j] = 1e-3
        fd = (_independent_rhs(x, u + du) - _independent_rhs(x, u - du)) / 2e-3
        assert_allclose(B[:, j], fd, rtol=1e-7, atol=1e-12)


def test_two_unit_form_of_eq_11():
    x_s, u_s = PLANT.unstable_steady_state()
    A, B = PLANT.jacobians(x_s, u_s)
    lin = PLANT.two_unit(x_s, u_s)
    assert_allclose(np.block([[lin.A1, lin.A12], [lin.A21, lin.A2]]), A)
    # each unit's inputs act on that unit only: B is block diagonal with square, invertible B_i
    assert_allclose(B[:2, 2:], 0.0)
    assert_allclose(B[2:, :2], 0.0)
    for i in range(2):
        assert lin.B[i].shape == (2, 2)
        assert abs(np.linalg.det(lin.B[i])) > 0
        assert_allclose(lin.C[i], [[1.0, 0.0]])  # only the temperature is measured
    # coupling: the recycle (Fr/V1) into unit 1, the flow F1/V2 into unit 2
    assert_allclose(lin.A12, np.diag([PAPER_PARAMS.Fr / PAPER_PARAMS.V1] * 2))
    assert_allclose(lin.A21, np.diag([PAPER_PARAMS.F1 / PAPER_PARAMS.V2] * 2))


def test_linearize_returns_named_state_space_and_predicts_small_steps():
    x_s, u_s = PLANT.unstable_steady_state()
    sys = PLANT.linearize(x_s, u_s)
    assert sys.nstates == 4 and sys.ninputs == 4 and sys.noutputs == 2
    assert list(sys.state_labels) == ["T1", "CA1", "T2", "CA2"]
    # short horizon (the point is unstable): linear vs non-linear response to a small Q1 step
    du = np.array([200.0, 0.0, 0.0, 0.0])
    t_end = 0.05
    A, B, C = sys.A, sys.B, sys.C
    lin = solve_ivp(lambda t, z: A @ z + B @ du, (0, t_end), np.zeros(4), rtol=1e-10, atol=1e-12)
    nl = solve_ivp(lambda t, x: PLANT.rhs(t, x, u_s + du), (0, t_end), x_s, rtol=1e-10, atol=1e-12)
    dy_lin = C @ lin.y[:, -1]
    dy_nl = PLANT.outputs(nl.y[:, -1]) - PLANT.outputs(x_s)
    assert np.max(np.abs(dy_nl)) > 0.01
    assert_allclose(dy_lin, dy_nl, rtol=0.02, atol=1e-4)


def test_params_refuse_bad_values():
    with pytest.raises(ValidationError, match="V1"):
        CSTRRecycleParams(**{**PAPER_PARAMS.model_dump(), "V1": 0.0})
    with pytest.raises(ValidationError, match="extra"):
        CSTRRecycleParams(**{**PAPER_PARAMS.model_dump(), "V3": 1.0})
